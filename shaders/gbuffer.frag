// G-buffer pass, fragments: everything the shading pass needs that depends on the surface only.
// The layout is documented once, in gbuffer_layout.glsl; gbuffer_read.glsl reads it back.

#include "raster_surface.glsl"
#include "gbuffer_layout.glsl"

layout(location = GB_SHADE_LOCATION) out uvec4 out_shade;
layout(location = GB_FRAME_LOCATION) out uvec4 out_frame;

void main() {
    RasterSurface s = fragment_surface();
    out_shade = uvec4(floatBitsToUint(s.diffuse), gb_pack_ids(object_material(v_object), v_object));
    out_frame = gb_pack_frame(s.normal, s.tangent, s.bitangent_sign, s.dark, s.normal_mapped, s.mr);
}
