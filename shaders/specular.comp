// Specular pass: adds the lobes' light (specular.glsl) to the pixels that need it, one work group
// per tile that shading.comp queued on this program's list, SPECULAR_LIST (an indirect dispatch over
// that list of specular_tiles; specular_work.glsl): pixels of the tile on another list are that
// list's program's.

#include "common.glsl"
#include "materials.glsl"
#include "gbuffer_read.glsl"
#include "specular.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;
layout(rgba32f, binding = RADIANCE_IMAGE) uniform image2D radiance_out;  // read: the view-independent part; write: the sum

// The pass's statistics, summed over the work group first: one atomic addition per counter and
// group on the work buffer, not one per pixel on the same three words.
shared uint group_pixels, group_lookups, group_mirror_lookups;

void main() {
    if (gl_LocalInvocationIndex == 0u) {
        group_pixels = 0u;
        group_lookups = 0u;
        group_mirror_lookups = 0u;
    }
    memoryBarrierShared();
    barrier();
    uint tile = specular_tiles[uint(SPECULAR_LIST) * specular_tile_capacity + gl_WorkGroupID.x];
    ivec2 p = ivec2(tile % specular_tiles_x, tile / specular_tiles_x) * LOCAL_SIZE + ivec2(gl_LocalInvocationID.xy);
    ivec2 size = imageSize(radiance_out);
    if (p.x < size.x && p.y < size.y && !gbuffer_empty(p)) {
        Surface s = gbuffer_surface(p, view_ray(p, size));
        Material m = materials[s.material];
        if (specular_list(s, m) == SPECULAR_LIST) {
            vec3 L = imageLoad(radiance_out, p).rgb + specular_radiance(s, m, p);
            imageStore(radiance_out, p, vec4(clean_radiance(L), 1.0));
            atomicAdd(group_pixels, 1u);
            atomicAdd(group_lookups, uint(specular_lookups));
            atomicAdd(group_mirror_lookups, uint(mirror_lookups));
        }
    }
    memoryBarrierShared();
    barrier();
    if (gl_LocalInvocationIndex == 0u) {
        atomicAdd(specular_pixels, group_pixels);
        atomicAdd(specular_lookups_total, group_lookups);
        atomicAdd(specular_mirror_lookups_total, group_mirror_lookups);
    }
}
