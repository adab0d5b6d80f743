// The split-sum approximation (Karis 2013; viewer/split_sum.py says what and why): one look-up of
// the prefiltered cube map (or of the mirror buffer, for planar reflectors) at the lobe's centre
// direction, times the lobe's directional albedo from a per-lobe LUT. specular.glsl includes
// this file when SPLIT_SUM is defined, after its own helpers, which it uses (SpecularPoint,
// planar_lobe_lod, planar_lookup), and calls `split_sum_estimate` for SPECULAR_SPLIT_SUM.

// The prefiltered chains, one samplerCubeArray per size class of cubemaps.glsl (same class and
// layer as the object's own map); the albedo is the walkthrough's table (lobe_albedo.glsl).
layout(binding = SPLIT_SUM_FIRST_UNIT) uniform samplerCubeArray split_sum_maps[CUBE_CLASSES];
uniform float split_sum_levels[CUBE_CLASSES];  // levels of each class's prefiltered chain

// The level holding roughness m: sqrt(m / M_MAX) (levels - 1), clamped (viewer/split_sum.py
// level_roughness is its inverse).
float split_sum_lod(float m, float levels) {
    return sqrt(clamp(m / SPLIT_SUM_M_MAX, 0.0, 1.0)) * (levels - 1.0);
}

// Prefiltered radiance of the object's cube map along `dir` for a lobe of roughness m,
// trilinear between the two nearest levels.
vec3 split_sum_cube(CubeObject c, vec3 dir, float m) {
    vec3 L = vec3(0.0);
    for (int k = 0; k < CUBE_CLASSES; ++k)  // a loop index is dynamically uniform: legal array index
        if (k == c.info.x)
            L = textureLod(split_sum_maps[k], vec4(dir, float(c.info.y)), split_sum_lod(m, split_sum_levels[k])).rgb;
    return L;
}

// One lobe's split-sum estimate (without ks): prefiltered radiance at the lobe centre -- the
// mirror direction, or the straight-through one for a transmission lobe -- times its albedo.
// Cube maps: the centre direction through the bounding planes (section 4.4.1; engines' parallax-
// corrected cube maps), at the level of the isotropic roughness sqrt(mx my). Planar reflectors:
// the centre's projection into the mirror buffer, at the MIP level of the lobe's footprint there.
vec3 split_sum_estimate(SpecularPoint sp, Lobe lobe, int lobe_index, bool planar) {
    vec3 centre = pattern_direction(sp.wo, vec2(1.0, 0.0), lobe);  // xi1 = 1: the lobe centre
    bool exact;  // the factor's albedo where the table is not the texel's: the best split-sum has
    float albedo = lobe_albedo_at(sp.wo, lobe_index, sp.texel.x, sp.texel.y, exact);
    vec3 L;
    if (planar) {
        MirrorSample ms;
        L = planar_lookup(sp, centre, sp.centre.position, sp.centre.normal, planar_lobe_lod(sp, lobe, 1), ms);
    } else {
        float m = sqrt(max(lobe.shape.x, M_MIN) * max(lobe.shape.y, M_MIN));
        L = split_sum_cube(sp.cube, bounding_plane_direction(sp.cube, sp.position, sp.frame * centre), m);
        specular_lookups += 1;
    }
    return albedo * L;
}
