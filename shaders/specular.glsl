// View-dependent light of a material's lobes at one surface point: for objects with a cube map
// (curved and transmissive ones, section 4.4) and for planar reflectors whose plane got a mirror
// pass this frame (section 4.5). specular.comp calls `specular_radiance` for the pixels that
// shading.comp found to need it and queued by tile, on the list of their kind (specular_work.glsl).
//
// Per lobe the specular integral (Eq. 4.3) over the object's cube map is estimated in one of these
// ways, `specular_mode`, a constant of the program (viewer/passes/shading.py compiles one per mode):
// - SPECULAR_PATTERNS (walkthrough): the lobe's deterministic regular pattern (Eq. 4.10-4.13, the
//   same (xi1, xi2) positions at every pixel: smooth in space and time), each sample a MIP-filtered
//   look-up (Eq. 4.16-4.17; its footprint from the lobe's second moment, or the thesis' A / n of
//   Eq. 4.14-4.15 with `pattern_footprint`), their p cos-weighted mean of the radiance times the
//   lobe's directional albedo for this view (lobe_sampling.glsl ESTIMATE_ALBEDO, the table of
//   lobe_albedo.glsl; viewer/lobe_albedo.py says why: Eq. 4.25's bias grows with Kurt's alpha), or
//   for comparison weighted by Eq. 4.25 (WEIGHTS_EQ_4_25) or Eq. 4.24 (WEIGHTS_EQ_4_24). A lobe whose
//   table is not its texel's (a metallic-roughness and an anisotropy texture at once) keeps Eq. 4.25.
//   Transmission lobes and glass solids alike: the look's weight (volume.glsl) is part of the
//   radiance averaged, the lobe's albedo holds its 1 - F.
// - SPECULAR_QMC (still camera): `qmc_count` quasi-random importance samples (Eq. 4.5-4.8) per
//   frame, the R2 sequence from sample `qmc_first` on, Cranley-Patterson rotated by a hash of the
//   pixel and lobe, unfiltered look-ups, weights f cos / p (Eq. 4.4). The frames' mean (viewer/
//   progressive.py) converges to the integral of the cube map's light.
// - SPECULAR_FILTERED_IS (for comparison, Colbert and Krivanek 2007): as many importance samples
//   as the lobe's pattern has, the same unrotated sequence at every pixel, each filtered by the
//   MIP level of its pdf; Eq. 4.4 weights.
// - SPECULAR_SPLIT_SUM (for comparison, compiled in with SPLIT_SUM; split_sum.glsl): what game
//   engines do, one look-up of a prefiltered cube map at the lobe centre times the lobe's albedo.
// Samples on the wrong side of the surface (below the horizon; for transmission above it) are
// dropped (section 4.4.3); each look-up goes through the object's bounding planes (4.4.1).
//
// Planar reflectors (section 4.5) read their plane's mirror buffer instead (mirror_buffer.glsl):
// each sample direction is mapped to a buffer position by the two-step tangent-plane projection
// (4.5.2), starting from the plane of P_R, the point the mirror direction sees.
// - SPECULAR_PATTERNS: the lobe's planar pattern (multi-ring for isotropic lobes, the lines for
//   anisotropic ones; viewer/lobe_patterns.py), each sample at its own MIP level (4.5.3 per
//   sample): its share A / n of the lobe's solid angle (Eq. 4.14-4.15) times the buffer's texels
//   per steradian at its look-up, the Jacobian of the two-step projection (the planar Eq. 4.16;
//   mirror_buffer.glsl); weighted as for cube maps. Split-sum keeps one level from the lobe's four extreme
//   directions, which span an ellipse in the buffer (planar_lobe_lod).
// - SPECULAR_QMC: importance samples as for cube maps, unfiltered; step 1 intersects the running
//   mean of the planes that this pixel's samples were found in so far (all frames of the still
//   camera; kept in two images) instead of P_R's own plane, so the first projection no longer
//   jumps with P_R at the depth edges of the mirror image.
// - SPECULAR_FILTERED_IS: importance samples, each at its own level for A / n sr (as the patterns).
// The mirror buffer holds the sky where nothing was drawn; a sample that leaves the buffer reads
// its edge (clamp to edge): the nearest known radiance, better indoors than the sky. Transmission
// lobes have no mirror image: a planar object's transmit lobes use its cube map if it has one
// and are dropped otherwise. A planar object whose plane got no pass this frame (over the budget,
// or the other skips of viewer/reflectors.py) falls back to its cube map if it has one; else it
// gets no specular light this frame (renderer.stats["mirror"] lists it). So do the faces of a
// planar object that are not in its plane (`mirror_slot_at`: the sides of a slab).

