// Reading the G-buffer back in compute passes (layout: gbuffer_layout.glsl).

#include "common.glsl"
#include "camera.glsl"
#include "gbuffer_layout.glsl"

layout(binding = GB_SHADE_UNIT) uniform usampler2D gb_shade;
layout(binding = GB_FRAME_UNIT) uniform usampler2D gb_frame;
layout(binding = GB_DEPTH_UNIT) uniform sampler2D gb_depth;

// One visible surface point, as the shading pass and its per-pixel hooks see it.
struct Surface {
    vec3 position;       // world space, reconstructed from depth
    vec3 normal;         // unit, on the side facing the viewer
    vec3 tangent;        // unit or zero (no tangent frame)
    float bitangent_sign;
    float anisotropy;    // the strength factor s of an anisotropy texture (the tangent's length)
    bool normal_mapped;  // the normal is a normal map's (gbuffer_layout.glsl)
    vec3 to_eye;         // unit direction from the point to the eye (-ray)
    vec3 diffuse;        // light-mapped diffuse radiance kd/pi * E
    int material;
    int object;          // index of the object in the bake manifest
    bool dark;           // back face of a single-sided material: sends no light to the viewer
    vec2 mr;             // metallic-roughness texel: roughness multiplier g, metallic M' (GB_FRAME's w)
};

// True where nothing was drawn (the sky shows).
bool gbuffer_empty(ivec2 p) {
    return texelFetch(gb_depth, p, 0).r >= 1.0;
}

Surface gbuffer_surface(ivec2 p, vec3 ray) {
    Surface s;
    uvec4 shade = texelFetch(gb_shade, p, 0);
    uvec4 frame = texelFetch(gb_frame, p, 0);
    s.normal = safe_normalize(gb_oct_decode(unpackSnorm2x16(frame.x)), -ray);
    s.anisotropy = unpackUnorm2x16(frame.z & 0xFFFFu).x;
    s.tangent = s.anisotropy > 0.0 ? gb_oct_decode(unpackSnorm2x16(frame.y)) : vec3(0.0);
    s.normal_mapped = (frame.z & GB_NORMAL_MAPPED_BIT) != 0u;
    s.bitangent_sign = (frame.z & GB_BITANGENT_NEGATIVE_BIT) != 0u ? -1.0 : 1.0;
    s.dark = (frame.z & GB_DARK_BIT) != 0u;
    s.diffuse = uintBitsToFloat(shade.xyz);
    s.mr = unpackUnorm2x16(frame.w);
    s.material = gb_material_id(shade.w);
    s.object = gb_object_id(shade.w);
    // ray is a unit vector within the field of view, so dot(ray, cam_forward) > 0.
    float along = eye_depth(texelFetch(gb_depth, p, 0).r) / max(dot(ray, cam_forward), 1e-6);
    s.position = eye + ray * along;
    s.to_eye = -ray;
    return s;
}
