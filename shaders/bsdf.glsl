// The section 3.3 material model on the GPU: Kurt et al.'s anisotropic Beckmann lobes (Eq. 3.3-3.4),
// the thin-surface transmission lobe (Eq. 3.5) and their importance sampling (Eq. 4.5-4.9).
// This is the GLSL mirror of core/bsdf.py, the numpy reference: same formulas, same guards, same
// constants (tests/test_bsdf_glsl.py holds the two equal). Read core/bsdf.py's docstring for why
// each guard is where it is; the comments here only say where the GLSL differs.
//
// Conventions (as core/bsdf.py): directions are in the local shading frame (t, b, n) = (x, y, z);
// wo points to the viewer, wi to the light, both away from the surface; wo.z >= 0. Values are
// scalars without ks (the caller multiplies by lobe.ks.rgb). Reflection needs wi.z >= 0,
// transmission wi.z <= 0; everything else is 0.

#include "common.glsl"
#include "materials.glsl"

// The guards of core/bsdf.py (M_MIN, HZ_MIN, DOT_MIN, COS_MIN, HALF_MIN, XI_MIN) are defines
// injected from there (viewer/shader_source.py glsl_constants): one source for both.

bool lobe_is_transmit(Lobe lobe) {
    return int(lobe.ks.a + 0.5) == LOBE_TRANSMIT;
}

// w reflected by the surface plane: the primes of Eq. 3.5.
vec3 mirror_z(vec3 w) {
    return vec3(w.xy, -w.z);
}

// h = (wi + wo) / |wi + wo|; false where there is none (wi = -wo). The sum is scaled by its largest
// component before normalising, so a tiny |wi + wo| neither underflows nor divides by zero.
bool half_vector(vec3 wi, vec3 wo, out vec3 h) {
    vec3 s = wi + wo;
    float m = max(max(abs(s.x), abs(s.y)), abs(s.z));
    h = vec3(0.0);
    if (!(m > HALF_MIN))
        return false;
    h = normalize(s / m);
    return true;
}

// Schlick's Fresnel approximation (Eq. 2.9): F(u) = r0 + (1 - r0)(1 - u)^5.
float schlick_F(float cos_theta, float r0) {
    float c = 1.0 - clamp(cos_theta, 0.0, 1.0);
    float c2 = c * c;
    return r0 + (1.0 - r0) * (c2 * c2 * c);
}

// Anisotropic normalised Beckmann distribution (Eq. 3.3):
//   D(h) = exp(-tan^2(th) (cos^2(ph)/mx^2 + sin^2(ph)/my^2)) / (pi mx my cos^4(th)),
// with tan^2(th) cos^2(ph) = hx^2/hz^2 and tan^2(th) sin^2(ph) = hy^2/hz^2 (no trigonometry).
// 0 for h on or below the horizon. h must be unit length.
float beckmann_D(vec3 h, float mx, float my) {
    if (!(h.z > 0.0))
        return 0.0;
    mx = max(mx, M_MIN);
    my = max(my, M_MIN);
    float c = max(h.z, HZ_MIN);
    float exponent = (h.x * h.x / (mx * mx) + h.y * h.y / (my * my)) / (c * c);
    float c2 = c * c;
    return exp(-exponent) / (PI * mx * my * c2 * c2);  // exp underflows to 0 at grazing h
}

// Kurt et al.'s shadowing/masking factor ((wi.n)(wo.n))^alpha of Eq. 3.4, floored (COS_MIN).
float kurt_shadowing(float ci, float co, float alpha) {
    return pow(max(ci, COS_MIN) * max(co, COS_MIN), alpha);  // base >= 1e-8 > 0: pow is defined
}

// The transmitted share 1 - F of Eq. 3.5, by 1 - c^5 = (1 - c)(1 + c + c^2 + c^3 + c^4), c = 1 - u:
// the same value as 1 - schlick_F, without the cancellation of 1 - F when F ~ 1 (grazing light
// through glass), where forming 1 - F in float32 loses up to all of its digits.
float schlick_transmitted(float cos_theta, float r0) {
    float u = clamp(cos_theta, 0.0, 1.0);
    float c = 1.0 - u;
    return (1.0 - r0) * u * (1.0 + c * (1.0 + c * (1.0 + c * (1.0 + c))));
}