#include "common.glsl"
#include "materials.glsl"
#include "gbuffer_read.glsl"
#include "lobe_sampling.glsl"
#include "lobe_albedo.glsl"
#include "cubemaps.glsl"
#include "volume.glsl"
#include "mirror_buffer.glsl"
#include "specular_work.glsl"

// The regular patterns in (xi1, xi2) space (viewer/lobe_patterns.py), all lobes' in one buffer;
// per lobe x: first position, y: count, z: pattern kind (viewer/gpu_materials.py PATTERN_KINDS).
layout(std430, binding = PATTERN_BINDING) readonly buffer PatternBuffer { vec2 pattern_xi[]; };
layout(std430, binding = LOBE_PATTERN_BINDING) readonly buffer LobePatternBuffer { ivec4 lobe_patterns[]; };

// The mode, the look-ups' footprint and the kind of pixel (specular_work.glsl) are constants of the
// program, not uniforms: llvmpipe (Mesa 22.3) runs both sides of every branch, a uniform condition's
// too, so one program for all modes and kinds paid for all of them (docs/VIEWER.md, "The specular
// pass: one program per mode and kind").
const int specular_mode = SPECULAR_MODE;  // SPECULAR_PATTERNS, SPECULAR_QMC, SPECULAR_FILTERED_IS (or SPECULAR_SPLIT_SUM)
// SPECULAR_LIST: the pixels this program shades, all reading their plane's mirror buffer or all their
// cube map; PLANAR_CUBE_MAPS: 1 where a planar reflector has a cube map (its transmission lobes read it).
const bool planar_pixels = SPECULAR_LIST == SPECULAR_LIST_PLANAR;
const int pattern_footprint = PATTERN_FOOTPRINT;  // SPECULAR_PATTERNS (cube maps and mirror buffers): one of these (viewer/renderer.py FOOTPRINTS)
uniform int qmc_first;      // SPECULAR_QMC: index of this frame's first sample in the sequence
uniform int qmc_count;      // SPECULAR_QMC: samples per lobe and pixel in this frame
const int FOOTPRINT_MOMENT = 0, FOOTPRINT_THESIS = 1, FOOTPRINT_MOMENT_ALL = 2;

// Cube-map and mirror-buffer look-ups this invocation made (the pass's statistics).
int specular_lookups = 0;
int mirror_lookups = 0;

// Still camera on planar reflectors: per pixel the sums of the planes (position, normal turned
// towards the pixel's point) that its samples were found in, over all frames so far; w of the
// first holds their count. Reset by the first frame of a still camera (qmc_first = 0).
layout(rgba32f, binding = MIRROR_PLANE_POSITION_IMAGE) uniform image2D mirror_plane_positions;
layout(rgba32f, binding = MIRROR_PLANE_NORMAL_IMAGE) uniform image2D mirror_plane_normals;

// What every lobe at one point shares: the shading frame (columns t, b, n; local (x, y, z) ->
// world), the view direction in it, the point and the object's cube map.
struct SpecularPoint {
    mat3 frame;
    vec3 wo;
    vec3 position;
    CubeObject cube;
    uvec3 seed;     // pixel and lobe: the per-pixel scramble of SPECULAR_QMC
    int mirror;     // slot of the object's mirror pass this frame, or -1 (look-ups in the cube map)
    MirrorCentre centre;  // the point's own look-up in that mirror buffer: P_R and its plane
    vec4 plane_sum_p;     // still camera: sum of the planes' positions so far, w: their count
    vec3 plane_sum_n;     // ... and of their normals
    vec2 texel;           // the texel's metallic-roughness factor g and anisotropy strength s (lobe_albedo_at)
};

