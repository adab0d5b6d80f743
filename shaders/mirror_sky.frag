// Mirror passes (viewer/passes/mirror.py), after the scene: the sky where the mirror camera saw
// nothing, drawn as one triangle over the viewport at the far plane (blit.vert with FAR_PLANE,
// depth test "<=" against the pass's depth: only texels still at the clear depth get it), so
// look-ups and the MIP chain built next find the sky there. The mirror buffer has the main view's
// size over a field widened by the pass's guard band (viewer/reflectors.py; the caller scales
// cam_right and cam_up by its s): its pixel p looks along the main camera's ray through
// (p - centre) * s + centre reflected about the mirror plane (p itself when s = 1).

#include "common.glsl"
#include "camera.glsl"
#include "sky.glsl"

uniform vec3 mirror_normal_world;  // the plane's unit normal
uniform ivec2 buffer_size;

layout(location = MIRROR_RADIANCE_LOCATION) out vec4 out_radiance;
layout(location = MIRROR_POSITION_LOCATION) out vec4 out_position;
layout(location = MIRROR_NORMAL_LOCATION) out vec4 out_normal;

void main() {
    vec3 ray = view_ray(ivec2(gl_FragCoord.xy), buffer_size);
    out_radiance = vec4(clean_half_radiance(sky_radiance(reflect(ray, mirror_normal_world))), 1.0);
    out_position = vec4(0.0);
    out_normal = vec4(0.0);  // background: no plane to intersect (mirror_buffer.glsl)
}
