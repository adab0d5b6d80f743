// The section 3.3 material (Eq. 3.6: kd/pi + lobes, plus emission) as viewer/gpu_materials.py packs
// it into shader storage buffers (std430). Flags (MAT_*) come in as defines from gpu_materials.py and
// bindings from gl_bindings.py, so the Python packer and this declaration cannot drift apart.

struct Material {
    vec4 kd;        // rgb: diffuse reflectance kd; a: base colour alpha factor (MAT_ALPHA_* only)
    vec4 emission;  // rgb: emitted radiance, W/(m^2 sr); a: alphaCutoff (MAT_ALPHA_MASK only)
    ivec4 info;     // x: MAT_* flags, y: kd texture index (-1: none), z: first lobe, w: lobe count
    vec4 surface;   // x: normalTexture scale; y, z: cos, sin of anisotropyRotation
};

struct Lobe {
    vec4 ks;        // rgb: lobe weight ks (Eq. 3.2) or kt (Eq. 3.6); a: LOBE_REFLECT or LOBE_TRANSMIT
    vec4 shape;     // x: mx, y: my (Beckmann roughness, Eq. 3.3), z: r0 (Schlick), w: alpha (Eq. 3.4)
};

layout(std430, binding = MATERIAL_BINDING) readonly buffer MaterialBuffer { Material materials[]; };
layout(std430, binding = LOBE_BINDING) readonly buffer LobeBuffer { Lobe lobes[]; };
// Per lobe: LOBE_MR_NONE, or how the material's metallic-roughness texture changes it (LOBE_MR_DIELECTRIC,
// LOBE_MR_METAL; specular.glsl lobe_at_pixel).
layout(std430, binding = LOBE_MR_BINDING) readonly buffer LobeMrBuffer { int lobe_mr[]; };

bool has_flag(Material m, int flag) {
    return (m.info.x & flag) != 0;
}

// The emission the shading passes add to a pixel: the constant emission, or nothing for textured
// emitters, whose emission x texture the raster pass already put in the diffuse radiance.
vec3 constant_emission(Material m) {
    return has_flag(m, MAT_EMISSION_TEXTURE) ? vec3(0.0) : m.emission.rgb;
}