// Where sample wi (local frame) reads the object's cube map and what of that reaches the eye:
// through a glass solid's volume for its transmission lobes (volume.glsl), else straight from the
// point through the bounding planes (section 4.4.1) at full weight.
CubeLook cube_look(SpecularPoint sp, vec3 wi, Lobe lobe) {
    vec3 d = sp.frame * wi;
    if (has_volume(sp.cube))
        return lobe_is_transmit(lobe) ? volume_transmit(sp.cube, sp.position, sp.frame[2], d)
                                      : volume_reflect(sp.cube, sp.position, sp.frame[2], d);
    return single_look(bounding_plane_direction(sp.cube, sp.position, d), vec3(1.0));
}

// The radiance a look brings, both of its look-ups at MIP level `lod`.
vec3 look_radiance(SpecularPoint sp, CubeLook look, float lod) {
    vec3 L = look.weight * cube_radiance(sp.cube, look.dir, lod);
    if (look.weight2 != vec3(0.0)) {
        L += look.weight2 * cube_radiance(sp.cube, look.dir2, lod);
        specular_lookups += 1;
    }
    return L;
}

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

// R2 as Roberts defines it starts at 0.5 (x_i = frac(0.5 + i alpha)): the shift every pixel shares
// when the same points serve the whole image (filtered importance sampling); point 0 then sits
// mid-lobe instead of at xi1 ~ 0, far out in the lobe's tail.
const uvec2 R2_CENTRED = uvec2(2147483648u);

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

// The solid angle each of a pattern's samples filters (its MIP footprint): the thesis' A' = A / n
// (Eq. 4.16), or the lobe's second moment less the pattern's own spread (lobe_sampling.glsl) for
// reflection lobes, in cube maps and mirror buffers alike. Transmission lobes keep A / n unless
// FOOTPRINT_MOMENT_ALL: the moment lost on material-classes' frosted sphere and won on
// living-room's frosted pane (viewer/lobe_patterns.py, "Footprint").
float pattern_sample_area(vec3 wo, Lobe lobe, ivec4 pattern) {
    int n = max(pattern.y, 1);
    if (pattern_footprint == FOOTPRINT_MOMENT_ALL || (pattern_footprint == FOOTPRINT_MOMENT && !lobe_is_transmit(lobe))) {
        PatternMoment pm = PatternMoment(0.0, vec2(0.0), vec2(0.0));
        for (int k = 0; k < pattern.y; ++k)
            add_pattern_moment(pm, pattern_xi[pattern.x + k]);
        return pattern_footprint_area(pm, n, lobe_ellipse_axes(wo, lobe));
    }
    return lobe_ellipse_area(wo, lobe) / float(n);
}

// Walkthrough: the regular pattern, MIP-filtered, its weighted mean by `estimator` (lobe_sampling.glsl:
// times the albedo by the caller for ESTIMATE_ALBEDO).
vec3 lobe_pattern_estimate(SpecularPoint sp, Lobe lobe, ivec4 pattern, int estimator) {
    float face = cube_map_face_size(sp.cube);
    float sample_area = pattern_sample_area(sp.wo, lobe, pattern);
    LobeSum sum = LobeSum(vec3(0.0), 0.0);
    for (int k = 0; k < pattern.y; ++k) {
        vec3 wi = pattern_direction(sp.wo, pattern_xi[pattern.x + k], lobe);
        if (!on_lobe_side(wi, lobe))
            continue;  // below the horizon: cannot contribute (section 4.4.3)
        CubeLook look = cube_look(sp, wi, lobe);
        vec3 L = look_radiance(sp, look, cube_mip_level(sample_area, look.dir, face));
        specular_lookups += 1;
        add_pattern_sample(sum, L, lobe_value(wi, sp.wo, lobe), lobe_pdf(wi, sp.wo, lobe), abs(wi.z), estimator);
    }
    return lobe_sum_result(sum);
}

