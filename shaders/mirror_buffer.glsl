// Mirror buffers of planar reflectors (section 4.5) as the shading passes read them: the two-step
// sample projection of section 4.5.2 and the MIP levels of section 4.5.3 (per pixel from the
// lobe's extremes, or per sample from the projection's texels per steradian). This is the
// GLSL port of bench/mirror_projection.py, the float64 numpy reference (tests/test_mirror_pass.py
// holds the two equal); its docstring states the conventions, in short:
// - a reflector's mirror buffer was rendered with the mirrored camera's view-projection
//   VP_m = G P V R (G: the guard band, x and y over its scale s >= 1; viewer/reflectors.py);
//   world points of the unmirrored scene are projected with VP_m as they are;
// - uv = ndc * 0.5 + 0.5, texel row 0 = the bottom (GL); the buffer has the main view's size and,
//   for s = 1, lines up with it pixel for pixel (P's own pixel holds the mirror direction's
//   radiance); a guard band s > 1 shows an s times wider field, s times coarser;
// - position / normal look-ups are nearest texel, clamped to the edge; a normal shorter than
//   MIRROR_BACKGROUND_NORMAL marks a texel where nothing was drawn (its radiance is the sky);
// - no hit of a tangent plane (parallel, or behind P): the direction itself is projected (w = 0),
//   i.e. the scene is taken to be infinitely far that way; a point or direction behind the
//   mirror camera (clip w <= MIRROR_W_EPS) is not valid and falls back to the centre sample's uv;
// - step 2 meeting background projects the direction where step 1 hit no plane or the direction's
//   uv is background too; else step 1's look-up (background: the sky) stands.
// Layers, slots and bindings: viewer/passes/mirror.py.

#include "common.glsl"

const float MIRROR_BACKGROUND_NORMAL = 0.5;
const float MIRROR_PARALLEL_EPS = 1e-8;
const float MIRROR_W_EPS = 1e-9;

// One mirror pass of this frame (a "slot": layer `slot` of the three texture arrays).
struct MirrorSlot {
    mat4 view_proj;  // world -> clip of the mirrored camera (P V R)
    vec4 plane;      // xyz: unit plane normal towards the eye, w: -dot(normal, point)
    vec4 info;       // x: the last MIP level of the radiance chain; y, z: buffer width, height
};

layout(std430, binding = MIRROR_SLOT_BINDING) readonly buffer MirrorSlotBuffer { MirrorSlot mirror_slots[]; };
// Per object of the bake manifest: the slot of its plane's pass this frame, or -1 (not planar,
// or its plane got no pass: outside the view, seen from behind, occluded, over the budget).
layout(std430, binding = MIRROR_OBJECT_BINDING) readonly buffer MirrorObjectBuffer { int mirror_object_slot[]; };

// Fixed units (defines), as cubemaps.glsl: llvmpipe ignored sampler uniforms of array textures.
layout(binding = MIRROR_RADIANCE_UNIT) uniform sampler2DArray mirror_radiance;  // MIP-mapped, trilinear
layout(binding = MIRROR_POSITION_UNIT) uniform sampler2DArray mirror_position;  // texelFetch only
layout(binding = MIRROR_NORMAL_UNIT) uniform sampler2DArray mirror_normal;      // texelFetch only

int mirror_slot_of(int object) {
    return object >= 0 && object < mirror_object_slot.length() ? mirror_object_slot[object] : -1;
}

// A world point (hw = 1) or direction (hw = 0) -> uv; `ok` false where it lies behind the camera
// (clip w <= MIRROR_W_EPS), and uv is then (0.5, 0.5). mirror_projection.project.
vec2 mirror_project(mat4 vp, vec3 x, float hw, out bool ok) {
    vec4 clip = vp * vec4(x, hw);
    ok = clip.w > MIRROR_W_EPS;
    vec2 ndc = ok ? clip.xy / clip.w : vec2(0.0);
    return ndc * 0.5 + 0.5;
}

