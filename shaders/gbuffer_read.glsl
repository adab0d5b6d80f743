// Reading the G-buffer back in compute passes (layout: gbuffer_layout.glsl).

#include "common.glsl"
#include "camera.glsl"
#include "gbuffer_layout.glsl"

layout(binding = GB_DIFFUSE_UNIT) uniform sampler2D gb_diffuse;
layout(binding = GB_NORMAL_UNIT) uniform sampler2D gb_normal;
layout(binding = GB_TANGENT_UNIT) uniform sampler2D gb_tangent;
layout(binding = GB_MATERIAL_UNIT) uniform usampler2D gb_material;
layout(binding = GB_DEPTH_UNIT) uniform sampler2D gb_depth;
layout(binding = GB_SURFACE_UNIT) uniform sampler2D gb_surface;

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
    vec2 mr;             // metallic-roughness texel: roughness multiplier g, metallic M' (GB_SURFACE)
};

// True where nothing was drawn (the sky shows).
bool gbuffer_empty(ivec2 p) {
    return texelFetch(gb_depth, p, 0).r >= 1.0;
}

Surface gbuffer_surface(ivec2 p, vec3 ray) {
    Surface s;
    vec4 n = texelFetch(gb_normal, p, 0);
    vec4 t = texelFetch(gb_tangent, p, 0);
    s.normal = safe_normalize(n.xyz, -ray);
    s.tangent = safe_normalize(t.xyz, vec3(0.0));
    s.anisotropy = clamp(length(t.xyz), 0.0, 1.0);
    s.normal_mapped = n.w < 0.5 * GB_NORMAL_MAPPED;
    s.bitangent_sign = t.w < 0.0 ? -1.0 : 1.0;
    s.dark = n.w > 0.5 * GB_DARK_BACK_FACE;
    s.diffuse = texelFetch(gb_diffuse, p, 0).rgb;
    s.mr = clamp(texelFetch(gb_surface, p, 0).rg, 0.0, 1.0);
    uint ids = texelFetch(gb_material, p, 0).r;
    s.material = gb_material_id(ids);
    s.object = gb_object_id(ids);
    // ray is a unit vector within the field of view, so dot(ray, cam_forward) > 0.
    float along = eye_depth(texelFetch(gb_depth, p, 0).r) / max(dot(ray, cam_forward), 1e-6);
    s.position = eye + ray * along;
    s.to_eye = -ray;
    return s;
}