// Importance sample `index` of the lobe (Eq. 4.5-4.8) with its pdf (Eq. 4.9) and Eq. 4.4 weight
// f cos(theta_i) / p; false for a sample that contributes nothing (the wrong side of the surface --
// the pdf covers those directions too -- or a degenerate pdf).
bool importance_sample(SpecularPoint sp, Lobe lobe, uint index, uvec2 rotation,
                       out vec3 wi, out float pdf, out float weight) {
    wi = sample_lobe(sp.wo, r2_point(index, rotation), lobe);
    pdf = 0.0;
    weight = 0.0;
    if (!on_lobe_side(wi, lobe))
        return false;
    pdf = lobe_pdf(wi, sp.wo, lobe);
    weight = lobe_value(wi, sp.wo, lobe) / pdf * abs(wi.z);
    return pdf > 0.0 && !isinf(weight) && !isnan(weight);
}

// Still camera and filtered importance sampling: Eq. 4.4 over `count` importance samples.
vec3 lobe_importance_estimate(SpecularPoint sp, Lobe lobe, uint first, int count, uvec2 rotation,
                              bool filtered) {
    float face = cube_map_face_size(sp.cube);
    vec3 sum = vec3(0.0);
    for (int k = 0; k < count; ++k) {
        vec3 wi;
        float pdf, weight;
        if (!importance_sample(sp, lobe, first + uint(k), rotation, wi, pdf, weight))
            continue;
        CubeLook look = cube_look(sp, wi, lobe);
        float lod = filtered ? importance_mip_level(pdf, count, face) : 0.0;  // unfiltered: unbiased
        sum += weight * look_radiance(sp, look, lod);
        specular_lookups += 1;
    }
    return sum / float(max(count, 1));
}

// -- planar reflectors: look-ups in the mirror buffer (section 4.5) ------------------------------

// The MIP level of a planar lobe sampled n times (section 4.5.3): the lobe's border directions at
// phi_h = 0, 180 deg (along t) and 90, 270 deg (along b), projected by the two steps.
float planar_lobe_lod(SpecularPoint sp, Lobe lobe, int n) {
    MirrorSlot slot = mirror_slots[sp.mirror];
    vec3 e0 = sp.frame * pattern_direction(sp.wo, vec2(0.0, 0.0), lobe);
    vec3 e1 = sp.frame * pattern_direction(sp.wo, vec2(0.0, 0.5), lobe);
    vec3 e2 = sp.frame * pattern_direction(sp.wo, vec2(0.0, 0.25), lobe);
    vec3 e3 = sp.frame * pattern_direction(sp.wo, vec2(0.0, 0.75), lobe);
    return mirror_lobe_mip_level(sp.position, e0, e1, e2, e3, n, slot.view_proj, sp.mirror, sp.centre,
                                 slot.info.yz, slot.info.x);
}

// Where a sample direction wi (local frame) reads the mirror buffer: projected by the two steps,
// step 1 in the plane (plane_p, plane_n); the still camera's unfiltered look-ups by a third
// (mirror_project_sample).
MirrorSample planar_project(SpecularPoint sp, vec3 wi, vec3 plane_p, vec3 plane_n) {
    MirrorSlot slot = mirror_slots[sp.mirror];
    mirror_lookups += 1;
    return mirror_project_sample(sp.position, sp.frame * wi, slot.view_proj, sp.mirror, sp.centre, plane_p,
                                 plane_n, true, specular_mode == SPECULAR_QMC);
}

// The radiance it reads there at MIP level `lod`.
vec3 planar_lookup(SpecularPoint sp, vec3 wi, vec3 plane_p, vec3 plane_n, float lod, out MirrorSample ms) {
    ms = planar_project(sp, wi, plane_p, plane_n);
    return mirror_radiance_at(sp.mirror, ms.uv, lod);
}

