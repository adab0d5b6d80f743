// Tone mapping: exposure (x 2^EV), the ACES filmic fit, then the sRGB OETF, into 8 bits.

#include "common.glsl"
#include "colour.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;
layout(rgba8, binding = TARGET_IMAGE) uniform writeonly image2D display;
layout(binding = SOURCE_UNIT) uniform sampler2D radiance;
uniform float exposure_scale;  // 2^EV

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= imageSize(display).x || p.y >= imageSize(display).y)
        return;
    vec3 L = clean_radiance(texelFetch(radiance, p, 0).rgb);
    imageStore(display, p, vec4(srgb_oetf(aces_narkowicz(L * exposure_scale)), 1.0));
}