// The texel nearest to uv, clamped to the image (mirror_projection.texel_index).
ivec3 mirror_texel(vec2 uv, int layer) {
    ivec2 size = textureSize(mirror_position, 0).xy;
    vec2 t = clamp(floor(uv * vec2(size)), vec2(0.0), vec2(size - 1));  // floor of +-inf / NaN: clamped
    return ivec3(ivec2(t), layer);
}

// World position and normal the mirror camera saw at uv (a normal of ~0: nothing drawn).
void mirror_fetch_plane(int layer, vec2 uv, out vec3 position, out vec3 normal) {
    ivec3 t = mirror_texel(uv, layer);
    position = texelFetch(mirror_position, t, 0).xyz;
    normal = texelFetch(mirror_normal, t, 0).xyz;
}

// Ray o + t d against the plane through p with normal n (any length; < MIRROR_BACKGROUND_NORMAL:
// background, no plane): t, and whether it hits (t > 0). mirror_projection.intersect_plane.
float mirror_intersect(vec3 o, vec3 d, vec3 p, vec3 n, out bool hit) {
    float nn = length(n);
    float denom = dot(d, n);
    bool usable = nn >= MIRROR_BACKGROUND_NORMAL && abs(denom) > MIRROR_PARALLEL_EPS * max(nn, 1.0);
    float t = usable ? dot(p - o, n) / denom : 0.0;
    hit = usable && t > 0.0 && !isinf(t) && !isnan(t);
    return hit ? t : 0.0;
}

// One step of the scheme: intersect P + t w with a plane, project the hit, or the direction
// where there is none (mirror_projection._step).
vec2 mirror_step(vec3 P, vec3 w, vec3 plane_p, vec3 plane_n, mat4 vp, out bool ok, out bool hit, out float t) {
    t = mirror_intersect(P, w, plane_p, plane_n, hit);
    return hit ? mirror_project(vp, P + t * w, 1.0, ok) : mirror_project(vp, w, 0.0, ok);
}

// Where the reflector point P (world) reads its mirror direction: P's projection (uv_c) and the
// scene point P_R and normal seen there. ok_c false: P is behind the mirror camera.
struct MirrorCentre {
    vec2 uv;
    bool ok;
    vec3 position;   // P_R
    vec3 normal;     // its normal (~0: background)
};

MirrorCentre mirror_centre(vec3 P, mat4 vp, int layer) {
    MirrorCentre c;
    c.uv = mirror_project(vp, P, 1.0, c.ok);
    mirror_fetch_plane(layer, c.uv, c.position, c.normal);
    return c;
}

// The look-up of one sample direction w (world, unit) at P (mirror_projection.project_sample):
// step 1 in the tangent plane (plane_p, plane_n) -- P_R's, or the still camera's averaged one --
// then, with `second_step`, step 2 in the plane the mirror camera saw at step 1's uv, and with
// `third_step` (where step 2 hit a drawn plane) a step 3 in the plane seen at step 2's uv: the
// scheme iterated once more towards the ray's own hit. The still camera takes it: its step 1 plane
// (the mean of the planes found so far, over walls, floor and ceiling for a wide lobe) put step 2 on
// the wrong surface, and its unfiltered look-ups showed it (a rough metal floor 12 % darker than
// Mitsuba rendering the same lobes; 3.6 % with step 3: docs/BENCHMARKS.md, "Issue 24: the floors'
// errors split"); the walkthrough's filtered look-ups did not change (within 0.1 %).
struct MirrorSample {
    vec2 uv;           // the look-up position
    bool valid;        // in front of the mirror camera (else uv is the centre's)
    bool at_infinity;  // uv is the projected direction: no plane was hit
    bool hit_second;   // step 2 hit the plane seen at step 1's uv
    vec3 plane_p;      // that plane, or step 3's where it was taken (the still camera averages them): position ...
    vec3 plane_n;      // ... and normal (~0 where step 1's uv showed background)
    float t;           // the look-up's point is P + t w, in the plane with normal `normal`; 0: at infinity
    vec3 normal;
};

