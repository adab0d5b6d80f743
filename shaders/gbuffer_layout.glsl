// The G-buffer's render targets (viewer/passes/gbuffer.py allocates them; their attachment numbers
// come in as defines GB_*_LOCATION from viewer/gl_bindings.py). Two RGBA32UI targets, 32 bytes per
// pixel, packed here: fewer bytes than float targets, and integer targets are the raster back end's
// cheap path (measured: docs/VIEWER.md, "A thinner G-buffer").
//   GB_SHADE  xyz: light-mapped diffuse radiance kd/pi * E (float bits; 0 on dark back faces), plus
//                  emission x emissiveTexture for MAT_EMISSION_TEXTURE materials
//             w:   ids: bits 0-15 material index, bits 16-31 object index (the object picks its cube
//                  map; gb_pack_ids / gb_material_id / gb_object_id)
//   GB_FRAME  x:   unit shading normal on the side the viewer sees (a normal map's), octahedral
//                  (Cigolle et al. 2014, "A Survey of Efficient Representations for Independent Unit
//                  Vectors"), 2 x snorm16
//             y:   tangent direction orthogonal to the normal (the anisotropy direction), octahedral
//             z:   bits 0-15: the tangent's length, unorm16: the anisotropy strength factor s in 0..1
//                  (the B of KHR_materials_anisotropy's texture; 1 without one; 0: no tangent frame);
//                  GB_DARK_BIT on back faces of single-sided materials, GB_NORMAL_MAPPED_BIT where a
//                  normal map perturbed the normal, GB_BITANGENT_NEGATIVE_BIT for a bitangent sign -1
//             w:   metallic-roughness texel of MAT_MR_TEXTURE materials, 2 x unorm16: roughness
//                  multiplier g, metallic M' (1, 0 for the others; specular.glsl lobe_at_pixel reads it)
//   depth     24 bit window depth; 1.0 (the clear value) = nothing drawn = sky
// GB_ID_BITS and the GB_*_BIT flags are defines from core/constants.py.

const uint GB_ID_MASK = (1u << GB_ID_BITS) - 1u;

// Material and object index share the one integer target: at most 65536 of each.
uint gb_pack_ids(int material, int object) {
    return (uint(object) << GB_ID_BITS) | (uint(material) & GB_ID_MASK);
}

int gb_material_id(uint ids) {
    return int(ids & GB_ID_MASK);
}

int gb_object_id(uint ids) {
    return int(ids >> GB_ID_BITS);
}

vec2 gb_sign_not_zero(vec2 v) {
    return vec2(v.x >= 0.0 ? 1.0 : -1.0, v.y >= 0.0 ? 1.0 : -1.0);
}

// Octahedral map of a unit vector to [-1, 1]^2 and back (Cigolle et al. 2014, listing 1).
vec2 gb_oct_encode(vec3 n) {
    n /= max(abs(n.x) + abs(n.y) + abs(n.z), 1e-30);
    return n.z >= 0.0 ? n.xy : (1.0 - abs(n.yx)) * gb_sign_not_zero(n.xy);
}

vec3 gb_oct_decode(vec2 p) {
    vec3 n = vec3(p, 1.0 - abs(p.x) - abs(p.y));
    if (n.z < 0.0)
        n.xy = (1.0 - abs(n.yx)) * gb_sign_not_zero(n.xy);
    return normalize(n);
}

uvec4 gb_pack_frame(vec3 normal, vec3 tangent, float bitangent_sign, bool dark, bool normal_mapped, vec2 mr) {
    float s = length(tangent);
    vec3 direction = s > 0.0 ? tangent / s : vec3(0.0, 0.0, 1.0);
    uint flags = (dark ? GB_DARK_BIT : 0u) | (normal_mapped ? GB_NORMAL_MAPPED_BIT : 0u)
               | (bitangent_sign < 0.0 ? GB_BITANGENT_NEGATIVE_BIT : 0u);
    return uvec4(packSnorm2x16(gb_oct_encode(normal)), packSnorm2x16(gb_oct_encode(direction)),
                 (packUnorm2x16(vec2(clamp(s, 0.0, 1.0), 0.0)) & 0xFFFFu) | flags, packUnorm2x16(clamp(mr, 0.0, 1.0)));
}
