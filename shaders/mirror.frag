// Mirror pass of a planar reflector (section 4.5.1), fragments: the diffuse scene seen in the
// mirror -- light-mapped diffuse + emission only (the last bounce alone is view-dependent) -- and
// the world position and normal of the *unmirrored* scene point, which the sample projection of
// section 4.5.2 intersects rays with (bench/mirror_projection.py). Layout: viewer/passes/mirror.py.
// Vertex side: gbuffer.vert with MIRROR_CLIP (clipped at the mirror plane).

#include "raster_surface.glsl"

layout(location = MIRROR_RADIANCE_LOCATION) out vec4 out_radiance;  // rgba16f: outgoing radiance towards the mirrored eye
layout(location = MIRROR_POSITION_LOCATION) out vec4 out_position;  // rgba32f: xyz world position, w = 1 (0 where nothing was drawn)
layout(location = MIRROR_NORMAL_LOCATION) out vec4 out_normal;    // rgba16f: xyz unit normal on the seen side (0 where nothing was drawn)

void main() {
    RasterSurface s = fragment_surface();
    vec3 L = s.dark ? vec3(0.0) : s.diffuse + constant_emission(materials[object_material(v_object)]);
    out_radiance = vec4(clean_half_radiance(L), 1.0);
    out_position = vec4(v_position, 1.0);
    out_normal = vec4(s.mesh_normal, 0.0);  // the surface's, not a normal map's: the projection's tangent plane
}
