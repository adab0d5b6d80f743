// The visibility buffer's raster pass (viewer/passes/gbuffer.py with `visibility`), fragments: depth
// and, per pixel, the object, triangle and facing that cover it (visibility.glsl) -- no light map, no
// texture but the coverage test's. MASK and BLEND materials drop the fragments the G-buffer's own
// raster pass drops (raster_surface.glsl coverage_discards), so both leave the same depth.
// Vertex side: gbuffer.vert. gbuffer_resolve.comp turns the ids into the G-buffer.

#include "raster_surface.glsl"
#include "visibility.glsl"

layout(location = VISIBILITY_LOCATION) out uvec2 out_ids;

void main() {
    SurfaceInput i = fragment_surface_input();
    if (coverage_discards(materials[object_material(i.object)], i))
        discard;
    out_ids = vis_pack(v_object, gl_PrimitiveID, gl_FrontFacing);
}
