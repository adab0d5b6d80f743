// Shading pass: outgoing radiance per G-buffer pixel, in a compute shader (docs/VIEWER.md, "Passes":
// rasterise little, shade in compute). Background pixels get the sky along their view ray.
//
// This dispatch writes the view-independent part (light-mapped diffuse, emission, sky) and sorts
// tiles: a pixel that needs specular light puts its LOCAL_SIZE x LOCAL_SIZE tile on the list of its
// kind (specular_work.glsl), which one of specular.comp's programs dispatches indirectly, so tiles
// without such pixels never run the specular code (and a scene without any runs no specular
// dispatch at all).

#include "common.glsl"
#include "materials.glsl"
#include "gbuffer_read.glsl"
#include "sky.glsl"
#include "specular_work.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;
layout(rgba32f, binding = RADIANCE_IMAGE) uniform writeonly image2D radiance_out;

// Eq. 3.6 towards the eye without the lobes: light-mapped diffuse (Eq. 4.1, from the G-buffer) +
// emission. A dark back face sends nothing, emission included (Mitsuba's one-sided emitters).
vec3 surface_radiance(Surface s) {
    if (s.dark)
        return vec3(0.0);
    return s.diffuse + constant_emission(materials[s.material]);
}

// Queue the work group's tile on each list one of its pixels needs: the pixels say so in shared
// flags and one invocation appends the tile, so a tile costs one atomic operation per list, not one
// per pixel on a per-tile flag (an atomic on one address from every pixel of a tile serialises them
// on a GPU). Called by every invocation of the group, in uniform control flow; list: the pixel's
// (specular_list), -1 for none.
shared bool tile_lists[SPECULAR_LIST_COUNT];

void queue_specular_tile(int list) {
    if (gl_LocalInvocationIndex < uint(SPECULAR_LIST_COUNT))
        tile_lists[gl_LocalInvocationIndex] = false;
    memoryBarrierShared();
    barrier();
    if (list >= 0)
        tile_lists[list] = true;  // every writer writes the same value
    memoryBarrierShared();
    barrier();
    if (gl_LocalInvocationIndex == 0u) {
        uint tile = gl_WorkGroupID.y * specular_tiles_x + gl_WorkGroupID.x;
        bool queued = false;
        for (int k = 0; k < SPECULAR_LIST_COUNT; ++k) {
            if (tile_lists[k]) {
                specular_tiles[uint(k) * specular_tile_capacity + atomicAdd(specular_groups[4 * k], 1u)] = tile;
                queued = true;
            }
        }
        if (queued)
            atomicAdd(specular_tiles_queued, 1u);
    }
}

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(radiance_out);
    bool inside = p.x < size.x && p.y < size.y;
    int list = -1;
    if (inside) {
        vec3 ray = view_ray(p, size);
        vec3 L;
        if (gbuffer_empty(p)) {
            L = sky_radiance(ray);
        } else {
            Surface s = gbuffer_surface(p, ray);
            L = surface_radiance(s);
            list = specular_list(s, materials[s.material]);
        }
        imageStore(radiance_out, p, vec4(clean_radiance(L), 1.0));
    }
    if (SPECULAR_POSSIBLE)  // a constant: uniform control flow for the barriers
        queue_specular_tile(list);  // the work group is the tile: LOCAL_SIZE x LOCAL_SIZE pixels
}