// ... at the sample's own MIP level, for `sample_sr` steradians of the lobe: times the texels per
// steradian of the projection at its look-up (mirror_sample_mip_level; the planar Eq. 4.16). One
// level for the whole lobe (planar_lobe_lod) over-blurred wide lobes: their samples see near and
// far, slanted and facing planes, and the guard band's coarser buffer (viewer/reflectors.py).
vec3 planar_filtered_lookup(SpecularPoint sp, vec3 wi, vec3 plane_p, vec3 plane_n, float sample_sr,
                            out MirrorSample ms) {
    ms = planar_project(sp, wi, plane_p, plane_n);
    MirrorSlot slot = mirror_slots[sp.mirror];
    float lod = mirror_sample_mip_level(sample_sr, sp.position, sp.frame * wi, ms, slot.view_proj, slot.info.yz,
                                        slot.info.x);
    return mirror_radiance_at(sp.mirror, ms.uv, lod);
}

// Step 1's plane (4.5.2): the mean of the planes this pixel's samples were found in so far, once
// there is one; P_R's own before. A wide lobe spans several planes (floor, walls): P_R's alone put
// step 1 far off for much of it (the blurry aluminium of planar-classes read up to 3 times the
// ray-cast light), the running mean lands near what a ray cast finds. Still camera, walkthrough
// and filtered importance sampling all project this way, so they estimate the same integral.
void step_one_plane(SpecularPoint sp, out vec3 plane_p, out vec3 plane_n) {
    plane_p = sp.centre.position;
    plane_n = sp.centre.normal;
    if (sp.plane_sum_p.w > 0.0) {
        plane_p = sp.plane_sum_p.xyz / sp.plane_sum_p.w;
        plane_n = safe_normalize(sp.plane_sum_n, sp.centre.normal);
    }
}

// Add the plane a sample's step 2 found to the running mean (its normal turned towards P).
void add_found_plane(inout SpecularPoint sp, MirrorSample ms) {
    if (length(ms.plane_n) >= MIRROR_BACKGROUND_NORMAL) {
        vec3 n = safe_normalize(ms.plane_n, vec3(0.0));
        sp.plane_sum_p += vec4(ms.plane_p, 1.0);
        sp.plane_sum_n += dot(n, sp.position - ms.plane_p) < 0.0 ? -n : n;
    }
}

// The steradians one of n samples of `lobe` filters in a mirror buffer: `area` (Eq. 4.14-4.16's
// A / n, or the second moment), at most its share of the lobe's cap, lobe_cap_solid_angle / n.
// Eq. 4.15's area is a solid angle only for narrow lobes; for one wider than ~45 degrees it is
// thousands of steradians, which sent every sample of a rough metal's tail lobe (m ~ 0.75) to the
// buffer's last MIP level, the whole buffer's mean (tests/test_planar_accuracy.py: 0.53 of a ray
// cast's light, 1.03 capped; docs/BENCHMARKS.md, "Issue 24: wide lobes in the mirror buffers").
// Cube maps need no cap: their levels end at one face (cube_mip_level).
float planar_sample_sr(float area, SpecularPoint sp, Lobe lobe, int n) {
    return min(area, lobe_cap_solid_angle(sp.wo, lobe) / float(max(n, 1)));
}

// Walkthrough: the lobe's planar pattern, each sample at its own MIP level for its footprint
// (pattern_sample_area: the second moment; A / n of Eq. 4.14-4.16 with the thesis' footprint) times
// the projection's texels per steradian, weighted by `estimator` as lobe_pattern_estimate; step 1 in the running mean of the planes
// found (the pattern's centre sample first: P_R's plane). With A / n the samples of a wide lobe read
// levels of 2-6, whose boxes mixed the sky beyond the room into the floor's reflection (measured:
// docs/BENCHMARKS.md, "Issue 6: all methods, split-sum included", planar reflectors).
vec3 planar_pattern_estimate(inout SpecularPoint sp, Lobe lobe, ivec4 pattern, int estimator) {
    float sample_sr = planar_sample_sr(pattern_sample_area(sp.wo, lobe, pattern), sp, lobe, pattern.y);
    LobeSum sum = LobeSum(vec3(0.0), 0.0);
    MirrorSample ms;
    for (int k = 0; k < pattern.y; ++k) {
        vec3 wi = pattern_direction(sp.wo, pattern_xi[pattern.x + k], lobe);
        if (!on_lobe_side(wi, lobe))
            continue;  // below the horizon: cannot contribute (section 4.4.3)
        vec3 plane_p, plane_n;
        step_one_plane(sp, plane_p, plane_n);
        vec3 L = planar_filtered_lookup(sp, wi, plane_p, plane_n, sample_sr, ms);
        add_found_plane(sp, ms);
        add_pattern_sample(sum, L, lobe_value(wi, sp.wo, lobe), lobe_pdf(wi, sp.wo, lobe), abs(wi.z), estimator);
    }
    return lobe_sum_result(sum);
}

