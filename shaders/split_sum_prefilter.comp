// Split-sum prefilter (viewer/split_sum.py): one level of one size class's prefiltered cube-map
// array, a texel per invocation, z = layer * 6 + face. Level k holds the cube map's radiance
// convolved with the section 3.3 lobe of roughness m_k (`roughness`) under the split-sum
// assumption n = v = r, r the texel's direction: the kernel f cos(theta_l) of Eq. 3.4 with F = 1 and
// alpha = 0 (the Fresnel and shadowing factors are in the albedo LUT), normalised. Estimated with
// `samples` importance samples of that lobe (Eq. 4.5-4.9) on a Hammersley set, each weighted by
// f cos / p (Eq. 4.4) and read from the source's MIP chain at Colbert and Krivanek's level for its
// pdf (filtered importance sampling); the estimate is the weighted mean.

#include "common.glsl"
#include "lobe_sampling.glsl"
#include "cubemaps.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;
layout(SPLIT_SUM_FORMAT, binding = PREFILTER_IMAGE) writeonly uniform imageCubeArray prefiltered;

uniform int source_class;  // the size class (viewer/cubemaps.py) this dispatch filters
uniform int face_size;     // texels per face side of the level written
uniform float roughness;   // m_k
uniform int samples;       // importance samples per texel

// The unit direction of texel (x, y) of cube face `face` (GL face order +X, -X, +Y, -Y, +Z, -Z;
// OpenGL 4.6 table 8.19: s = (sc / |ma| + 1) / 2, t = (tc / |ma| + 1) / 2).
vec3 cube_texel_direction(int face, ivec2 texel, int size) {
    vec2 st = (vec2(texel) + 0.5) / float(size) * 2.0 - 1.0;  // (sc, tc) / |ma|
    float sc = st.x, tc = st.y;
    vec3 d = face == 0 ? vec3(1.0, -tc, -sc) : face == 1 ? vec3(-1.0, -tc, sc)
           : face == 2 ? vec3(sc, 1.0, tc)   : face == 3 ? vec3(sc, -1.0, -tc)
           : face == 4 ? vec3(sc, -tc, 1.0)  : vec3(-sc, -tc, -1.0);
    return normalize(d);
}

// Point i of n of the Hammersley set ((i + 1/2) / n, radical inverse of i), as core/bsdf.py
// qmc_points: xi1 is never 0.
vec2 hammersley(uint i, uint n) {
    return vec2((float(i) + 0.5) / float(n), float(bitfieldReverse(i)) * 2.3283064365386963e-10);
}

void main() {
    ivec3 id = ivec3(gl_GlobalInvocationID);
    if (id.x >= face_size || id.y >= face_size)
        return;
    int layer = id.z / 6, face = id.z % 6;
    vec3 r = cube_texel_direction(face, id.xy, face_size);
    // A frame (t, b, r): the lobe is isotropic, any orientation about r will do.
    vec3 t = normalize(cross(abs(r.z) < 0.999 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0), r));
    mat3 frame = mat3(t, cross(r, t), r);
    CubeObject source = CubeObject(vec4(0.0), ivec4(source_class, layer, 0, 0), vec4(0.0), vec4(0.0),
                                         vec4[3](vec4(0.0), vec4(0.0), vec4(0.0)));
    float source_face = cube_map_face_size(source);
    Lobe lobe = Lobe(vec4(1.0, 1.0, 1.0, float(LOBE_REFLECT)), vec4(roughness, roughness, 1.0, 0.0));
    const vec3 wo = vec3(0.0, 0.0, 1.0);  // v = n = r
    vec3 sum = vec3(0.0);
    float total = 0.0;
    for (int k = 0; k < samples; ++k) {
        vec3 wi = sample_lobe(wo, hammersley(uint(k), uint(samples)), lobe);
        float pdf = lobe_pdf(wi, wo, lobe);
        float w = wi.z > 0.0 && pdf > 0.0 ? lobe_value(wi, wo, lobe) * wi.z / pdf : 0.0;  // Eq. 4.4
        if (!(w > 0.0) || isinf(w))
            continue;
        float lod = samples > 1 ? importance_mip_level(pdf, samples, source_face) : 0.0;
        sum += w * cube_radiance(source, frame * wi, lod);
        total += w;
    }
    vec3 L = total > 0.0 ? sum / total : cube_radiance(source, r, 0.0);
    imageStore(prefiltered, id, vec4(clean_radiance(L), 1.0));
}
