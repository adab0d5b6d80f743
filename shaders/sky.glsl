// Radiance arriving from infinitely far away along a direction: none, a constant, or an
// equirectangular map times a scale. The direction <-> (u, v) mapping is bake/lights.py's
// (`equirect_uv`), the one the bake integrated the light maps with:
//     u = 0.5 + atan2(z, x) / (2 pi),   v = acos(y) / pi   (v = 0 straight up = row 0).
// The map texture repeats in u and clamps in v with GL_LINEAR: SkyLight.radiance's bilinear look-up.

#include "common.glsl"

uniform int sky_mode;        // SKY_NONE, SKY_CONSTANT or SKY_MAP
uniform vec3 sky_scale;      // radiance (constant sky) or the map's multiplier
layout(binding = SKY_UNIT) uniform sampler2D sky_map;

vec2 equirect_uv(vec3 d) {
    // atan(0, 0) is undefined in GLSL; numpy's arctan2(0, 0) = 0 gives u = 0.5 at the poles.
    float phi = (abs(d.x) + abs(d.z) > 0.0) ? atan(d.z, d.x) : 0.0;
    return vec2(0.5 + phi / (2.0 * PI), acos(clamp(d.y, -1.0, 1.0)) * INV_PI);
}

vec3 sky_radiance(vec3 direction) {
    if (sky_mode == SKY_CONSTANT)
        return sky_scale;
    if (sky_mode == SKY_MAP)
        return sky_scale * textureLod(sky_map, equirect_uv(direction), 0.0).rgb;
    return vec3(0.0);
}
