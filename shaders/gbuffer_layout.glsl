// The G-buffer's render targets (viewer/passes/gbuffer.py allocates them; their attachment numbers
// come in as defines GB_*_LOCATION from viewer/gl_bindings.py):
//   GB_DIFFUSE   rgba32f  rgb: light-mapped diffuse radiance kd/pi * E (0 on dark back faces), plus
//                         emission x emissiveTexture for MAT_EMISSION_TEXTURE materials
//   GB_NORMAL    rgba16f  xyz: unit shading normal on the side the viewer sees (a normal map's);
//                         w: GB_DARK_BACK_FACE on back faces of single-sided materials, else
//                         GB_NORMAL_MAPPED where a normal map perturbed it, else 0
//   GB_TANGENT   rgba16f  xyz: tangent orthogonal to the normal (the anisotropy direction), or 0;
//                         its length is the anisotropy strength factor s in 0..1 (the B of
//                         KHR_materials_anisotropy's texture; 1 without one); w: bitangent sign
//   GB_SURFACE   rg16f    metallic-roughness texel of MAT_MR_TEXTURE materials: x roughness multiplier g,
//                         y metallic M' (1, 0 for the others; specular.glsl lobe_at_pixel reads it)
//   GB_MATERIAL  r32ui    bits 0-15: material index, bits 16-31: object index (the object picks its
//                         cube map; gb_pack_ids / gb_material_id / gb_object_id)
//   depth        24 bit   window depth; 1.0 (the clear value) = nothing drawn = sky
// GB_DARK_BACK_FACE, GB_NORMAL_MAPPED and GB_ID_BITS (16) are defines from core/constants.py.

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
