// Raster passes over the bake's meshes, vertices: the G-buffer (gbuffer.frag), the mirror passes of
// planar reflectors (mirror.frag, with MIRROR_CLIP defined) and their occlusion queries
// (occlusion.frag). Bake meshes are already in world space.

uniform mat4 view_proj;
#ifdef MIRROR_CLIP
// The mirror plane, (a, b, c, d) in world space with the real eye's side positive
// (viewer/mirror_camera.py `clip_plane`): geometry behind the mirror is clipped away.
uniform vec4 clip_plane;
out float gl_ClipDistance[1];
#endif

// The occlusion queries redraw G-buffer geometry and test it against the G-buffer's depth with
// "<=": the same positions must give the same depth in both programs.
invariant gl_Position;

in vec3 in_position;
in vec3 in_normal;
in vec4 in_tangent;     // xyz: tangent along +u of the texture; w: bitangent sign (0 0 0 0: none)
in vec2 in_uv;          // base-colour texture coordinates (its texCoord set, KHR_texture_transform applied)
in vec2 in_lm_uv;       // light-map coordinates, texel (y, x) centred at ((x + .5) / W, (y + .5) / H)
in int in_lm_page;      // light-map page = layer of the texture array
in int in_object;       // index of the object in the bake manifest
in vec3 in_color;       // vertex colour (glTF COLOR_0; -1 without): multiplies the base colour

out vec3 v_position;
out vec3 v_normal;
out vec4 v_tangent;
out vec2 v_uv;
out vec2 v_lm_uv;
flat out int v_lm_page;
flat out int v_object;
out vec3 v_color;

void main() {
    v_position = in_position;
    v_normal = in_normal;
    v_tangent = in_tangent;
    v_uv = in_uv;
    v_lm_uv = in_lm_uv;
    v_lm_page = in_lm_page;
    v_object = in_object;
    v_color = in_color;
    gl_Position = view_proj * vec4(in_position, 1.0);
#ifdef MIRROR_CLIP
    gl_ClipDistance[0] = dot(clip_plane, vec4(in_position, 1.0));
#endif
}
