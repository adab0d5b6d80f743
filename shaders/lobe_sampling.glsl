// Deterministic regular lobe sampling for walkthroughs (thesis section 4.4.3): pattern directions
// (Eq. 4.10-4.13), the MIP level of each sample (Eq. 4.14-4.17, and Colbert-Krivanek's pdf-based
// level for filtered importance sampling), and the normalised estimators: the albedo-normalised
// mean (the default) and Eq. 4.24 / 4.25.
// The pattern positions in (xi1, xi2) space come from viewer/lobe_patterns.py, which also holds
// the numpy reference of every function here (tests/test_lobe_patterns.py holds them equal).
// Directions are in the local frame (t, b, n) of bsdf.glsl.

#include "bsdf.glsl"

// XI1_BORDER (Eq. 4.10's lobe border) and LOBE_TAN_MAX (Eq. 4.15's cap on tan(alpha): a wider
// lobe has no tangent-plane ellipse, and its samples are filtered at the coarsest MIP level
// anyway) are defines from core/constants.py.

// theta_thresh of Eq. 4.10 for the direction cs = (cos, sin)(phi_h):
//   arctan(sqrt(-log(xi1_border) / (cos^2 ph/mx^2 + sin^2 ph/my^2))).
float theta_thresh(vec2 cs, float mx, float my) {
    return atan(sqrt(-log(XI1_BORDER) / lobe_phi_factor(cs, mx, my)));
}

// The pattern sample at (xi1, xi2) mapped into the lobe: phi_h by Eq. 4.12 (= Eq. 4.5),
// theta_h = (1 - xi1) theta_thresh (Eq. 4.13), so xi1 = 1 is the lobe centre (the mirror or
// straight-through direction) and xi1 = 0 its border; then h by Eq. 4.7 and wi by Eq. 4.8
// (mirrored through the surface for a transmission lobe).
vec3 pattern_direction(vec3 wo, vec2 xi, Lobe lobe) {
    float mx = max(lobe.shape.x, M_MIN), my = max(lobe.shape.y, M_MIN);
    vec2 cs = lobe_phi(xi.y, mx, my);                   // Eq. 4.12
    float theta = (1.0 - xi.x) * theta_thresh(cs, mx, my);  // Eq. 4.13
    return scatter_about(wo, half_vector_at(cs, theta), lobe);  // Eq. 4.7-4.8
}

// tan of the angle between the lobe centre c and a border direction w (Eq. 4.14-4.15:
// u = tan(acos(c.w))), written as |c x w| / (c.w), which stays accurate for the tiny angles of
// near-mirror lobes where acos of a float near 1 does not; capped at LOBE_TAN_MAX (also for
// angles of 90 degrees and more, c.w <= 0).
float lobe_border_tan(vec3 c, vec3 w) {
    float cos_a = dot(c, w);
    float sin_a = length(cross(c, w));
    return cos_a * LOBE_TAN_MAX > sin_a ? sin_a / cos_a : LOBE_TAN_MAX;
}

// Half-axes (u, v) and area A = pi u v of the lobe's elliptical cross-section at unit distance
// (Eq. 4.14-4.15): the ellipse's vertices U, V are the border directions (xi1 = 0) at phi_h = 0
// and 90 degrees (xi2 = 0, 0.25: along t and b), its centre C the lobe centre (xi1 = 1).
vec2 lobe_ellipse_axes(vec3 wo, Lobe lobe) {
    vec3 c = pattern_direction(wo, vec2(1.0, 0.0), lobe);
    vec3 u = pattern_direction(wo, vec2(0.0, 0.0), lobe);
    vec3 v = pattern_direction(wo, vec2(0.0, 0.25), lobe);
    return vec2(lobe_border_tan(c, u), lobe_border_tan(c, v));
}

float lobe_ellipse_area(vec3 wo, Lobe lobe) {
    vec2 uv = lobe_ellipse_axes(wo, lobe);
    return PI * uv.x * uv.y;
}

// The solid angle of the lobe's cap: the ellipse of Eq. 4.14 with its half-axes as chords
// |c - w| = 2 sin(alpha / 2) instead of tan(alpha) (Lambert's equal-area projection, exact for a
// round cap: 2 pi (1 - cos alpha)). The two agree to first order for narrow lobes; past 45 degrees
// Eq. 4.15's area grows without bound (LOBE_TAN_MAX^2 pi), this one stays below 4 pi.
float lobe_cap_solid_angle(vec3 wo, Lobe lobe) {
    vec3 c = safe_normalize(pattern_direction(wo, vec2(1.0, 0.0), lobe), vec3(0.0));  // 0: no view, no cap
    vec3 u = safe_normalize(pattern_direction(wo, vec2(0.0, 0.0), lobe), c);
    vec3 v = safe_normalize(pattern_direction(wo, vec2(0.0, 0.25), lobe), c);
    return PI * length(c - u) * length(c - v);
}