// Still camera (over all its frames; unfiltered: unbiased) and filtered importance sampling
// (`filtered`: each sample at its own MIP level for A / count sr, as the patterns; within the
// frame): step 1 in the running mean of the planes found so far (step_one_plane); Eq. 4.4 over
// `count` importance samples. Not Colbert and Krivanek's 1 / (count p) sr per sample (the cube maps'
// importance_mip_level): in a mirror buffer it blurs the tails' samples of a narrow lobe over the
// whole buffer (measured: docs/BENCHMARKS.md, "What is measured", filtered-is).
vec3 planar_importance_estimate(inout SpecularPoint sp, Lobe lobe, uint first, int count, uvec2 rotation,
                                bool filtered) {
    float sample_sr = filtered ? planar_sample_sr(lobe_ellipse_area(sp.wo, lobe) / float(max(count, 1)), sp, lobe, count)
                               : 0.0;  // A' = A / n
    vec3 sum = vec3(0.0);
    MirrorSample ms;
    for (int k = 0; k < count; ++k) {
        vec3 wi;
        float pdf, weight;
        if (!importance_sample(sp, lobe, first + uint(k), rotation, wi, pdf, weight))
            continue;
        vec3 plane_p, plane_n;
        step_one_plane(sp, plane_p, plane_n);
        vec3 L = filtered ? planar_filtered_lookup(sp, wi, plane_p, plane_n, sample_sr, ms)
                          : planar_lookup(sp, wi, plane_p, plane_n, 0.0, ms);
        add_found_plane(sp, ms);
        sum += weight * L;
    }
    return sum / float(max(count, 1));
}

// -------------------------------------------------------------------------------------------------

#ifdef SPLIT_SUM
#include "split_sum.glsl"
#endif

// The lobe at this pixel: a lobe that follows its material's metallic-roughness texture
// (LOBE_MR_*, bake/material_mapping.py) gets the texel's width and weight, so every estimate below
// -- the pattern's directions, its MIP levels (second moment or A / n), the importance samples,
// split-sum's centre and level, the mirror-buffer look-ups -- follows the texel's roughness:
//   m' = max(m g^2, M_MIN)  (glTF: alpha = (r g)^2 and m = max(r^2, 1e-4)),
//   anisotropic: a^2 = (mx - my) / (1 - my) kept, mx' = m' + (1 - m') a^2 (KHR_materials_anisotropy),
//   ks' = ks M' (metal) or ks (1 - M') (dielectric and transmit lobes).
// Then KHR_materials_anisotropy's texture scales the strength a by s (the G-buffer tangent's
// length): mx = m + (1 - m) a^2, my = m become mx' = my + (mx - my) s^2.
// The lobe keeps its sampling pattern (chosen for the material's mx, my).
Lobe lobe_at_pixel(Lobe lobe, int mr, Surface s, Material mat) {
    if (mr != LOBE_MR_NONE) {
        float my = lobe.shape.y;
        float a2 = my < 1.0 ? clamp((lobe.shape.x - my) / (1.0 - my), 0.0, 1.0) : 0.0;
        float m = max(my * s.mr.x * s.mr.x, M_MIN);
        lobe.shape.xy = vec2(m + (1.0 - m) * a2, m);
        lobe.ks.rgb *= mr == LOBE_MR_METAL ? s.mr.y : 1.0 - s.mr.y;
    }
    if (has_flag(mat, MAT_ANISOTROPY_TEXTURE))
        lobe.shape.x = lobe.shape.y + (lobe.shape.x - lobe.shape.y) * s.anisotropy * s.anisotropy;
    return lobe;
}

