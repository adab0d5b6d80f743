// The surface at a pixel of the passes that draw the bake's meshes: shading normal on the seen side,
// tangent frame, and light-mapped diffuse radiance (Eq. 4.1). Two ways in, one surface:
// - a fragment of a raster pass (the G-buffer's gbuffer.frag, the mirror passes' mirror.frag; the
//   vertex side is gbuffer.vert): `fragment_surface_input()` from the interpolated varyings, with the
//   screen-space derivatives and facing of the fragment;
// - a pixel of the visibility buffer (visibility_resolve.comp, with SURFACE_FROM_IDS defined): its
//   triangle's vertices interpolated there, the derivatives those of the same triangle one pixel over
//   (visibility.glsl).
// Either way the material textures take their level from the texture coordinates' differences across
// the pixel's 2 x 2 quad, from its first pixel (even x and y) one pixel right and one up (textureGrad),
// worked out from the surface itself (`quad_uv_derivatives`), never from the hardware's dFdx, whose
// pixels GL leaves to the driver (llvmpipe takes these, an NVIDIA driver others): so the two ways, and
// any two GPUs, pick the same levels.

#include "common.glsl"
#include "materials.glsl"
#include "scene_objects.glsl"

layout(binding = KD_TEXTURE_UNIT) uniform sampler2D kd_texture;   // the material's base colour (1x1 white: none)
layout(binding = EMISSION_TEXTURE_UNIT) uniform sampler2D emission_texture;  // its emissiveTexture (same)
layout(binding = METALLIC_ROUGHNESS_TEXTURE_UNIT) uniform sampler2D metallic_roughness_texture;  // G, B (same)
layout(binding = NORMAL_TEXTURE_UNIT) uniform sampler2D normal_texture;  // its normalTexture (linear)
layout(binding = ANISOTROPY_TEXTURE_UNIT) uniform sampler2D anisotropy_texture;  // KHR_materials_anisotropy's
layout(binding = LIGHTMAP_UNIT) uniform sampler2DArray lightmaps;  // irradiance E (rgb), one layer per page
uniform vec3 eye;                   // the eye the pass looks from (a mirror pass: the mirrored eye)

// What the surface is made from at one pixel.
struct SurfaceInput {
    vec3 position;      // world
    vec3 normal;        // interpolated vertex normal (any length; 0: none)
    vec4 tangent;       // xyz: tangent along +u of the texture; w: bitangent sign (0 0 0 0: none)
    vec2 uv;            // base-colour texture coordinates
    vec2 uv_dx;         // their change to the next pixel to the right ...
    vec2 uv_dy;         // ... and up (the mip level of the material's textures)
    vec3 color;         // glTF COLOR_0 in 0..1; -1 for objects without (viewer/gpu_meshes.py)
    vec2 lm_uv;         // light-map coordinates
    int lm_page;
    int object;         // index of the object in the bake manifest
    bool front_facing;  // counter-clockwise on screen (a mirror pass: as its glFrontFace says)
    vec3 face_normal;   // the triangle's normal, either orientation, any length: the fallback for
                        // zero-length vertex normals
};

// Whether material m has a texture of kind `flag` (a MAT_*_TEXTURE flag). TEXTURE_KINDS holds the kinds
// the program may meet: a raster program serves one texture batch (viewer/draw_list.py BatchPrograms),
// whose materials have only its kinds, so the others' code is left out (llvmpipe runs both sides of
// every branch: an untextured batch paid for every kind's look-up; docs/VIEWER.md, "Raster programs per
// texture batch").
bool has_texture(Material m, int flag) {
    return (TEXTURE_KINDS & flag) != 0 && has_flag(m, flag);
}

#ifndef SURFACE_FROM_IDS
in vec3 v_position;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
in vec3 v_color;
in vec2 v_lm_uv;
flat in int v_lm_page;
flat in int v_object;

