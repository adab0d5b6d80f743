// A visibility buffer's resolve (viewer/passes/visibility.py): per pixel, what the raster pass's own
// fragment shader would have written there -- with RESOLVE_GBUFFER the G-buffer's two words
// (gbuffer.frag, gbuffer_layout.glsl), with RESOLVE_MIRROR a mirror buffer's radiance, position and
// normal at layer `layer` (mirror.frag) -- from the triangle the raster pass left in the visibility
// buffer (visibility.glsl): its three vertices fetched from the scene's vertex and index buffers,
// interpolated at the pixel's centre with perspective-correct barycentrics, and the texture
// coordinates' derivatives those of the pixel's 2 x 2 quad on the same triangle (what a fragment's
// dFdx / dFdy measure there). Defined SURFACE_FROM_IDS, raster_surface.glsl builds the same surface
// from them.
//
// One dispatch per texture batch (viewer/draw_list.py), the batch's textures bound, over the batch's
// own pixels, which visibility_classify.comp listed (the dispatch's size is on the GPU).
//
// Reads: the visibility buffer, the pixel lists, the vertex and index buffers (scene_mesh.glsl), the object and material
// tables, the light maps and the batch's textures. Writes: the owner's images.

#include "raster_surface.glsl"
#include "gbuffer_layout.glsl"
#include "visibility.glsl"
#include "scene_mesh.glsl"

layout(local_size_x = RESOLVE_GROUP) in;
layout(std430, binding = VISIBILITY_TALLY_BINDING) readonly buffer VisibilityTally {
    uint counts[VISIBILITY_BATCHES];
    uint offsets[VISIBILITY_BATCHES];
};
layout(std430, binding = VISIBILITY_PIXELS_BINDING) readonly buffer VisibilityPixels { uint pixels[]; };
layout(binding = VISIBILITY_UNIT) uniform usampler2D visibility_ids;
#ifndef RESOLVE_MIRROR  // a mirror pass's images: visibility.glsl
layout(binding = GB_SHADE_IMAGE, rgba32ui) writeonly uniform uimage2D gb_shade;
layout(binding = GB_FRAME_IMAGE, rgba32ui) writeonly uniform uimage2D gb_frame;
#endif

uniform mat4 view_proj;  // the raster pass's
uniform int batch;       // the texture batch this dispatch resolves

// Perspective-correct barycentrics of the point of the triangle (clip-space vertices c0, c1, c2) seen
// at normalised device coordinates p: b with sum 1 and (b . X) / (b . W) = p.x, (b . Y) / (b . W) = p.y,
// i.e. b orthogonal to (X - p.x W) and (Y - p.y W) -- their cross product (2-D homogeneous
// rasterisation, Olano and Greer 1997: no division by a vertex's w, so vertices behind the eye need no
// clipping).
vec3 barycentrics(vec4 c0, vec4 c1, vec4 c2, vec2 p) {
    vec3 u = vec3(c0.x - p.x * c0.w, c1.x - p.x * c1.w, c2.x - p.x * c2.w);
    vec3 v = vec3(c0.y - p.y * c0.w, c1.y - p.y * c1.w, c2.y - p.y * c2.w);
    vec3 b = cross(u, v);
    float sum = b.x + b.y + b.z;
    return abs(sum) > 0.0 ? b / sum : vec3(1.0 / 3.0);
}

vec2 mix3(vec3 b, vec2 a0, vec2 a1, vec2 a2) {
    return b.x * a0 + b.y * a1 + b.z * a2;
}

vec3 mix3(vec3 b, vec3 a0, vec3 a1, vec3 a2) {
    return b.x * a0 + b.y * a1 + b.z * a2;
}

vec4 mix3(vec3 b, vec4 a0, vec4 a1, vec4 a2) {
    return b.x * a0 + b.y * a1 + b.z * a2;
}