// One lobe's reflected (or transmitted) radiance towards the eye, times its ks.
vec3 lobe_radiance(inout SpecularPoint sp, Lobe lobe, int lobe_index) {
    bool planar = planar_pixels;
    if (planar && lobe_is_transmit(lobe)) {  // no mirror image of the far side
#if PLANAR_CUBE_MAPS
        if (!has_cube_map(sp.cube))
            return vec3(0.0);
        planar = false;
#else
        return vec3(0.0);  // no planar reflector has a cube map
#endif
    }
#ifdef SPLIT_SUM
    if (specular_mode == SPECULAR_SPLIT_SUM)
        return lobe.ks.rgb * split_sum_estimate(sp, lobe, lobe_index, planar);
#endif
    ivec4 pattern = lobe_patterns[planar ? lobe_patterns[lobe_index].w : lobe_index];
    uvec2 rotation = pcg3d(sp.seed + uvec3(0u, 0u, uint(lobe_index))).xy;
    vec3 L;
    if (specular_mode == SPECULAR_QMC) {
        L = planar ? planar_importance_estimate(sp, lobe, uint(qmc_first), qmc_count, rotation, false)
                   : lobe_importance_estimate(sp, lobe, uint(qmc_first), qmc_count, rotation, false);
    } else if (specular_mode == SPECULAR_FILTERED_IS) {
        L = planar ? planar_importance_estimate(sp, lobe, 0u, pattern.y, R2_CENTRED, true)
                   : lobe_importance_estimate(sp, lobe, 0u, pattern.y, R2_CENTRED, true);
    } else {
        // The walkthrough: the albedo-normalised mean where the table holds the texel's lobe, else Eq. 4.25.
        int estimator = ESTIMATOR_DEFAULT;
        float albedo = 1.0;
        if (estimator == ESTIMATE_ALBEDO) {
            bool exact;
            albedo = lobe_albedo_at(sp.wo, lobe_index, sp.texel.x, sp.texel.y, exact);
#ifdef LOBE_ALBEDO_INEXACT
            estimator = exact ? ESTIMATE_ALBEDO : ESTIMATE_EQ_4_25;
#endif
        }
        L = planar ? planar_pattern_estimate(sp, lobe, pattern, estimator) : lobe_pattern_estimate(sp, lobe, pattern, estimator);
        if (estimator == ESTIMATE_ALBEDO)
            L *= albedo;
    }
    return lobe.ks.rgb * L;
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
    sp.mirror = planar_pixels ? mirror_slot_at(s) : -1;
    sp.plane_sum_p = vec4(0.0);
    sp.plane_sum_n = vec3(0.0);
    sp.texel = vec2(s.mr.x, s.anisotropy);
    bool planes = planar_pixels && specular_mode == SPECULAR_QMC;
    if (planar_pixels)
        sp.centre = mirror_centre(s.position, mirror_slots[sp.mirror].view_proj, sp.mirror);
    if (planes && qmc_first > 0) {  // frame 0 of a still camera starts the sums afresh
        sp.plane_sum_p = imageLoad(mirror_plane_positions, pixel);
        sp.plane_sum_n = imageLoad(mirror_plane_normals, pixel).xyz;
    }
    vec3 sum = vec3(0.0);
    for (int i = 0; i < m.info.w; ++i) {
        int k = m.info.z + i;
        sum += lobe_radiance(sp, lobe_at_pixel(lobes[k], lobe_mr[k], s, m), k);
    }
    if (planes) {
        imageStore(mirror_plane_positions, pixel, sp.plane_sum_p);
        imageStore(mirror_plane_normals, pixel, vec4(sp.plane_sum_n, 0.0));
    }
    return sum;
}
