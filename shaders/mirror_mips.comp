// Mirror passes (viewer/passes/mirror.py): one level of the radiance MIP chain from the level above
// (section 4.5.3: "downsampled, averaging 4 pixels in each iteration"), for the slots 0 .. z - 1.
// Level sizes are GL's, floor(size / 2) (at least 1); an odd row or column of the finer level is
// folded into the last texel of the coarser one, so every fine texel counts.

#include "common.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;
layout(rgba16f, binding = MIP_SOURCE_IMAGE) uniform readonly image2DArray finer;
layout(rgba16f, binding = MIP_TARGET_IMAGE) uniform writeonly image2DArray coarser;

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID.xy, gl_GlobalInvocationID.z);
    ivec2 size = imageSize(coarser).xy;
    if (p.x >= size.x || p.y >= size.y)
        return;
    ivec2 fine = imageSize(finer).xy;
    ivec2 lo = min(2 * p.xy, fine - 1);
    // the last texel also takes the odd remainder; a level of size 1 takes all (2 or 3) texels
    ivec2 hi = min(2 * p.xy + 1, fine - 1);
    if (p.x == size.x - 1)
        hi.x = fine.x - 1;
    if (p.y == size.y - 1)
        hi.y = fine.y - 1;
    vec3 sum = vec3(0.0);
    for (int y = lo.y; y <= hi.y; ++y)
        for (int x = lo.x; x <= hi.x; ++x)
            sum += imageLoad(finer, ivec3(x, y, p.z)).rgb;
    vec2 count = vec2(hi - lo + 1);
    imageStore(coarser, p, vec4(clean_radiance(sum / (count.x * count.y)), 1.0));
}
