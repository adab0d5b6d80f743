// The raster half of a visibility buffer (bench/measure_thin_raster.py): depth and, per pixel, the
// object and triangle that cover it -- no texture read, no light map, one 32-bit target. Not a pass
// of the renderer: it measures how much of the G-buffer pass a visibility buffer could save.

#include "raster_surface.glsl"

layout(location = 0) out uvec2 out_ids;

void main() {
    out_ids = uvec2(uint(v_object), uint(gl_PrimitiveID));
}
