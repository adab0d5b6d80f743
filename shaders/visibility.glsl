// The visibility buffer's per-pixel id (Burns and Hunt 2013, "The Visibility Buffer: A Cache-Friendly
// Approach to Deferred Shading"): one R32UI texel per pixel, written by visibility.frag, read by
// visibility_classify.comp and visibility_resolve.comp. Where the depth is 1 (the clear value) nothing
// was drawn and the id is undefined.
//   bits 0-30: the triangle's index in the scene's index buffer (its first index / 3; its object:
//              scene_mesh.glsl triangle_object); bit 31: front facing
// One word, not two (object and triangle): a data-centre GPU writes render targets slowly, 0.53 ms for
// depth and R32UI at 1920x1080 on an H200 against 0.82 ms for depth and RG32UI (issue 27's
// measurement), and every mirror pass pays it too.

const uint VIS_FRONT_BIT = 0x80000000u;

uint vis_pack(uint triangle, bool front_facing) {
    return (triangle & ~VIS_FRONT_BIT) | (front_facing ? VIS_FRONT_BIT : 0u);
}

uint vis_triangle(uint id) {
    return id & ~VIS_FRONT_BIT;
}

bool vis_front_facing(uint id) {
    return (id & VIS_FRONT_BIT) != 0u;
}

// A pixel of the G-buffer in one word (the resolve's per-batch lists: visibility_classify.comp):
// x in bits 0-15, y in bits 16-31 (render targets are at most 16384 wide).
uint vis_pack_pixel(ivec2 p) {
    return uint(p.x) | (uint(p.y) << 16);
}

ivec2 vis_unpack_pixel(uint word) {
    return ivec2(int(word & 0xFFFFu), int(word >> 16));
}

#ifdef RESOLVE_MIRROR
// A mirror pass's targets (mirror.frag's outputs) as images at layer `layer`, the pass's slot: the resolve
// writes the drawn pixels, the classification's count the empty ones (visibility_classify.comp).
layout(binding = MIRROR_RADIANCE_IMAGE, rgba16f) writeonly uniform image2DArray mirror_radiance_image;
layout(binding = MIRROR_POSITION_IMAGE, rgba32f) writeonly uniform image2DArray mirror_position_image;
layout(binding = MIRROR_NORMAL_IMAGE, rgba16f) writeonly uniform image2DArray mirror_normal_image;
uniform int layer;
#endif
