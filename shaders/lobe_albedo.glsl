// The lobes' directional albedo int f cos dw (without ks) for a local view wo: the table of
// viewer/lobe_albedo.py (its docstring says why and how), read by the walkthrough's albedo-normalised
// pattern estimate (lobe_sampling.glsl ESTIMATE_ALBEDO, specular.glsl) and by split-sum.
// Layers of LOBE_ALBEDO_COS x LOBE_ALBEDO_PHI values, row-major: row i at sqrt(cos theta_v) =
// i / (COS - 1), column j at the view azimuth j / (PHI - 1) pi / 2, read bilinearly here (a storage
// buffer, not a texture: cheaper on llvmpipe). Per lobe a row: x its first layer, y its node count
// along z's axis (the texel's metallic-roughness factor g, or its anisotropy strength s, in [0, 1];
// one node for LOBE_ALBEDO_AXIS_NONE), w its flags (LOBE_ALBEDO_EXACT: the table holds the texel's
// own lobe; LOBE_ALBEDO_ISOTROPIC: every column alike, the azimuth not needed).

layout(std430, binding = LOBE_ALBEDO_BINDING) readonly buffer LobeAlbedoBuffer { ivec4 lobe_albedo_rows[]; };
layout(std430, binding = LOBE_ALBEDO_TABLE_BINDING) readonly buffer LobeAlbedoTable { float lobe_albedo_values[]; };

const int LOBE_ALBEDO_LAYER = LOBE_ALBEDO_COS * LOBE_ALBEDO_PHI;

// One layer's value at the continuous grid position (column x, row y), bilinear.
float lobe_albedo_layer(int layer, vec2 p) {
    ivec2 i = min(ivec2(p), ivec2(LOBE_ALBEDO_PHI - 2, LOBE_ALBEDO_COS - 2));
    vec2 t = p - vec2(i);
    int base = layer * LOBE_ALBEDO_LAYER + i.y * LOBE_ALBEDO_PHI + i.x;
    float a = mix(lobe_albedo_values[base], lobe_albedo_values[base + 1], t.x);
    float b = mix(lobe_albedo_values[base + LOBE_ALBEDO_PHI], lobe_albedo_values[base + LOBE_ALBEDO_PHI + 1], t.x);
    return mix(a, b, t.y);
}

// Lobe `lobe_index`'s albedo at the view wo (wo.z >= 0; the lobe is symmetric in x and in y), for a
// texel of metallic-roughness factor g and anisotropy strength s (used only by lobes whose row has
// that axis): linear between the two nodes around it. `exact` false where the table is the
// factor's lobe, not the texel's. >= 0.
float lobe_albedo_at(vec3 wo, int lobe_index, float g, float s, out bool exact) {
    ivec4 row = lobe_albedo_rows[lobe_index];
    exact = (row.w & LOBE_ALBEDO_EXACT) != 0;
    float phi = 0.0;
    vec2 a = abs(wo.xy);
    if ((row.w & LOBE_ALBEDO_ISOTROPIC) == 0 && a.x + a.y > 0.0)
        phi = atan(a.y, a.x) / (0.5 * PI);
    vec2 p = vec2(phi, sqrt(clamp(wo.z, 0.0, 1.0))) * vec2(LOBE_ALBEDO_PHI - 1, LOBE_ALBEDO_COS - 1);
    float t = row.z == LOBE_ALBEDO_AXIS_ROUGHNESS ? g : row.z == LOBE_ALBEDO_AXIS_ANISOTROPY ? s : 0.0;
    float x = clamp(t, 0.0, 1.0) * float(max(row.y - 1, 0));
    float k = min(floor(x), float(max(row.y - 2, 0)));
    float albedo = lobe_albedo_layer(row.x + int(k), p);
    if (row.y > 1)
        albedo = mix(albedo, lobe_albedo_layer(row.x + int(k) + 1, p), x - k);
    return max(albedo, 0.0);
}