// The texture coordinates' change across the fragment's 2 x 2 quad (the header's definition): uv / w and
// 1 / w (gl_FragCoord.w) are affine in the window, so their dFdx and dFdy are exact whichever pixels the
// driver differences, and give uv at the quad's first pixel and at its neighbours right and up.
void quad_uv_derivatives(vec2 uv, out vec2 uv_dx, out vec2 uv_dy) {
    vec3 a = vec3(uv, 1.0) * gl_FragCoord.w;
    vec3 ax = dFdx(a), ay = dFdy(a);
    vec2 to_first = floor(gl_FragCoord.xy * 0.5) * 2.0 + 0.5 - gl_FragCoord.xy;  // 0 or -1 per axis
    vec3 q = a + ax * to_first.x + ay * to_first.y;
    vec2 uv_q = q.xy / q.z;
    uv_dx = (q.xy + ax.xy) / (q.z + ax.z) - uv_q;
    uv_dy = (q.xy + ay.xy) / (q.z + ay.z) - uv_q;
}

// The fragment's input; the derivatives are taken here, in uniform control flow.
SurfaceInput fragment_surface_input() {
    SurfaceInput i;
    i.position = v_position;
    i.normal = v_normal;
    i.tangent = v_tangent;
    i.uv = v_uv;
    quad_uv_derivatives(v_uv, i.uv_dx, i.uv_dy);
    i.color = v_color;
    i.lm_uv = v_lm_uv;
    i.lm_page = v_lm_page;
    i.object = v_object;
    i.front_facing = gl_FrontFacing;
    i.face_normal = cross(dFdx(v_position), dFdy(v_position));
    return i;
}
#endif

// The drawn object's material (one multi-draw draws many objects: viewer/draw_list.py).
int object_material(int object) {
    return scene_objects[object].info.x;
}

// Layers a back face adds to its light-map page: the object's back-side pages (E around -n, baked
// for two-sided materials) follow the front pages in the array; 0 = no back side, the front serves.
int lightmap_back_layer(int object) {
    return scene_objects[object].info.y;
}

struct RasterSurface {
    vec3 normal;          // unit shading normal (the normal map's, if any), on the side the eye sees
    vec3 mesh_normal;     // unit interpolated vertex normal, on the side the eye sees
    bool normal_mapped;   // normal != mesh_normal
    vec3 tangent;         // orthogonal to the normal, length = the anisotropy strength factor
                          // (1 without an anisotropy texture), or 0 (no tangent frame)
    float bitangent_sign;
    vec3 diffuse;         // kd/pi * E; 0 on dark back faces
    bool dark;            // back face of a single-sided material: sends no light
    vec2 mr;              // metallic-roughness texel: x roughness multiplier g, y metallic M' (MAT_MR_TEXTURE)
};

// Coverage of MASK and BLEND materials (glTF 3.9.4 "Alpha Coverage"): alpha = the material's
// baseColorFactor alpha x the base colour texture's alpha (viewer/gpu_textures.py uploads it for these
// materials only). MASK keeps alpha >= alphaCutoff. BLEND has no order-independent answer in a
// deferred renderer; it keeps a fragment where a 4 x 4 ordered-dither threshold lies below alpha,
// so a block of supersamples keeps the fraction alpha and the resolve averages it (docs/SCENES.md),
// shifted per object so that stacked layers do not drop the same pixels.
// The base colour texture through its glTF sampler. The texture object repeats, bilinear; where the
// sampler says otherwise (MAT_KD_* flags) the uv is wrapped here: MIRRORED_REPEAT folds it into
// 0..1, and both it and CLAMP_TO_EDGE keep it half a texel inside the image, so the bilinear
// filter reads what GL's wrap of the texel indices reads (OpenGL 4.6 section 8.14.2) at level 0;
// magFilter NEAREST snaps to the texel's centre. The unwrapped uv's derivatives pick the mip level.
float wrap_kd(float u, float size, bool clamp_edge, bool mirror) {
    if (mirror)
        u = 1.0 - abs(mod(u, 2.0) - 1.0);
    return (clamp_edge || mirror) ? clamp(u, 0.5 / size, 1.0 - 0.5 / size) : u;
}

// A material texture at i.uv through the material's sampler (the base colour's: the emissive texture
// shares its uv set and sampler, bake/gltf_materials.py).
vec4 sample_material_texture(sampler2D tex, Material m, SurfaceInput i) {
    const int wrapped = MAT_KD_CLAMP_S | MAT_KD_CLAMP_T | MAT_KD_MIRROR_S | MAT_KD_MIRROR_T | MAT_KD_NEAREST;
    if ((m.info.x & wrapped) == 0)
        return textureGrad(tex, i.uv, i.uv_dx, i.uv_dy);
    vec2 size = vec2(textureSize(tex, 0));
    vec2 uv = vec2(wrap_kd(i.uv.x, size.x, has_flag(m, MAT_KD_CLAMP_S), has_flag(m, MAT_KD_MIRROR_S)),
                   wrap_kd(i.uv.y, size.y, has_flag(m, MAT_KD_CLAMP_T), has_flag(m, MAT_KD_MIRROR_T)));
    if (has_flag(m, MAT_KD_NEAREST))
        uv = (floor(uv * size) + 0.5) / size;
    return textureGrad(tex, uv, i.uv_dx, i.uv_dy);
}

