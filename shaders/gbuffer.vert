// G-buffer pass, vertices: bake meshes are already in world space.

uniform mat4 view_proj;

in vec3 in_position;
in vec3 in_normal;
in vec4 in_tangent;     // xyz: tangent along +u of the texture; w: bitangent sign (0 0 0 0: none)
in vec2 in_uv;          // base-colour texture coordinates (glTF TEXCOORD_0)
in vec2 in_lm_uv;       // light-map coordinates, texel (y, x) centred at ((x + .5) / W, (y + .5) / H)
in int in_lm_page;      // light-map page = layer of the texture array
in int in_object;       // index of the object in the bake manifest

out vec3 v_position;
out vec3 v_normal;
out vec4 v_tangent;
out vec2 v_uv;
out vec2 v_lm_uv;
flat out int v_lm_page;
flat out int v_object;

void main() {
    v_position = in_position;
    v_normal = in_normal;
    v_tangent = in_tangent;
    v_uv = in_uv;
    v_lm_uv = in_lm_uv;
    v_lm_page = in_lm_page;
    v_object = in_object;
    gl_Position = view_proj * vec4(in_position, 1.0);
}
