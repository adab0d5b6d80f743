// G-buffer pass, fragments: everything the shading pass needs that depends on the surface only.
// The layout is documented once, in gbuffer_layout.glsl; gbuffer_read.glsl reads it back.

#include "raster_surface.glsl"
#include "gbuffer_layout.glsl"

layout(location = GB_DIFFUSE_LOCATION) out vec4 out_diffuse;
layout(location = GB_NORMAL_LOCATION) out vec4 out_normal;
layout(location = GB_TANGENT_LOCATION) out vec4 out_tangent;
layout(location = GB_MATERIAL_LOCATION) out uint out_material;
layout(location = GB_SURFACE_LOCATION) out vec2 out_surface;

void main() {
    RasterSurface s = raster_surface();
    out_diffuse = vec4(s.diffuse, 1.0);
    out_normal = vec4(s.normal, s.dark ? GB_DARK_BACK_FACE : s.normal_mapped ? GB_NORMAL_MAPPED : 0.0);
    out_tangent = vec4(s.tangent, s.bitangent_sign);
    out_material = gb_pack_ids(object_material(), v_object);
    out_surface = s.mr;
}