vec4 sample_kd(Material m, SurfaceInput i) {
    return sample_material_texture(kd_texture, m, i);
}

#ifndef SURFACE_FROM_IDS
// Whether a fragment of `object` at texture coordinates i.uv is left out (the visibility buffer's
// raster pass asks too, so that the same fragments cover its pixels).
bool coverage_discards(Material m, SurfaceInput i) {
    bool mask = has_flag(m, MAT_ALPHA_MASK);
    if (!mask && !has_flag(m, MAT_ALPHA_BLEND))
        return false;
    float alpha = m.kd.a;
    if (has_texture(m, MAT_KD_TEXTURE))
        alpha *= sample_kd(m, i).a;
    if (mask)
        return alpha < m.emission.a;
    const float bayer[16] = float[16](0.0, 8.0, 2.0, 10.0, 12.0, 4.0, 14.0, 6.0,
                                      3.0, 11.0, 1.0, 9.0, 15.0, 7.0, 13.0, 5.0);
    ivec2 p = (ivec2(gl_FragCoord.xy) + ivec2(i.object, 3 * i.object)) & 3;
    return (bayer[p.y * 4 + p.x] + 0.5) / 16.0 >= alpha;
}
#endif

// glTF 3.9.3 normalTexture: the tangent-space normal (2 x texel - 1, x and y times the scale) in the
// frame (t, b, n) of the front face, b = w n x t (glTF 3.7.2.1: +Y of the map is the bitangent,
// which points up the image, towards -v, for a texture not mirrored).
vec3 normal_mapped(Material m, SurfaceInput i, vec3 n, vec3 t, vec3 b) {
    vec3 tn = sample_material_texture(normal_texture, m, i).xyz * 2.0 - 1.0;
    tn.xy *= m.surface.x;
    return safe_normalize(t * tn.x + b * tn.y + n * tn.z, n);
}

// KHR_materials_anisotropy: the direction in tangent space, (cos, sin) of anisotropyRotation, turned
// by the anisotropyTexture's RG direction (2 x texel - 1; default (1, 0.5): along t) where there is one;
// -> xy: direction, z: the texture's B, the factor on the anisotropy strength (1 without).
vec3 anisotropy_direction(Material m, SurfaceInput i) {
    vec2 rotation = m.surface.yz;
    if (!has_texture(m, MAT_ANISOTROPY_TEXTURE))
        return vec3(rotation, 1.0);
    vec3 a = sample_material_texture(anisotropy_texture, m, i).rgb;
    vec2 d = a.rg * 2.0 - 1.0;
    d = dot(d, d) > 1e-8 ? normalize(d) : vec2(1.0, 0.0);
    return vec3(mat2(rotation.x, rotation.y, -rotation.y, rotation.x) * d, clamp(a.b, 0.0, 1.0));
}

// Below this cosine to the eye a normal-mapped normal is bent towards the eye (raster_surface).
const float NORMAL_MAP_MIN_COS = 0.02;