void main() {
    ivec2 size = textureSize(visibility_ids, 0);
    if (gl_GlobalInvocationID.x >= counts[batch])
        return;
    ivec2 pixel = vis_unpack_pixel(pixels[offsets[batch] + gl_GlobalInvocationID.x]);
    uint id = texelFetch(visibility_ids, pixel, 0).x;
    uint first = 3u * vis_triangle(id);
    uint k0 = vertex_indices[first], k1 = vertex_indices[first + 1u], k2 = vertex_indices[first + 2u];
    int object = vertex_int(k0, VERTEX_OBJECT);
    vec3 p0 = vertex3(k0, VERTEX_POSITION), p1 = vertex3(k1, VERTEX_POSITION), p2 = vertex3(k2, VERTEX_POSITION);
    vec4 c0 = view_proj * vec4(p0, 1.0), c1 = view_proj * vec4(p1, 1.0), c2 = view_proj * vec4(p2, 1.0);
    vec2 step = 2.0 / vec2(size);  // one pixel in normalised device coordinates
    vec2 ndc = (vec2(pixel) + 0.5) * step - 1.0;
    vec3 b = barycentrics(c0, c1, c2, ndc);
    vec2 quad = (vec2(pixel & ~1) + 0.5) * step - 1.0;
    vec3 bq = barycentrics(c0, c1, c2, quad);
    vec3 bx = barycentrics(c0, c1, c2, quad + vec2(step.x, 0.0));
    vec3 by = barycentrics(c0, c1, c2, quad + vec2(0.0, step.y));

    SurfaceInput i;
    i.position = mix3(b, p0, p1, p2);
    i.normal = mix3(b, vertex3(k0, VERTEX_NORMAL), vertex3(k1, VERTEX_NORMAL), vertex3(k2, VERTEX_NORMAL));
    i.tangent = mix3(b, vertex4(k0, VERTEX_TANGENT), vertex4(k1, VERTEX_TANGENT), vertex4(k2, VERTEX_TANGENT));
    vec2 t0 = vertex2(k0, VERTEX_UV), t1 = vertex2(k1, VERTEX_UV), t2 = vertex2(k2, VERTEX_UV);
    i.uv = mix3(b, t0, t1, t2);
    vec2 uv_quad = mix3(bq, t0, t1, t2);
    i.uv_dx = mix3(bx, t0, t1, t2) - uv_quad;
    i.uv_dy = mix3(by, t0, t1, t2) - uv_quad;
    i.color = mix3(b, vertex3(k0, VERTEX_COLOR), vertex3(k1, VERTEX_COLOR), vertex3(k2, VERTEX_COLOR));
    i.lm_uv = mix3(b, vertex2(k0, VERTEX_LM_UV), vertex2(k1, VERTEX_LM_UV), vertex2(k2, VERTEX_LM_UV));
    i.lm_page = vertex_int(k2, VERTEX_LM_PAGE);  // a flat varying's: the provoking (last) vertex's
    i.object = object;
    i.front_facing = vis_front_facing(id);
    i.face_normal = cross(p1 - p0, p2 - p0);

    RasterSurface s = raster_surface(i);
#ifdef RESOLVE_MIRROR
    // mirror.frag's: diffuse + emission towards the mirrored eye, the unmirrored point, the mesh normal
    vec3 L = s.dark ? vec3(0.0) : s.diffuse + constant_emission(materials[object_material(object)]);
    imageStore(mirror_radiance_image, ivec3(pixel, layer), vec4(clean_half_radiance(L), 1.0));
    imageStore(mirror_position_image, ivec3(pixel, layer), vec4(i.position, 1.0));
    imageStore(mirror_normal_image, ivec3(pixel, layer), vec4(s.mesh_normal, 0.0));
#else
    imageStore(gb_shade, pixel, uvec4(floatBitsToUint(s.diffuse), gb_pack_ids(object_material(object), object)));
    imageStore(gb_frame, pixel, gb_pack_frame(s.normal, s.tangent, s.bitangent_sign, s.dark, s.normal_mapped, s.mr));
#endif
}
