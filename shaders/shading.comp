// Shading pass: outgoing radiance per G-buffer pixel, in a compute shader (DESIGN.md "Viewer":
// rasterise little, shade in compute). Background pixels get the sky along their view ray.

#include "common.glsl"
#include "materials.glsl"
#include "gbuffer_read.glsl"
#include "sky.glsl"
#include "specular.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;
layout(rgba32f) uniform writeonly image2D radiance_out;

// Eq. 3.6 towards the eye: light-mapped diffuse (Eq. 4.1, from the G-buffer) + emission +
// the lobes. A dark back face sends nothing, emission included (Mitsuba's one-sided emitters).
vec3 surface_radiance(Surface s) {
    if (s.dark)
        return vec3(0.0);
    Material m = materials[s.material];
    vec3 L = s.diffuse + m.emission.rgb;
    if (has_flag(m, MAT_SPECULAR))
        L += specular_radiance(s, m);
    return L;
}

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(radiance_out);
    if (p.x >= size.x || p.y >= size.y)
        return;
    vec3 ray = view_ray(p, size);
    vec3 L = gbuffer_empty(p) ? sky_radiance(ray) : surface_radiance(gbuffer_surface(p, ray));
    imageStore(radiance_out, p, vec4(clean_radiance(L), 1.0));
}