MirrorSample mirror_project_sample(vec3 P, vec3 w, mat4 vp, int layer, MirrorCentre c, vec3 plane_p,
                                   vec3 plane_n, bool second_step, bool third_step) {
    MirrorSample s;
    bool ok1, hit1;
    float t1;
    vec2 uv1 = mirror_step(P, w, plane_p, plane_n, vp, ok1, hit1, t1);
    vec2 uv = uv1;
    bool ok = ok1;
    s.at_infinity = !hit1;
    s.t = t1;
    s.normal = plane_n;
    s.hit_second = false;
    s.plane_p = vec3(0.0);
    s.plane_n = vec3(0.0);
    if (second_step) {
        mirror_fetch_plane(layer, uv1, s.plane_p, s.plane_n);
        bool ok2, hit2;
        float t2;
        vec2 uv2 = mirror_step(P, w, s.plane_p, s.plane_n, vp, ok2, hit2, t2);
        // Background at step 1's point: the ray passes its plane where nothing was drawn. Step 1's
        // look-up (that background, the sky) stands unless the direction at infinity shows background
        // too (the sky along w itself); taking the direction's uv whatever it shows put whatever the
        // direction meets there -- a lamp the ray passed beside -- into the ray (mirror_projection.
        // project_sample). A missed (parallel / behind) plane keeps step 1.
        bool background = length(s.plane_n) < MIRROR_BACKGROUND_NORMAL;
        if (background && hit1 && !hit2) {
            vec3 p_inf, n_inf;
            mirror_fetch_plane(layer, uv2, p_inf, n_inf);
            background = length(n_inf) < MIRROR_BACKGROUND_NORMAL;
        }
        if (third_step && hit2 && !background) {
            vec3 p3, n3;
            mirror_fetch_plane(layer, uv2, p3, n3);
            bool ok3, hit3;
            float t3;
            vec2 uv3 = mirror_step(P, w, p3, n3, vp, ok3, hit3, t3);
            if (length(n3) >= MIRROR_BACKGROUND_NORMAL && hit3) {  // else step 2 stands
                uv2 = uv3;
                ok2 = ok3;
                t2 = t3;
                s.plane_p = p3;
                s.plane_n = n3;
            }
        }
        if (hit2 || background) {
            uv = uv2;
            ok = ok2;
            s.at_infinity = !hit2;
            s.t = t2;
            s.normal = s.plane_n;
        }
        s.hit_second = hit2;
    }
    s.valid = ok && c.ok;
    s.uv = s.valid ? uv : c.uv;
    return s;
}

// MIP level from the lobe's four extreme directions projected into the buffer, in the order
// (+a, -a, +b, -b): the ends of two conjugate diameters of an ellipse of area pi |a x b| pixels,
// over `n` samples, log4, clamped to the chain (mirror_projection.ellipse_mip_level, conjugate).
float mirror_ellipse_mip_level(vec2 uv0, vec2 uv1, vec2 uv2, vec2 uv3, int n, vec2 size, float max_level) {
    vec2 a = (uv0 - uv1) * size * 0.5;
    vec2 b = (uv2 - uv3) * size * 0.5;
    float area = PI * abs(a.x * b.y - a.y * b.x);
    float per_sample = (isinf(area) || isnan(area) ? 0.0 : area) / float(max(n, 1));
    return clamp(0.5 * log2(max(per_sample, 1.0)), 0.0, max_level);
}

