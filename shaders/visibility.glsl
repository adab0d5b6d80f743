// The visibility buffer's per-pixel ids (Burns and Hunt 2013, "The Visibility Buffer: A Cache-Friendly
// Approach to Deferred Shading"): one RG32UI texel per pixel, written by visibility.frag, read by
// visibility_resolve.comp. Where the depth is 1 (the clear value) nothing was drawn and the ids are
// undefined.
//   x: the object's index in the bake manifest
//   y: bits 0-30: the triangle's index within the object's range of the index buffer
//      (gl_PrimitiveID: each command of a multi-draw counts its own from 0); bit 31: front facing

const uint VIS_FRONT_BIT = 0x80000000u;

uvec2 vis_pack(int object, int triangle, bool front_facing) {
    return uvec2(uint(object), (uint(triangle) & ~VIS_FRONT_BIT) | (front_facing ? VIS_FRONT_BIT : 0u));
}

int vis_object(uvec2 ids) {
    return int(ids.x);
}

int vis_triangle(uvec2 ids) {
    return int(ids.y & ~VIS_FRONT_BIT);
}

bool vis_front_facing(uvec2 ids) {
    return (ids.y & VIS_FRONT_BIT) != 0u;
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