// f_r,lobe (Eq. 3.4) or f_t,lobe (Eq. 3.5), without ks:
//   F(wo.h) D(h) / (4 (wo.h) ((wi.n)(wo.n))^alpha), and for transmission the same with wi' (wi
//   mirrored by the surface plane) and 1 - F: by the symmetry of Fig. 3.6 it is a reflection lobe.
float lobe_value(vec3 wi, vec3 wo, Lobe lobe) {
    bool transmit = lobe_is_transmit(lobe);
    vec3 wr = transmit ? mirror_z(wi) : wi;
    vec3 h;
    bool ok = half_vector(wr, wo, h);
    float ci = wr.z, co = wo.z, oh = dot(wo, h);
    if (!(ok && ci >= 0.0 && co >= 0.0 && oh > 0.0))
        return 0.0;
    float F = transmit ? schlick_transmitted(oh, lobe.shape.z) : schlick_F(oh, lobe.shape.z);
    float D = beckmann_D(h, lobe.shape.x, lobe.shape.y);
    return F * D / (4.0 * max(oh, DOT_MIN) * kurt_shadowing(ci, co, lobe.shape.w));
}

// The bracket of Eq. 4.6 and 4.10: cos^2(phi_h)/mx^2 + sin^2(phi_h)/my^2, for cs = (cos, sin)(phi_h).
float lobe_phi_factor(vec2 cs, float mx, float my) {
    return cs.x * cs.x / (mx * mx) + cs.y * cs.y / (my * my);
}

// (cos, sin)(phi_h) of Eq. 4.5 / 4.12, phi_h = arctan(my/mx tan(2 pi xi2)). Written as
// atan2(my sin(2 pi xi2), mx cos(2 pi xi2)) it keeps the quadrant (as core/bsdf.py); its cosine and
// sine are then just that vector normalised, which skips an atan/cos/sin round trip.
vec2 lobe_phi(float xi2, float mx, float my) {
    float a = 2.0 * PI * xi2;
    return normalize(vec2(mx * cos(a), my * sin(a)));  // mx, my >= M_MIN: never the zero vector
}

// Eq. 4.7: h = (sin th cos ph, sin th sin ph, cos th).
vec3 half_vector_at(vec2 cs_phi, float theta) {
    return vec3(sin(theta) * cs_phi, cos(theta));
}

// Eq. 4.8: the direction h mirrors wo into, wi = 2 (wo.h) h - wo; for a transmission lobe that
// reflected direction is mirrored through the surface plane (section 3.3.1).
vec3 scatter_about(vec3 wo, vec3 h, Lobe lobe) {
    vec3 wi = 2.0 * dot(wo, h) * h - wo;
    return lobe_is_transmit(lobe) ? mirror_z(wi) : wi;
}

// Importance-sampled incident direction from uniform xi in [0, 1]^2 (Eq. 4.5-4.8):
//   phi_h (Eq. 4.5), theta_h = arctan(sqrt(-log(xi1) / (cos^2 ph/mx^2 + sin^2 ph/my^2))) (Eq. 4.6).
// Samples whose h faces away from wo, or that land on the wrong side, are returned as they are:
// lobe_pdf and lobe_value are 0 there, so estimators drop them.
vec3 sample_lobe(vec3 wo, vec2 xi, Lobe lobe) {
    float mx = max(lobe.shape.x, M_MIN), my = max(lobe.shape.y, M_MIN);
    float xi1 = clamp(xi.x, XI_MIN, 1.0);  // -log(xi1) needs xi1 in (0, 1]
    vec2 cs = lobe_phi(xi.y, mx, my);
    float theta = atan(sqrt(max(-log(xi1), 0.0) / lobe_phi_factor(cs, mx, my)));  // Eq. 4.6, < pi/2
    return scatter_about(wo, half_vector_at(cs, theta), lobe);
}

// Solid-angle pdf of sample_lobe producing wi (Eq. 4.9):
//   p = exp(-tan^2(th)(cos^2 ph/mx^2 + sin^2 ph/my^2)) / (4 pi mx my cos^3(th) (wo.h)) = D(h) cos(th) / (4 wo.h),
// h the half vector of wo and wi (mirrored wi' for a transmission lobe).
float lobe_pdf(vec3 wi, vec3 wo, Lobe lobe) {
    vec3 wr = lobe_is_transmit(lobe) ? mirror_z(wi) : wi;
    vec3 h;
    bool ok = half_vector(wr, wo, h);
    float oh = dot(wo, h);
    if (!(ok && oh > 0.0 && h.z > 0.0))
        return 0.0;
    return beckmann_D(h, lobe.shape.x, lobe.shape.y) * h.z / (4.0 * max(oh, DOT_MIN));
}
