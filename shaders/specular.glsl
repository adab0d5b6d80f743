// View-dependent light of a material's lobes at one surface point, for objects with a cube map
// (curved and transmissive ones, section 4.4): specular.comp calls `specular_radiance` for the
// pixels that shading.comp found to need it (`needs_specular`) and queued by tile.
//
// Per lobe the specular integral (Eq. 4.3) over the object's cube map is estimated in one of three
// ways, chosen by the uniform `specular_mode` (one program serves the moving and the still camera):
// - SPECULAR_PATTERNS (walkthrough): the lobe's deterministic regular pattern (Eq. 4.10-4.13, the
//   same (xi1, xi2) positions at every pixel: smooth in space and time), each sample a MIP-filtered
//   look-up (Eq. 4.14-4.17), weighted by Eq. 4.25 (or Eq. 4.24 with WEIGHTS_EQ_4_24).
// - SPECULAR_QMC (still camera): `qmc_count` quasi-random importance samples (Eq. 4.5-4.8) per
//   frame, the R2 sequence from sample `qmc_first` on, Cranley-Patterson rotated by a hash of the
//   pixel and lobe, unfiltered look-ups, weights f cos / p (Eq. 4.4). The frames' mean (viewer/
//   progressive.py) converges to the integral of the cube map's light.
// - SPECULAR_FILTERED_IS (for comparison, Colbert and Krivanek 2007): as many importance samples
//   as the lobe's pattern has, the same unrotated sequence at every pixel, each filtered by the
//   MIP level of its pdf; Eq. 4.4 weights.
// Samples on the wrong side of the surface (below the horizon; for transmission above it) are
// dropped (section 4.4.3); each look-up goes through the object's bounding planes (4.4.1).

#include "common.glsl"
#include "materials.glsl"
#include "gbuffer_read.glsl"
#include "lobe_sampling.glsl"
#include "cubemaps.glsl"

// The regular patterns in (xi1, xi2) space (viewer/lobe_patterns.py), all lobes' in one buffer;
// per lobe x: first position, y: count, z: pattern kind (viewer/gpu_scene.py PATTERN_KINDS).
layout(std430, binding = PATTERN_BINDING) readonly buffer PatternBuffer { vec2 pattern_xi[]; };
layout(std430, binding = LOBE_PATTERN_BINDING) readonly buffer LobePatternBuffer { ivec4 lobe_patterns[]; };

uniform int specular_mode;  // SPECULAR_PATTERNS, SPECULAR_QMC or SPECULAR_FILTERED_IS
uniform int qmc_first;      // SPECULAR_QMC: index of this frame's first sample in the sequence
uniform int qmc_count;      // SPECULAR_QMC: samples per lobe and pixel in this frame

// The specular work of a frame: shading.comp queues the tiles (LOCAL_SIZE^2 pixels) that have a
// pixel needing specular light, and their count is the x size of specular.comp's indirect
// dispatch; specular.comp counts pixels and look-ups. viewer/passes/shading.py resets it.
layout(std430, binding = SPECULAR_WORK_BINDING) buffer SpecularWork {
    uint specular_groups[3];      // glDispatchComputeIndirect: (queued tiles, 1, 1)
    uint specular_pixels;         // pixels that got specular light
    uint specular_lookups_total;  // cube-map look-ups
    uint specular_tiles_x;        // tiles per row of the image
    uint specular_unused[2];
    uint specular_tiles[];        // the queued tiles, y * specular_tiles_x + x
};
layout(std430, binding = SPECULAR_FLAGS_BINDING) buffer SpecularTileFlags { uint specular_tile_queued[]; };

// Queue tile t once (the first of its pixels to ask wins).
void queue_specular_tile(uvec2 t) {
    uint tile = t.y * specular_tiles_x + t.x;
    if (atomicCompSwap(specular_tile_queued[tile], 0u, 1u) == 0u)
        specular_tiles[atomicAdd(specular_groups[0], 1u)] = tile;
}

// Cube-map look-ups this invocation made (the pass's statistics).
int specular_lookups = 0;

// What every lobe at one point shares: the shading frame (columns t, b, n; local (x, y, z) ->
// world), the view direction in it, the point and the object's cube map.
struct SpecularPoint {
    mat3 frame;
    vec3 wo;
    vec3 position;
    CubeObject cube;
    uvec3 seed;     // pixel and lobe: the per-pixel scramble of SPECULAR_QMC
};

// Any orthonormal (t, b) for a unit n (Duff et al. 2017, branchless and continuous except at n.z = 0).
mat3 any_frame(vec3 n) {
    float sgn = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (sgn + n.z);
    float b = n.x * n.y * a;
    return mat3(vec3(1.0 + sgn * n.x * n.x * a, sgn * b, -sgn * n.x), vec3(b, sgn + n.y * n.y * a, -n.y), n);
}

// The tangent frame of the G-buffer: its tangent, re-orthogonalised against the normal (16-bit
// targets), b = sign n x t; any frame where the surface has no tangent.
mat3 shading_frame(Surface s) {
    vec3 n = s.normal;
    vec3 t = safe_normalize(s.tangent - n * dot(s.tangent, n), vec3(0.0));
    if (t == vec3(0.0))
        return any_frame(n);
    return mat3(t, s.bitangent_sign * cross(n, t), n);
}

// PCG3D (Jarzynski and Olano 2020): a well-mixed 32-bit hash of three integers.
uvec3 pcg3d(uvec3 v) {
    v = v * 1664525u + 1013904223u;
    v.x += v.y * v.z; v.y += v.z * v.x; v.z += v.x * v.y;
    v ^= v >> 16u;
    v.x += v.y * v.z; v.y += v.z * v.x; v.z += v.x * v.y;
    return v;
}

