// A visibility buffer's raster pass (viewer/passes/visibility.py: the G-buffer's, a mirror pass's), fragments: depth
// and, per pixel, the triangle and facing that cover it (visibility.glsl) -- no light map, no
// texture but the coverage test's. MASK and BLEND materials drop the fragments the G-buffer's own
// raster pass drops (raster_surface.glsl coverage_discards), so both leave the same depth.
// Vertex side: gbuffer.vert (with MIRROR_CLIP in a mirror pass). visibility_resolve.comp turns the ids
// into what the pass's own fragment shader would have written (viewer/passes/visibility.py).

#include "raster_surface.glsl"
#include "visibility.glsl"

layout(location = VISIBILITY_LOCATION) out uint out_id;

void main() {
    SurfaceInput i = fragment_surface_input();
    if (coverage_discards(materials[object_material(i.object)], i))
        discard;
    // gl_PrimitiveID counts from 0 in each command of a multi-draw, which draws the object's range of
    // the index buffer (scene_objects.glsl info.z: its first index)
    out_id = vis_pack(uint(scene_objects[i.object].info.z) / 3u + uint(gl_PrimitiveID), gl_FrontFacing);
}
