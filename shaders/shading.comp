// Shading pass: outgoing radiance per G-buffer pixel, in a compute shader (docs/VIEWER.md, "Passes":
// rasterise little, shade in compute). Background pixels get the sky along their view ray.
//
// This dispatch writes the view-independent part (light-mapped diffuse, emission, sky) and sorts
// tiles: a pixel that needs specular light puts its LOCAL_SIZE x LOCAL_SIZE tile on the list of
// specular.comp's indirect dispatch, so tiles without such pixels never run the specular code
// (and a scene without any runs no specular dispatch at all).

#include "common.glsl"
#include "materials.glsl"
#include "gbuffer_read.glsl"
#include "sky.glsl"
#include "specular.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;
layout(rgba32f, binding = RADIANCE_IMAGE) uniform writeonly image2D radiance_out;

// Eq. 3.6 towards the eye without the lobes: light-mapped diffuse (Eq. 4.1, from the G-buffer) +
// emission. A dark back face sends nothing, emission included (Mitsuba's one-sided emitters).
vec3 surface_radiance(Surface s) {
    if (s.dark)
        return vec3(0.0);
    return s.diffuse + constant_emission(materials[s.material]);
}

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(radiance_out);
    if (p.x >= size.x || p.y >= size.y)
        return;
    vec3 ray = view_ray(p, size);
    vec3 L;
    if (gbuffer_empty(p)) {
        L = sky_radiance(ray);
    } else {
        Surface s = gbuffer_surface(p, ray);
        L = surface_radiance(s);
        if (needs_specular(s, materials[s.material]))
            queue_specular_tile(uvec2(p) / uint(LOCAL_SIZE));
    }
    imageStore(radiance_out, p, vec4(clean_radiance(L), 1.0));
}
