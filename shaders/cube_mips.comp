// Cube-map probes (viewer/cubemaps.py): one MIP level of a cube-map array from the level above, every
// layer-face at once (the dispatch's z), each texel the mean of the 2 x 2 texels it covers: the box
// filter the MIP look-ups of Eq. 4.14-4.17 assume. Faces are square powers of two, so every level
// halves exactly. One dispatch per level instead of glGenerateMipmap, whose work Mesa's llvmpipe
// does as a blit per layer-face and level (thousands of them for a scene of many small probes), and
// the same arithmetic on every GPU. The radiance is finite and at most HALF_MAX in a half-float
// class, so is the mean.

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;
#ifdef CUBE_MIPS_FLOAT
layout(rgba32f, binding = MIP_SOURCE_IMAGE) uniform readonly imageCubeArray finer;
layout(rgba32f, binding = MIP_TARGET_IMAGE) uniform writeonly imageCubeArray coarser;
#else
layout(rgba16f, binding = MIP_SOURCE_IMAGE) uniform readonly imageCubeArray finer;
layout(rgba16f, binding = MIP_TARGET_IMAGE) uniform writeonly imageCubeArray coarser;
#endif
uniform int size;  // the coarser level's face size

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);  // z: layer-face = layer * 6 + face
    if (p.x >= size || p.y >= size)
        return;
    ivec2 f = 2 * p.xy;
    vec4 sum = (imageLoad(finer, ivec3(f, p.z)) + imageLoad(finer, ivec3(f.x + 1, f.y, p.z)))
             + (imageLoad(finer, ivec3(f.x, f.y + 1, p.z)) + imageLoad(finer, ivec3(f + 1, p.z)));
    imageStore(coarser, p, sum * 0.25);
}