RasterSurface raster_surface(SurfaceInput i) {
    RasterSurface s;
    Material m = materials[object_material(i.object)];
    vec3 to_eye = safe_normalize(eye - i.position, vec3(0.0, 0.0, 1.0));

    // Geometric normal, towards the viewer: the fallback for zero-length vertex normals.
    vec3 ng = safe_normalize(i.face_normal, to_eye);
    ng = dot(ng, to_eye) < 0.0 ? -ng : ng;
    vec3 n = safe_normalize(i.normal, i.front_facing ? ng : -ng);

    // Back faces (clockwise on screen; counter-clockwise in a mirror pass, which flips the winding
    // and says so with glFrontFace) of one-sided materials are black, as in Mitsuba: neither
    // their BSDF nor their emission acts on that side. Seen from the back, the shading frame of a
    // double-sided material flips.
    bool back = !i.front_facing;
    s.dark = back && !has_flag(m, MAT_TWO_SIDED);

    // The mesh's tangent frame on the front side: t Gram-Schmidt against n, b = w n x t.
    vec3 t = safe_normalize(i.tangent.xyz - n * dot(i.tangent.xyz, n), vec3(0.0));
    float sign_b = i.tangent.w < 0.0 ? -1.0 : 1.0;
    vec3 b = sign_b * cross(n, t);
    vec3 ns = n;
    s.normal_mapped = has_texture(m, MAT_NORMAL_TEXTURE) && t != vec3(0.0);
    if (s.normal_mapped)
        ns = normal_mapped(m, i, n, t, b);
    vec3 aniso = anisotropy_direction(m, i);
    vec3 ta = t * aniso.x + b * aniso.y;
    // Seen from the back, the whole frame flips with the normal (a point reflection of the
    // front's normal field: a bump stays a bump from either side); t and b keep their axes.
    if (back) {
        n = -n;
        ns = -ns;
    }
    // A normal map can tilt the normal away from the eye (grazing views): there it is bent towards
    // the eye until its cosine is NORMAL_MAP_MIN_COS (or the mesh normal's, if lower), adding a
    // multiple of to_eye, so the lobes see a view just above their horizon instead of none.
    float cos_eye = dot(ns, to_eye), lowest = min(dot(n, to_eye), NORMAL_MAP_MIN_COS);
    if (s.normal_mapped && cos_eye < lowest)
        ns = safe_normalize(ns + to_eye * (lowest - cos_eye), n);
    s.normal = ns;
    s.mesh_normal = n;

    // Light-mapped diffuse radiance, Eq. 4.1: L = kd / pi * E (times the base-colour texture).
    vec3 kd = m.kd.rgb;
    if (has_texture(m, MAT_KD_TEXTURE))
        kd *= sample_kd(m, i).rgb;
    // glTF metallicRoughnessTexture: G multiplies the roughness, B is the metallic M' (the loader
    // multiplied metallicFactor in); kd is the base colour at M' = 0 (bake/material_mapping.py).
    s.mr = vec2(1.0, 0.0);
    if (has_texture(m, MAT_MR_TEXTURE)) {
        s.mr = clamp(sample_material_texture(metallic_roughness_texture, m, i).gb, 0.0, 1.0);
        kd *= 1.0 - s.mr.y;
    }
    // glTF: COLOR_0 x baseColorFactor x texture. Objects without are marked by -1, not 1: the
    // interpolation of a constant 1 need not give exactly 1, and their images must not change.
    if (i.color.r >= 0.0)
        kd *= i.color;
    // E of the side seen: a two-sided surface is lit on each side by its own light map.
    int layer = i.lm_page + (back ? lightmap_back_layer(i.object) : 0);
    vec3 E = clean_radiance(textureLod(lightmaps, vec3(i.lm_uv, float(layer)), 0.0).rgb);  // no MIP levels
    s.diffuse = s.dark ? vec3(0.0) : clean_radiance(max(kd, 0.0) * INV_PI * E);
    // glTF 3.9.3: emission = emissiveFactor x emissiveTexture. Textured emission varies per pixel,
    // so it joins the diffuse radiance here (the G-buffer has no emission target) and the shading
    // passes add no constant emission for these materials; a dark back face emits nothing.
    if (has_texture(m, MAT_EMISSION_TEXTURE) && !s.dark)
        s.diffuse = clean_radiance(s.diffuse + m.emission.rgb * max(sample_material_texture(emission_texture, m, i).rgb, 0.0));

    // Tangent for anisotropic lobes: the anisotropy direction re-orthogonalised against the shading
    // normal; zero if none; its length carries the strength factor (gbuffer_layout.glsl).
    s.tangent = safe_normalize(ta - ns * dot(ta, ns), vec3(0.0)) * aniso.z;
    s.bitangent_sign = back ? -sign_b : sign_b;
    return s;
}

#ifndef SURFACE_FROM_IDS
// The surface of this fragment; fragments MASK or BLEND leave uncovered are discarded, last, so the
// derivatives and implicit-LOD look-ups of raster_surface run in uniform control flow.
RasterSurface fragment_surface() {
    SurfaceInput i = fragment_surface_input();
    RasterSurface s = raster_surface(i);
    if (coverage_discards(materials[object_material(i.object)], i))
        discard;
    return s;
}
#endif
