// The lobes' directional albedo int f cos dw (without ks) for a local view wo: the table of
// viewer/lobe_albedo.py (its docstring says why and how), read by the walkthrough's albedo-normalised
// pattern estimate (lobe_sampling.glsl ESTIMATE_ALBEDO, specular.glsl) and by split-sum.
// Layers of LOBE_ALBEDO_PHI x LOBE_ALBEDO_COS texels: x the view azimuth in [0, pi/2], y
// sqrt(cos theta_v), nodes at both ends, bilinear. Per lobe a row: x its first layer, y its node
// count along z's axis (the texel's metallic-roughness factor g, or its anisotropy strength s, in
// [0, 1]; one node for LOBE_ALBEDO_AXIS_NONE), w 1 where the table holds the texel's own lobe.

layout(binding = LOBE_ALBEDO_UNIT) uniform sampler2DArray lobe_albedo_table;
layout(std430, binding = LOBE_ALBEDO_BINDING) readonly buffer LobeAlbedoBuffer { ivec4 lobe_albedo_rows[]; };

// The texture coordinates of the view wo (wo.z >= 0); the lobe is symmetric in x and in y.
vec2 lobe_albedo_uv(vec3 wo) {
    vec2 a = abs(wo.xy);
    float phi = a.x + a.y > 0.0 ? atan(a.y, a.x) : 0.0;
    vec2 node = vec2(phi / (0.5 * PI), sqrt(clamp(wo.z, 0.0, 1.0)));
    return (node * vec2(LOBE_ALBEDO_PHI - 1, LOBE_ALBEDO_COS - 1) + 0.5) / vec2(LOBE_ALBEDO_PHI, LOBE_ALBEDO_COS);
}

// Lobe `lobe_index`'s albedo at the view wo, for a texel of metallic-roughness factor g and
// anisotropy strength s (used only by lobes whose row has that axis): linear between the two nodes
// around it. `exact` false where the table is the factor's lobe, not the texel's. >= 0.
float lobe_albedo_at(vec3 wo, int lobe_index, float g, float s, out bool exact) {
    ivec4 row = lobe_albedo_rows[lobe_index];
    exact = row.w != 0;
    vec2 uv = lobe_albedo_uv(wo);
    float t = row.z == LOBE_ALBEDO_AXIS_ROUGHNESS ? g : row.z == LOBE_ALBEDO_AXIS_ANISOTROPY ? s : 0.0;
    float x = clamp(t, 0.0, 1.0) * float(max(row.y - 1, 0));
    float k = min(floor(x), float(max(row.y - 2, 0)));
    float a0 = textureLod(lobe_albedo_table, vec3(uv, float(row.x) + k), 0.0).r;  // no MIPs
    float a = a0;
    if (row.y > 1)
        a = mix(a0, textureLod(lobe_albedo_table, vec3(uv, float(row.x) + k + 1.0), 0.0).r, x - k);
    return max(a, 0.0);
}
