// Display transforms: a filmic curve and the sRGB transfer function.

// The ACES filmic curve as fitted by K. Narkowicz, "ACES Filmic Tone Mapping Curve" (blog,
// 2016-01-06): a rational fit of ACES' RRT+ODT, per channel, pre-exposed so that 1 maps to ~0.8.
// Inputs are clamped to [0, 1e4], where the curve has long reached 1, so x * x cannot overflow.
vec3 aces_narkowicz(vec3 x) {
    x = clamp(x, 0.0, 1e4);
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

// sRGB OETF (IEC 61966-2-1): linear [0, 1] -> encoded [0, 1].
vec3 srgb_oetf(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    vec3 lo = 12.92 * c;
    vec3 hi = 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055;
    return mix(hi, lo, lessThanEqual(c, vec3(0.0031308)));
}