// The same for four world directions at P (mirror_projection.lobe_mip_level).
float mirror_lobe_mip_level(vec3 P, vec3 e0, vec3 e1, vec3 e2, vec3 e3, int n, mat4 vp, int layer,
                            MirrorCentre c, vec2 size, float max_level) {
    vec2 uv0 = mirror_project_sample(P, e0, vp, layer, c, c.position, c.normal, true, false).uv;
    vec2 uv1 = mirror_project_sample(P, e1, vp, layer, c, c.position, c.normal, true, false).uv;
    vec2 uv2 = mirror_project_sample(P, e2, vp, layer, c, c.position, c.normal, true, false).uv;
    vec2 uv3 = mirror_project_sample(P, e3, vp, layer, c, c.position, c.normal, true, false).uv;
    return mirror_ellipse_mip_level(uv0, uv1, uv2, uv3, n, size, max_level);
}

// Buffer texels per steradian of sample direction at the look-up of sample s of direction w
// (unit) at P: |det| of the map from the directions around w to buffer pixels (section 4.5.3 per
// sample: the planar counterpart of Eq. 4.16's d^2 / cos). Turning w by d (d . w = 0) moves the
// point X = P + t w in its plane (normal n) by t (d - (d . n) / (w . n) w), a direction at
// infinity (t = 0) by d itself; the projection uv = (clip.xy / clip.w) / 2 moves by G dX, G's rows
// (clip.w A_r - clip_r A_w) / clip.w^2 (A_r: row r of vp's xyz columns). For a 2x3 map with rows
// g_x, g_y restricted to the plane normal to w, the area factor is |(g_x x g_y) . w|.
// 0 where the look-up is not valid (the centre's uv stands in). mirror_projection.texels_per_steradian.
float mirror_texels_per_sr(vec3 P, vec3 w, MirrorSample s, mat4 vp, vec2 size) {
    bool finite = s.t > 0.0;
    vec4 clip = vp * (finite ? vec4(P + s.t * w, 1.0) : vec4(w, 0.0));
    if (!s.valid || !(clip.w > MIRROR_W_EPS))
        return 0.0;
    vec3 a_x = vec3(vp[0].x, vp[1].x, vp[2].x);
    vec3 a_y = vec3(vp[0].y, vp[1].y, vp[2].y);
    vec3 a_w = vec3(vp[0].w, vp[1].w, vp[2].w);
    float inv_w2 = 1.0 / (clip.w * clip.w);
    vec3 g_x = (clip.w * a_x - clip.x * a_w) * (0.5 * size.x * inv_w2);  // pixels per unit of X
    vec3 g_y = (clip.w * a_y - clip.y * a_w) * (0.5 * size.y * inv_w2);
    if (finite) {  // times t (I - w n^T / (w . n)): the plane's point follows w (w . n != 0: a hit)
        float wn = dot(w, s.normal);
        g_x = s.t * (g_x - (dot(g_x, w) / wn) * s.normal);
        g_y = s.t * (g_y - (dot(g_y, w) / wn) * s.normal);
    }
    return abs(dot(cross(g_x, g_y), w));
}

// The MIP level of one sample covering `solid_angle` sr of the lobe: log4 of its texels,
// clamped to the chain; the chain's last level where that is unknown (invalid look-up, overflow).
// mirror_projection.sample_mip_level.
float mirror_sample_mip_level(float solid_angle, vec3 P, vec3 w, MirrorSample s, mat4 vp, vec2 size,
                              float max_level) {
    float texels = solid_angle * mirror_texels_per_sr(P, w, s, vp, size);
    bool known = s.valid && !isnan(texels) && !isinf(texels);
    return known ? clamp(0.5 * log2(max(texels, 1.0)), 0.0, max_level) : max_level;
}

// Radiance the mirror buffer holds at uv (clamped to its edge: a sample leaving the buffer reads
// the nearest edge texel), filtered at MIP level `lod`.
vec3 mirror_radiance_at(int layer, vec2 uv, float lod) {
    return textureLod(mirror_radiance, vec3(uv, float(layer)), lod).rgb;
}
