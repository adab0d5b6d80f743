// Constants and numerically guarded helpers shared by every pass.
// Nothing non-finite may reach a frame buffer (docs/ARCHITECTURE.md, "Numerics"): helpers that divide
// or normalise take a fallback instead of trusting their input.

const float PI = 3.14159265358979323846;
const float INV_PI = 0.31830988618379067154;
// Largest radiance a pass stores: N x N of them (N <= 8) still sum to a finite fp32.
const float RADIANCE_MAX = 1e30;

// NaN and +-Inf components become 0.
vec3 finite_or_zero(vec3 v) {
    return vec3(isnan(v.x) || isinf(v.x) ? 0.0 : v.x,
                isnan(v.y) || isinf(v.y) ? 0.0 : v.y,
                isnan(v.z) || isinf(v.z) ? 0.0 : v.z);
}

// Radiance as a pass may store it: finite, non-negative, at most RADIANCE_MAX.
vec3 clean_radiance(vec3 v) {
    return min(max(finite_or_zero(v), vec3(0.0)), vec3(RADIANCE_MAX));
}

// Radiance for a half-float (rgba16f) target: clean_radiance clamped to the largest half float,
// HALF_MAX (a define from core/constants.py). A larger value's conversion is implementation-dependent (GL 4.5, 2.3.4.2): Mesa clamps,
// other drivers may store Inf, which the mirror buffer's MIP chain would spread (a 1e5 lamp seen in
// a mirror: glint bench --stress, the emitters case).
vec3 clean_half_radiance(vec3 v) {
    return min(clean_radiance(v), vec3(HALF_MAX));
}

// v / |v|, or `fallback` when v is (nearly) zero or not finite.
vec3 safe_normalize(vec3 v, vec3 fallback) {
    float len2 = dot(v, v);
    return (len2 > 1e-30 && !isinf(len2) && !isnan(len2)) ? v * inversesqrt(len2) : fallback;
}

// Rec. 709 luminance (the weights of bake/lights.py).
float luminance(vec3 rgb) {
    return dot(rgb, vec3(0.2126, 0.7152, 0.0722));
}
