// The visibility buffer's pixels sorted by texture batch (viewer/passes/visibility.py), so that
// the resolve (visibility_resolve.comp) runs once per batch over that batch's
// pixels only, each dispatch sized on the GPU (glDispatchComputeIndirect): a scene of many textured
// materials costs no more dispatches over the whole screen than a scene of one. Three programs, one
// define each, run in this order:
//   CLASSIFY_COUNT    per pixel drawn: counts[its batch] += 1
//   CLASSIFY_PLAN     one invocation: offsets = exclusive prefix sum of counts; per batch the
//                     dispatch (ceil(count / RESOLVE_GROUP), 1, 1)
//   CLASSIFY_SCATTER  per pixel drawn: pixels[offsets[batch] + cursors[batch]++] = the pixel
// With RESOLVE_MIRROR (a mirror pass's), the count also writes the empty pixels' texels of the pass's
// layer: the sky seen along the mirrored ray (none, a constant or the map: what mirror_sky.frag or the
// targets' clear colour gives the raster pass), position and normal 0. The raster pass's clears and
// its sky triangle would go through the raster back end, a cost of the whole buffer per pass (and a
// GPU's fast clear would have to be expanded before the resolve's image stores).
// Reads: the visibility buffer and depth, the object of its triangles (scene_mesh.glsl), the batch of each object. Writes: the tally and the pixel list
// (and the mirror layer's empty texels).

#include "visibility.glsl"
#include "scene_mesh.glsl"

layout(std430, binding = VISIBILITY_TALLY_BINDING) buffer VisibilityTally {
    uint counts[VISIBILITY_BATCHES];
    uint offsets[VISIBILITY_BATCHES];
    uint cursors[VISIBILITY_BATCHES];
    uint dispatch[3 * VISIBILITY_BATCHES];  // x, y, z per batch: glDispatchComputeIndirect's
};
layout(std430, binding = VISIBILITY_PIXELS_BINDING) writeonly buffer VisibilityPixels { uint pixels[]; };
layout(std430, binding = DRAW_BATCH_OF_OBJECT_BINDING) readonly buffer BatchOfObject { int batch_of_object[]; };

#ifdef CLASSIFY_PLAN
layout(local_size_x = 1) in;

void main() {
    uint sum = 0u;
    for (int b = 0; b < VISIBILITY_BATCHES; ++b) {
        offsets[b] = sum;
        sum += counts[b];
        dispatch[3 * b] = (counts[b] + uint(RESOLVE_GROUP) - 1u) / uint(RESOLVE_GROUP);
        dispatch[3 * b + 1] = 1u;
        dispatch[3 * b + 2] = 1u;
    }
}
#else
layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(binding = VISIBILITY_UNIT) uniform usampler2D visibility_ids;
layout(binding = VISIBILITY_DEPTH_UNIT) uniform sampler2D visibility_depth;

// Per work group first, then once per group and batch in the buffer: a frame's pixels fall into a few
// batches, and millions of atomic additions to the same few words would queue up on a GPU.
shared uint group_count[VISIBILITY_BATCHES];
shared uint group_base[VISIBILITY_BATCHES];
#if defined(CLASSIFY_COUNT) && defined(RESOLVE_MIRROR)
#include "camera.glsl"
#include "sky.glsl"
uniform vec3 mirror_normal_world;  // the pass's plane (mirror_sky.frag's uniforms: the main camera's
                                   // ray basis widened by the guard band)
#endif

void main() {
    const uint GROUP = uint(LOCAL_SIZE * LOCAL_SIZE);
    uint local = gl_LocalInvocationIndex;
    for (uint b = local; b < uint(VISIBILITY_BATCHES); b += GROUP)
        group_count[b] = 0u;
    barrier();

    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    bool inside = all(lessThan(pixel, textureSize(visibility_ids, 0)));
    bool drawn = inside && texelFetch(visibility_depth, pixel, 0).r < 1.0;
#if defined(CLASSIFY_COUNT) && defined(RESOLVE_MIRROR)
    if (inside && !drawn) {  // mirror_sky.frag's texel
        vec3 sky = sky_radiance(reflect(view_ray(pixel, textureSize(visibility_ids, 0)), mirror_normal_world));
        imageStore(mirror_radiance_image, ivec3(pixel, layer), vec4(clean_half_radiance(sky), 1.0));
        imageStore(mirror_position_image, ivec3(pixel, layer), vec4(0.0));
        imageStore(mirror_normal_image, ivec3(pixel, layer), vec4(0.0));
    }
#endif
    int batch = drawn ? batch_of_object[triangle_object(vis_triangle(texelFetch(visibility_ids, pixel, 0).x))] : 0;
    uint slot = drawn ? atomicAdd(group_count[batch], 1u) : 0u;
    barrier();

    for (uint b = local; b < uint(VISIBILITY_BATCHES); b += GROUP) {
        uint n = group_count[b];
#ifdef CLASSIFY_COUNT
        if (n > 0u)
            atomicAdd(counts[b], n);
#else
        group_base[b] = n > 0u ? offsets[b] + atomicAdd(cursors[b], n) : 0u;
#endif
    }
#ifdef CLASSIFY_SCATTER
    barrier();
    if (drawn)
        pixels[group_base[batch] + slot] = vis_pack_pixel(pixel);
#endif
}
#endif