// MIP level of a cube-map sample of area `sample_area` (A' = A / n at unit distance) along
// `dir_world` (any length), for faces of face_size^2 = N texels (Eq. 4.16-4.17):
//   A'_cube = A' d^2 / cos(beta)   (Eq. 4.16), pixels = A'_cube N / 4   (Eq. 4.17), level = log4(pixels).
// The cube is [-1, 1]^3 around the unit sphere; along the unit direction the face is reached at
// d = 1 / max|component| and its normal is tilted by cos(beta) = max|component|.
// Clamped to the levels that exist: 0 (a sample smaller than a texel) .. log2(face_size).
float cube_mip_level(float sample_area, vec3 dir_world, float face_size) {
    float len = length(dir_world);
    vec3 a = abs(dir_world);
    float m = max(max(a.x, a.y), a.z);
    if (!(m > 0.0))
        return 0.0;  // no direction: any level is as wrong as another
    float cos_beta = m / len;
    float d = 1.0 / cos_beta;
    float area_cube = sample_area * d * d / cos_beta;          // Eq. 4.16
    float pixels = area_cube * face_size * face_size / 4.0;    // Eq. 4.17
    return clamp(0.5 * log2(max(pixels, 1.0)), 0.0, log2(face_size));  // log4
}

// The footprint of one pattern sample from the lobe's second moment (viewer/lobe_patterns.py,
// "Footprint"), instead of the thesis' share A / n of the 99 % ellipse (Eq. 4.16), which for
// n = 1 is a box as wide as the lobe's support: a filter of ~2.7 times its standard deviation. Each
// sample's filter supplies the part of the lobe's spread that the pattern's own spread does not:
//   k_a = max(s^2 - v_a, s^2 / n)   per axis a = t, b of the lobe, in units of its border radius,
// s^2 = 1 / (-2 log xi1_border) the lobe's variance per axis (D falls as xi1_border^(r^2) to the
// border r = 1), v_a the D-weighted variance of the pattern's positions r (cos, sin)(2 pi xi2),
// r = 1 - xi1 (Eq. 4.12-4.13 in the lobe's ellipse scaled to a unit circle), s^2 / n the share of
// one of n samples. A bilinear look-up of a 2 x 2 box-filtered MIP level whose texels have area a
// filters with variance a / 4 per axis (box * tent), so the sample's area is 4 sqrt(K_t K_b),
// K_a = k_a times the squared half-axis (u or v of Eq. 4.15).
const float LOBE_AXIS_VARIANCE = -0.5 / log(XI1_BORDER);

struct PatternMoment {
    float w;     // sum of the weights D / D(centre) = xi1_border^(r^2)
    vec2 mean;   // their weighted sums of the position
    vec2 sq;     // ... and of its square
};

void add_pattern_moment(inout PatternMoment pm, vec2 xi) {
    float r = 1.0 - xi.x;
    vec2 p = r * vec2(cos(2.0 * PI * xi.y), sin(2.0 * PI * xi.y));
    float w = pow(XI1_BORDER, r * r);
    pm.w += w;
    pm.mean += w * p;
    pm.sq += w * p * p;
}

// The area (at unit distance, as A' of Eq. 4.16) that each of the pattern's n samples filters, for
// a lobe of ellipse half-axes uv = (u, v) (Eq. 4.15).
float pattern_footprint_area(PatternMoment pm, int n, vec2 uv) {
    vec2 mean = pm.mean / pm.w;
    vec2 v = max(pm.sq / pm.w - mean * mean, 0.0);
    vec2 k = max(vec2(LOBE_AXIS_VARIANCE) - v, vec2(LOBE_AXIS_VARIANCE / float(max(n, 1))));
    return 4.0 * sqrt(k.x * k.y) * uv.x * uv.y;
}

