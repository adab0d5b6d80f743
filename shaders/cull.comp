// Culling of every object at once (viewer/draw_list.py): per object one glDrawElementsIndirect
// command in this region's part of the command buffer -- instance count 1 when the object may be
// seen, 0 when it is hidden, has no triangles, lies wholly outside a frustum plane or wholly behind
// the clip plane -- and the reason, for the stats. Commands follow the draw order (objects batched
// by the textures of their material), so each batch is one contiguous multi-draw. With DRAW_LOD
// (a scene with levels of detail, viewer/lod.py) a drawn object's command draws the level `detail` picks.

#include "common.glsl"
#include "scene_objects.glsl"
#include "draw_command.glsl"

layout(local_size_x = CULL_GROUP) in;


layout(std430, binding = DRAW_ORDER_BINDING) readonly buffer DrawOrder { int draw_order[]; };
layout(std430, binding = DRAW_COMMAND_BINDING) writeonly buffer DrawCommands { DrawCommand commands[]; };
layout(std430, binding = DRAW_STATE_BINDING) writeonly buffer DrawStates { uint draw_states[]; };
layout(std430, binding = DRAW_HIDDEN_BINDING) readonly buffer DrawHidden { uint hidden[]; };

uniform vec4 planes[6];    // the view frustum's planes, inside where dot(plane, (x, 1)) >= 0 (camera.py)
uniform vec4 clip_plane;   // mirror passes: the mirror plane, the eye's side positive
uniform int use_clip;
uniform int first_command; // this region's first command (region x object count)
uniform int object_count;
// Objects smaller than this are dropped (0: none): the radius of the box's bounding sphere over its
// distance along the view axis, times proj_scale (the projection's y scale, cot(yfov / 2)), in NDC
// units; emitters are never dropped (a small lamp still lights what reflects it).
uniform float min_radius_ndc;
uniform float proj_scale;
uniform vec4 view_row;     // the view-projection's last row: w of a point = depth along the view axis

#ifdef DRAW_LOD
// Levels of detail (viewer/lod.py), finest first: per object the index range of each coarser version.
struct ObjectLod {
    int first[LOD_LEVELS];
    int count[LOD_LEVELS];  // indices; 0: no such level
};
layout(std430, binding = OBJECT_LOD_BINDING) readonly buffer ObjectLods { ObjectLod object_lods[]; };
uniform vec3 lod_eye;
// Pixels per radian at the view's centre times sqrt(triangles per pixel); 0: every object whole.
uniform float lod_scale;

// The index range to draw: the coarsest level with at least as many triangles as the disc that
// the box's bounding sphere covers seen from lod_eye, pi (asin(r / d) lod_scale)^2. The disc's
// angle depends on the eye only, not on the view direction, so the six faces of a cube map pick
// the same level of an object that spans several.
uvec2 detail(int i, SceneObject o) {
    uvec2 range = uvec2(o.info.z, o.info.w);
    vec3 centre = 0.5 * (o.lo.xyz + o.hi.xyz);
    float radius = 0.5 * length(o.hi.xyz - o.lo.xyz), d = length(centre - lod_eye);
    if (lod_scale <= 0.0 || d <= radius)
        return range;
    float disc = asin(radius / d) * lod_scale;
    float indices = 3.0 * PI * disc * disc;
    for (int k = 0; k < LOD_LEVELS; ++k) {
        int count = object_lods[i].count[k];
        if (count > 0 && float(count) >= indices)
            range = uvec2(object_lods[i].first[k], count);
    }
    return range;
}
#endif

// Whether the box lies wholly on the negative side of the plane: its corner farthest along the
// plane's normal is behind it (viewer/camera.py in_frustum, the test this replaces).
bool beyond(vec4 plane, vec3 lo, vec3 hi) {
    vec3 far_corner = mix(lo, hi, step(0.0, plane.xyz));
    return dot(plane.xyz, far_corner) + plane.w < 0.0;
}

// Whether the box's bounding sphere, wholly in front of the eye, projects to a radius under
// min_radius_ndc (the nearest point of the sphere gives the largest projection).
bool too_small(vec3 lo, vec3 hi) {
    vec3 centre = 0.5 * (lo + hi);
    float radius = 0.5 * length(hi - lo);
    float w = dot(view_row, vec4(centre, 1.0)) - radius;
    return w > 0.0 && radius * proj_scale < min_radius_ndc * w;
}

void main() {
    int c = int(gl_GlobalInvocationID.x);
    if (c >= object_count)
        return;
    int i = draw_order[c];
    SceneObject o = scene_objects[i];
    uint state = DRAWN;
    if (hidden[first_command + i] != 0u)
        state = HIDDEN;
    else if (o.info.w == 0)
        state = EMPTY;
    else if (use_clip != 0 && beyond(clip_plane, o.lo.xyz, o.hi.xyz))
        state = BEHIND_PLANE;
    else if (min_radius_ndc > 0.0 && o.lo.w == 0.0 && too_small(o.lo.xyz, o.hi.xyz))
        state = TOO_SMALL;
    else {
        for (int k = 0; k < 6; ++k)
            if (beyond(planes[k], o.lo.xyz, o.hi.xyz))
                state = OUTSIDE_VIEW;
    }
    uvec2 range = uvec2(o.info.z, o.info.w);  // first index, index count
#ifdef DRAW_LOD
    if (state == DRAWN)
        range = detail(i, o);
#endif
    commands[first_command + c] = DrawCommand(range.y, state == DRAWN ? 1u : 0u, range.x, 0, uint(i));
    draw_states[first_command + i] = state;
}
