// Supersampling resolve: each output pixel is the mean of its N x N block of input pixels, the
// box filter a path tracer applies over the pixel's area (Mitsuba's `box` rfilter).

#include "common.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;
layout(rgba32f, binding = TARGET_IMAGE) uniform writeonly image2D resolved;
layout(binding = SOURCE_UNIT) uniform sampler2D radiance;
uniform int factor;  // N

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= imageSize(resolved).x || p.y >= imageSize(resolved).y)
        return;
    vec3 sum = vec3(0.0);
    for (int j = 0; j < factor; ++j)
        for (int i = 0; i < factor; ++i)
            sum += texelFetch(radiance, p * factor + ivec2(i, j), 0).rgb;
    imageStore(resolved, p, vec4(clean_radiance(sum / float(factor * factor)), 1.0));
}
