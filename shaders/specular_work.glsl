// The specular work of a frame, shared by shading.comp (which queues it) and specular.comp (which
// does it): which pixels need specular light, of which kind, and the lists of their tiles.
//
// A pixel needs specular light where its material has lobes, its side is lit, and it has incident
// light to read: its plane's mirror buffer this frame (section 4.5; SPECULAR_LIST_PLANAR) or else its
// object's cube map (section 4.4; SPECULAR_LIST_CUBE). shading.comp puts each LOCAL_SIZE x LOCAL_SIZE
// tile holding such pixels on the list of each kind it holds; each list is the indirect dispatch of
// its own specular.comp program, which holds only that kind's code (llvmpipe runs both sides of
// every branch, so one program for both kinds cost every pixel both; docs/VIEWER.md, "The specular
// pass: one program per mode and kind"). The lists' numbers and their count, SPECULAR_LIST_COUNT,
// come from viewer/passes/shading.py SPECULAR_LISTS, which also resets the buffer per frame.

#include "common.glsl"
#include "materials.glsl"
#include "gbuffer_read.glsl"
#include "cubemaps.glsl"
#include "mirror_buffer.glsl"

layout(std430, binding = SPECULAR_WORK_BINDING) buffer SpecularWork {
    uint specular_groups[4 * SPECULAR_LIST_COUNT];  // per list k at 4 k: glDispatchComputeIndirect's (tiles, 1, 1), and one unused
    uint specular_pixels;                // pixels that got specular light
    uint specular_lookups_total;         // cube-map look-ups
    uint specular_mirror_lookups_total;  // mirror-buffer look-ups
    uint specular_tiles_queued;          // tiles on any list, each counted once
    uint specular_tiles_x;               // tiles per row of the image
    uint specular_tile_capacity;         // tiles in the image: list k's tiles start at k times this
    uint specular_unused[2];
    uint specular_tiles[];               // the lists' tiles, y * specular_tiles_x + x
};

// A planar object's surface reads its plane's mirror buffer where it lies in that plane: its normal
// within MIRROR_PLANE_COS of the plane's (facing the same way). Elsewhere -- the sides of a slab
// made planar by the sidecar -- the mirror image is not the light it receives: -1 there, as for
// objects whose plane got no pass this frame.

// Normal-mapped pixels ask it of their position (within MIRROR_PLANE_DISTANCE x the distance to
// the eye of the plane), since their normal is not the surface's.
int mirror_slot_at(Surface s) {
    if (MIRROR_ACTIVE == 0)
        return -1;  // the scene has no planar reflector that can get a pass: no code here
    int slot = mirror_slot_of(s.object);
    if (slot < 0)
        return -1;
    vec4 plane = mirror_slots[slot].plane;
    if (s.normal_mapped)
        return abs(dot(plane.xyz, s.position) + plane.w) <= MIRROR_PLANE_DISTANCE * distance(s.position, eye) ? slot : -1;
    return dot(s.normal, plane.xyz) >= MIRROR_PLANE_COS ? slot : -1;
}

// Whether any pixel can need specular light (MIRROR_ACTIVE, CUBE_OBJECTS: viewer/passes/shading.py);
// else shading.comp leaves the lists out, and `specular_list` is a constant -1.
const bool SPECULAR_POSSIBLE = MIRROR_ACTIVE != 0 || CUBE_OBJECTS != 0;

// The list of the pixel's specular light (above), or -1 where it needs none.
int specular_list(Surface s, Material m) {
    if (s.dark || !has_flag(m, MAT_SPECULAR))
        return -1;
    if (mirror_slot_at(s) >= 0)
        return SPECULAR_LIST_PLANAR;
    return has_cube_map(cube_objects[s.object]) ? SPECULAR_LIST_CUBE : -1;
}
