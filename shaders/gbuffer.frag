// G-buffer pass, fragments: everything the shading pass needs that depends on the surface only.
// The layout is documented once, in gbuffer_read.glsl, which reads it back.

#include "common.glsl"
#include "materials.glsl"
#include "gbuffer_layout.glsl"

uniform int material_index;
uniform sampler2D kd_texture;       // the material's base colour (1x1 white when it has none)
uniform sampler2DArray lightmaps;   // irradiance E (rgb), one layer per page
uniform vec3 eye;

in vec3 v_position;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
in vec2 v_lm_uv;
flat in int v_lm_page;
flat in int v_object;

layout(location = GB_DIFFUSE) out vec4 out_diffuse;
layout(location = GB_NORMAL) out vec4 out_normal;
layout(location = GB_TANGENT) out vec4 out_tangent;
layout(location = GB_MATERIAL) out uint out_material;

void main() {
    Material m = materials[material_index];
    vec3 to_eye = safe_normalize(eye - v_position, vec3(0.0, 0.0, 1.0));

    // Geometric normal from screen-space derivatives, towards the viewer: the fallback for
    // zero-length vertex normals.
    vec3 ng = safe_normalize(cross(dFdx(v_position), dFdy(v_position)), to_eye);
    ng = dot(ng, to_eye) < 0.0 ? -ng : ng;
    vec3 n = safe_normalize(v_normal, gl_FrontFacing ? ng : -ng);

    // Back faces (clockwise on screen) of one-sided materials are black, as in Mitsuba:
    // neither their BSDF nor their emission acts on that side. Seen from the back, the
    // shading frame of a double-sided material flips.
    bool back = !gl_FrontFacing;
    bool dark = back && !has_flag(m, MAT_TWO_SIDED);
    if (back)
        n = -n;

    // Light-mapped diffuse radiance, Eq. 4.1: L = kd / pi * E (times the base-colour texture).
    vec3 kd = m.kd.rgb;
    if (has_flag(m, MAT_KD_TEXTURE))
        kd *= texture(kd_texture, v_uv).rgb;
    vec3 E = clean_radiance(texture(lightmaps, vec3(v_lm_uv, float(v_lm_page))).rgb);
    vec3 diffuse = dark ? vec3(0.0) : clean_radiance(max(kd, 0.0) * INV_PI * E);

    // Tangent frame for anisotropic lobes (later issues): Gram-Schmidt against n; zero if none.
    vec3 t = v_tangent.xyz - n * dot(v_tangent.xyz, n);
    t = safe_normalize(t, vec3(0.0));
    float sign_b = v_tangent.w < 0.0 ? -1.0 : 1.0;

    out_diffuse = vec4(diffuse, 1.0);
    out_normal = vec4(n, dark ? GB_DARK_BACK_FACE : 0.0);
    out_tangent = vec4(t, back ? -sign_b : sign_b);
    out_material = gb_pack_ids(material_index, v_object);
}