// Colbert and Krivanek's (2007) MIP level for n filtered importance samples, the comparison
// method of `glint bench` (filtered-is): the sample's solid angle omega_s = 1 / (n pdf) over a texel's
// omega_p = 4 pi / (6 N), N = face_size^2, level = 0.5 log2(omega_s / omega_p) (no bias term).
// Written as a difference of logarithms so that neither a tiny nor a huge pdf overflows;
// clamped to 0 .. log2(face_size) (a pdf of 0 gives the coarsest level).
float importance_mip_level(float pdf, int n, float face_size) {
    float n_pdf = max(float(n) * pdf, 1e-30);
    float level = 0.5 * (log2(6.0 * face_size * face_size / (4.0 * PI)) - log2(n_pdf));
    return clamp(level, 0.0, log2(face_size));
}

// The normalised estimators of the specular integral over a pattern. The thesis' two (Eq. 4.24,
// 4.25) are a weighted mean of each sample's radiance times its importance weight v = cos(theta_i) f / p:
//   Eq. 4.24: sum L cos^2 f / sum p cos             = sum w v L / sum w, w = p cos
//   Eq. 4.25: sum L cos^2 f^2 / p / sum f cos       = sum w v L / sum w, w = f cos
// Under uniform light neither reads the lobe's directional albedo A: Eq. 4.25 gives
// sum f^2 cos^2 / p / sum f cos, leaning towards the samples of large v, and with Kurt's alpha f
// carries (cos_i cos_o)^-alpha, which the pdf (Eq. 4.9) does not, so v grows towards the horizon and
// the bias with alpha (6-12 % too bright at 74.5 degrees for the fitted glTF lobes, issue 24). The
// default, ESTIMATE_ALBEDO, is the split sum's normalisation (Karis 2013) applied to the pattern:
//   A(wo) x sum w L / sum w, w = p cos   (Eq. 4.24 with each sample's v replaced by its mean A)
// -- exact under uniform light, the pattern's weighting of the light kept; A from the table of
// viewer/lobe_albedo.py (lobe_albedo.glsl), which also says why p cos and not f cos or v. The
// caller multiplies lobe_sum_result by A. Eq. 4.25 and 4.24 stay for comparisons (Renderer
// weights="eq4.25" / "eq4.24": ESTIMATOR_DEFAULT), and Eq. 4.25 for lobes with no exact table.
// `num` holds that mean, updated incrementally (West 1979), `den` the sum of the weights: no
// product w v L is ever formed, because f reaches ~1e27 for near-mirror lobes seen at grazing
// angles and cube-map radiance may be large, which together would overflow fp32.
// Start from LobeSum(vec3(0.0), 0.0).
const int ESTIMATE_ALBEDO = 0, ESTIMATE_EQ_4_25 = 1, ESTIMATE_EQ_4_24 = 2;
#if defined(WEIGHTS_EQ_4_24)
const int ESTIMATOR_DEFAULT = ESTIMATE_EQ_4_24;
#elif defined(WEIGHTS_EQ_4_25)
const int ESTIMATOR_DEFAULT = ESTIMATE_EQ_4_25;
#else
const int ESTIMATOR_DEFAULT = ESTIMATE_ALBEDO;
#endif

struct LobeSum {
    vec3 num;   // weighted mean of L (ESTIMATE_ALBEDO) or of L v (Eq. 4.24, 4.25) so far
    float den;  // sum of the weights w
};

// Add one pattern sample: L its (filtered) incident radiance, f = lobe_value, pdf = lobe_pdf, and
// cos_i the cosine of the sample direction on the lobe's side of the surface (wi.z for reflection,
// -wi.z for transmission); `estimator` one of ESTIMATE_*. Samples below that horizon (cos_i <= 0)
// or outside the lobe's support (f or pdf 0) are dropped, as the thesis drops samples below the
// horizon (ESTIMATE_ALBEDO: the mean of the kept ones, A holding the horizon's loss).
void add_pattern_sample(inout LobeSum s, vec3 L, float f, float pdf, float cos_i, int estimator) {
    if (!(f > 0.0 && pdf > 0.0 && cos_i > 0.0))
        return;
    float v = cos_i * (f / pdf);  // the importance weight of Eq. 4.4
    float w = estimator == ESTIMATE_EQ_4_25 ? f * cos_i : pdf * cos_i;  // Eq. 4.25; Eq. 4.24 and albedo
    if (!(w > 0.0) || isinf(w))
        return;                   // underflowed: it would add nothing, and 0/0 on a first sample
    vec3 x = estimator == ESTIMATE_ALBEDO ? L : L * v;
    s.den += w;
    s.num += (w / s.den) * (x - s.num);
}

// The weighted mean (times A for ESTIMATE_ALBEDO: the caller's), or 0 when no sample counted.
vec3 lobe_sum_result(LobeSum s) {
    return s.den > 0.0 ? s.num : vec3(0.0);
}
