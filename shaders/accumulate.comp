// Still-camera accumulation (section 4.4.2): the fp32 running sum of the frames' quasi-random
// estimates and the image shown, their mean -- blended from the last walkthrough image while
// only a few frames are in (`blend` < 1), so stopping the camera does not flash noise.

#include "common.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;
layout(rgba32f, binding = TARGET_IMAGE) uniform image2D accumulation;     // sum of frames 0 .. frame
layout(rgba32f, binding = SHOWN_IMAGE) uniform writeonly image2D shown;
layout(binding = SOURCE_UNIT) uniform sampler2D frame_radiance;            // this frame's estimate
layout(binding = BASE_UNIT) uniform sampler2D base;  // the walkthrough image (read when blend < 1)
uniform int frame;                                      // index of this frame: 0 starts a new sum
uniform float blend;                                    // weight of the mean against `base`

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= imageSize(shown).x || p.y >= imageSize(shown).y)
        return;
    vec3 sum = clean_radiance(texelFetch(frame_radiance, p, 0).rgb);
    if (frame > 0)
        sum += imageLoad(accumulation, p).rgb;
    imageStore(accumulation, p, vec4(sum, 1.0));
    vec3 mean = sum / float(frame + 1);
    vec3 L = blend >= 1.0 ? mean : mix(texelFetch(base, p, 0).rgb, mean, blend);
    imageStore(shown, p, vec4(clean_radiance(L), 1.0));
}
