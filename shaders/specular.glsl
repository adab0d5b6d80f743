// View-dependent light of a material's lobes at one surface point: the per-pixel hook of the
// shading pass. The specular issues fill `lobe_radiance` (deterministic lobe sample patterns,
// Eq. 4.10-4.13, cube-map and mirror-buffer look-ups, weights of Eq. 4.25); this issue's
// viewer has none, so every lobe contributes nothing yet.

#include "materials.glsl"
#include "gbuffer_read.glsl"

vec3 lobe_radiance(Surface s, Material m, Lobe lobe) {
    return vec3(0.0);
}

vec3 specular_radiance(Surface s, Material m) {
    vec3 sum = vec3(0.0);
    for (int i = 0; i < m.info.w; ++i)
        sum += lobe_radiance(s, m, lobes[m.info.z + i]);
    return sum;
}