// Point i of the R2 sequence (Roberts 2018: i (1/g, 1/g^2) mod 1, g the plastic number) in 32-bit
// fixed point, so it stays exact for any i; `rotation` adds a per-pixel Cranley-Patterson shift.
// The result lies in (0, 1): xi1 = 0 never reaches Eq. 4.6's -log(xi1).
vec2 r2_point(uint i, uvec2 rotation) {
    const uvec2 R2_STEP = uvec2(3242174889u, 2447445414u);  // round(2^32 / g), round(2^32 / g^2)
    uvec2 x = rotation + i * R2_STEP;
    return (vec2(x >> 8u) + 0.5) / 16777216.0;  // top 24 bits: what a float holds exactly
}

// Reflected samples must lie above the surface, transmitted ones below it.
bool on_lobe_side(vec3 wi, Lobe lobe) {
    return int(lobe.ks.a + 0.5) == LOBE_TRANSMIT ? wi.z < 0.0 : wi.z > 0.0;
}

// Walkthrough: the regular pattern, MIP-filtered, normalised by Eq. 4.25 (or 4.24).
vec3 lobe_pattern_estimate(SpecularPoint sp, Lobe lobe, ivec4 pattern) {
    int n = max(pattern.y, 1);
    float face = cube_map_face_size(sp.cube);
    float sample_area = lobe_ellipse_area(sp.wo, lobe) / float(n);  // A' = A / n (Eq. 4.16)
    LobeSum sum = LobeSum(vec3(0.0), 0.0);
    for (int k = 0; k < pattern.y; ++k) {
        vec3 wi = pattern_direction(sp.wo, pattern_xi[pattern.x + k], lobe);
        if (!on_lobe_side(wi, lobe))
            continue;  // below the horizon: cannot contribute (section 4.4.3)
        vec3 look = bounding_plane_direction(sp.cube, sp.position, sp.frame * wi);
        vec3 L = cube_radiance(sp.cube, look, cube_mip_level(sample_area, look, face));
        specular_lookups += 1;
        add_pattern_sample(sum, L, lobe_value(wi, sp.wo, lobe), lobe_pdf(wi, sp.wo, lobe), abs(wi.z));
    }
    return lobe_sum_result(sum);
}

// Still camera and filtered importance sampling: Eq. 4.4 over `count` importance samples.
vec3 lobe_importance_estimate(SpecularPoint sp, Lobe lobe, uint first, int count, uvec2 rotation,
                              bool filtered) {
    float face = cube_map_face_size(sp.cube);
    vec3 sum = vec3(0.0);
    for (int k = 0; k < count; ++k) {
        vec3 wi = sample_lobe(sp.wo, r2_point(first + uint(k), rotation), lobe);
        if (!on_lobe_side(wi, lobe))
            continue;  // a zero sample: the pdf covers these directions too
        float pdf = lobe_pdf(wi, sp.wo, lobe);
        float weight = lobe_value(wi, sp.wo, lobe) / pdf * abs(wi.z);  // f cos(theta_i) / p (Eq. 4.4)
        if (!(pdf > 0.0) || isinf(weight) || isnan(weight))
            continue;
        vec3 look = bounding_plane_direction(sp.cube, sp.position, sp.frame * wi);
        float lod = filtered ? importance_mip_level(pdf, count, face) : 0.0;  // unfiltered: unbiased
        sum += weight * cube_radiance(sp.cube, look, lod);
        specular_lookups += 1;
    }
    return sum / float(max(count, 1));
}

// One lobe's reflected (or transmitted) radiance towards the eye, times its ks.
vec3 lobe_radiance(SpecularPoint sp, Lobe lobe, int lobe_index) {
    ivec4 pattern = lobe_patterns[lobe_index];
    vec3 L;
    if (specular_mode == SPECULAR_QMC) {
        uvec2 rotation = pcg3d(sp.seed + uvec3(0u, 0u, uint(lobe_index))).xy;
        L = lobe_importance_estimate(sp, lobe, uint(qmc_first), qmc_count, rotation, false);
    } else if (specular_mode == SPECULAR_FILTERED_IS) {
        L = lobe_importance_estimate(sp, lobe, 0u, pattern.y, uvec2(0u), true);
    } else {
        L = lobe_pattern_estimate(sp, lobe, pattern);
    }
    return lobe.ks.rgb * L;
}

// Whether the point gets specular light at all: a lobe, an object with a cube map, a lit side.
bool needs_specular(Surface s, Material m) {
    return !s.dark && has_flag(m, MAT_SPECULAR) && has_cube_map(cube_objects[s.object]);
}

// The sum over the material's lobes (Eq. 3.6 without kd) at pixel `pixel` of the shaded image.
vec3 specular_radiance(Surface s, Material m, ivec2 pixel) {
    SpecularPoint sp;
    sp.frame = shading_frame(s);
    // The view in the local frame; an interpolated normal can put it slightly below the surface,
    // where the lobes are 0: lift it onto the horizon instead (grazing views stay finite).
    vec3 wo = transpose(sp.frame) * s.to_eye;
    sp.wo = safe_normalize(vec3(wo.xy, max(wo.z, 0.0)), vec3(0.0, 0.0, 1.0));
    sp.position = s.position;
    sp.cube = cube_objects[s.object];
    sp.seed = uvec3(uvec2(pixel), 0u);
    vec3 sum = vec3(0.0);
    for (int i = 0; i < m.info.w; ++i)
        sum += lobe_radiance(sp, lobes[m.info.z + i], m.info.z + i);
    return sum;
}
