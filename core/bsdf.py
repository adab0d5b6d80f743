"""Numpy reference of the section 3.3 material model and its importance sampling (4.4.2).

The BSDF (Eq. 3.6) is kd/pi plus Kurt et al.'s anisotropic Beckmann lobes
(Eq. 3.3-3.4) plus thin-surface transmission lobes (Eq. 3.5); the lobes are
importance-sampled through the half-way vector (Eq. 4.5-4.8) with the pdf of
Eq. 4.9. The GLSL shaders mirror these functions line by line (a test holds the
two equal), so everything here is plain and explicit: no clever rewrites that
the shader would not also do.

Conventions
- Directions are unit vectors in the local shading frame (t, b, n) = (x, y, z),
  arrays shaped (..., 3). wo points towards the viewer, wi towards the light,
  both away from the surface. Parameters (mx, my, r0, alpha) broadcast.
- The frame is oriented so the viewer is on the +n side: everything is zero
  for wo.z < 0 (a caller shading the back of a two-sided surface flips n).
  Reflection needs wi.z >= 0, transmission wi.z <= 0.
- "Above the horizon" includes z == 0 exactly, so a view exactly along the
  surface still gets finite values (the guards below keep them finite).

Numerical guards (docs/ARCHITECTURE.md, "Numerics"), each named once here:
- M_MIN: roughness is clamped to >= 1e-4 (mx = 0 would divide by zero in
  Eq. 3.3; below 1e-4 a lobe is a mirror at any screen resolution).
- HZ_MIN: cos(theta_h) is clamped inside D (Eq. 3.3). tan^2(theta_h) cos^2(phi_h)
  is written as hx^2 / hz^2 (no trig), so a horizontal h gives a huge finite
  exponent whose exp() underflows to 0, divided by a finite hz^4: 0, never
  inf * 0. The clamp never changes a representable D: D is already 0 in
  float64 (and float32) for any hz < 0.03 when m <= 1.
- DOT_MIN: wo.h in the denominators of Eq. 3.4 / 4.9 is floored. wo.h -> 0
  only when wi -> -wo; the products f cos(theta_i) and the weight f / p stay
  bounded there, only the bare f and p are capped.
- COS_MIN: the cosines in Kurt's shadowing/masking factor ((wi.n)(wo.n))^alpha
  (Eq. 3.4) are floored. For alpha > 0 that factor goes to 0 at grazing angles
  and the model is then not energy conserving (thesis 3.3); the floor keeps f
  finite and bounds a lobe's directional albedo by about 1 / COS_MIN^alpha.
  It has no effect when alpha = 0 (x^0 = 1). (As m -> 0 the albedo of Eq. 3.4
  tends to F cos(theta_o)^(1 - 2 alpha): alpha = 0.5 is the energy-neutral
  mirror, alpha > 0.5 gains energy towards grazing angles by design.)
- XI_MIN: -log(xi1) of Eq. 4.6 needs xi1 in (0, 1]; xi1 is clamped to
  [XI_MIN, 1], so xi1 = 0 (the first point of most QMC sets) gives a finite,
  steep but valid half vector.
- |wi + wo| = 0 (wi = -wo) has no half vector: lobes and pdf are 0 there.
- cos values passed to Schlick's Fresnel are clamped to [0, 1].
All constants are representable in float32 so the GLSL mirror uses the same ones.
"""
from __future__ import annotations

import numpy as np

from glint.core.constants import XI1_BORDER

M_MIN = 1e-4
HZ_MIN = 1e-7
DOT_MIN = 1e-12
COS_MIN = 1e-4
XI_MIN = 2.0**-126  # smallest normal float32: the GLSL uses the same clamp (a subnormal may flush to 0)
HALF_MIN = 1e-30  # |wi + wo| below this: no half vector

KINDS = ("reflect", "transmit")


# ----------------------------------------------------------------------------- helpers

def dot3(a, b):
    """Dot products of (..., 3) arrays along the last axis."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def mirror(w):
    """w reflected by the surface plane: (x, y, z) -> (x, y, -z) (the primes of Eq. 3.5)."""
    w = np.asarray(w, dtype=float)
    return w * np.array([1.0, 1.0, -1.0])


def half_vector(wi, wo):
    """h = (wi + wo) / |wi + wo| and a mask of where it exists (wi != -wo)."""
    s = np.asarray(wi, dtype=float) + np.asarray(wo, dtype=float)
    length = np.sqrt(dot3(s, s))
    ok = length > HALF_MIN
    h = s / np.maximum(length, HALF_MIN)[..., None]  # s = 0 gives h = 0 (masked by ok)
    return h, ok


def clamp_roughness(mx, my):
    """(mx, my) as arrays floored at M_MIN (see the module docstring)."""
    return np.maximum(np.asarray(mx, dtype=float), M_MIN), np.maximum(np.asarray(my, dtype=float), M_MIN)


def _check_kind(kind):
    if kind not in KINDS:
        raise ValueError(f"lobe kind must be one of {KINDS}, got {kind!r}")


# ----------------------------------------------------------------------------- Eq. 2.9, 3.3

def schlick_F(cos_theta, r0):
    """Schlick's Fresnel approximation F(u) = r0 + (1 - r0)(1 - u)^5 (Eq. 2.9)."""
    u = np.clip(np.asarray(cos_theta, dtype=float), 0.0, 1.0)  # rounding may push |u| past 1
    return r0 + (1.0 - r0) * (1.0 - u) ** 5


def beckmann_D(h, mx, my):
    """Anisotropic normalised Beckmann distribution (Eq. 3.3).

    D(h) = exp(-tan^2(th) (cos^2(ph)/mx^2 + sin^2(ph)/my^2)) / (pi mx my cos^4(th))
    with tan^2(th) cos^2(ph) = hx^2/hz^2 and tan^2(th) sin^2(ph) = hy^2/hz^2.
    Zero for h below or on the horizon (hz <= 0). h must be unit length.
    """
    h = np.asarray(h, dtype=float)
    mx, my = clamp_roughness(mx, my)
    hx, hy, hz = h[..., 0], h[..., 1], h[..., 2]
    c = np.maximum(hz, HZ_MIN)  # HZ_MIN: finite exponent, finite c^4 (see module doc)
    exponent = (hx * hx / (mx * mx) + hy * hy / (my * my)) / (c * c)
    D = np.exp(-exponent) / (np.pi * mx * my * c ** 4)  # exp underflows to 0 at grazing h
    return np.where(hz > 0.0, D, 0.0)


# ----------------------------------------------------------------------------- Eq. 3.4-3.6

def _shadowing(ci, co, alpha):
    """Kurt et al.'s shadowing/masking factor ((wi.n)(wo.n))^alpha of Eq. 3.4, floored (COS_MIN)."""
    return (np.maximum(ci, COS_MIN) * np.maximum(co, COS_MIN)) ** alpha


def _lobe(wi, wo, mx, my, r0, alpha, transmit):
    """Eq. 3.4 for wi, wo on the +n side; transmit=True swaps F for 1 - F (Eq. 3.5)."""
    wi = np.asarray(wi, dtype=float)
    wo = np.asarray(wo, dtype=float)
    h, ok = half_vector(wi, wo)
    ci, co = wi[..., 2], wo[..., 2]
    oh = dot3(wo, h)
    F = schlick_F(oh, r0)
    if transmit:
        F = 1.0 - F
    D = beckmann_D(h, mx, my)
    # Eq. 3.4: F(wo.h) D(h) / (4 (wo.h) ((wi.n)(wo.n))^alpha)
    f = F * D / (4.0 * np.maximum(oh, DOT_MIN) * _shadowing(ci, co, alpha))
    valid = ok & (ci >= 0.0) & (co >= 0.0) & (oh > 0.0)
    return np.where(valid, f, 0.0)


def reflect_lobe(wi, wo, mx, my, r0, alpha):
    """Specular reflection lobe f_r,lobe (Eq. 3.4), without k_s. Zero when wi or wo is below the horizon."""
    return _lobe(wi, wo, mx, my, r0, alpha, transmit=False)


def transmit_lobe(wi, wo, mx, my, r0, alpha):
    """Thin-surface transmission lobe f_t,lobe (Eq. 3.5), without k_t.

    wi lies on the other side (wi.z <= 0 for wo.z >= 0). By the symmetry of
    Fig. 3.6 it is the reflection lobe evaluated with wi' = wi mirrored by the
    surface plane, with the complementary Fresnel term 1 - F(wo.h').
    Peaks at wi = -wo (light passing straight through).
    """
    return _lobe(mirror(wi), wo, mx, my, r0, alpha, transmit=True)


def lobe_value(wi, wo, mx, my, r0, alpha, kind):
    """reflect_lobe or transmit_lobe by kind."""
    _check_kind(kind)
    fn = reflect_lobe if kind == "reflect" else transmit_lobe
    return fn(wi, wo, mx, my, r0, alpha)


def bsdf(wi, wo, kd, lobes):
    """The full BSDF f_s(wi, wo) of Eq. 3.6 as (..., 3) RGB.

    kd/pi (wi and wo on the same, +n, side) + sum_n ks_n f_r,lobe_n
    + sum_m kt_m f_t,lobe_m, with `lobes` a list of glint.core.scene.Lobe (ks is RGB).
    """
    wi = np.asarray(wi, dtype=float)
    wo = np.asarray(wo, dtype=float)
    same_side = (wi[..., 2] >= 0.0) & (wo[..., 2] >= 0.0)
    kd = np.asarray(kd, dtype=float)
    out = np.where(same_side[..., None], kd / np.pi, 0.0)
    out = np.broadcast_to(out, np.broadcast_shapes(out.shape, same_side.shape + (3,))).copy()
    for lobe in lobes:
        f = lobe_value(wi, wo, lobe.mx, lobe.my, lobe.r0, lobe.alpha, lobe.kind)
        out += np.asarray(lobe.ks, dtype=float) * f[..., None]
    return out


# ----------------------------------------------------------------------------- Eq. 4.5-4.9

def sample_half_vector(xi1, xi2, mx, my):
    """Half-way vector from uniform numbers (Eq. 4.5-4.7), shape (..., 3).

    phi_h = arctan(my/mx tan(2 pi xi2)) (Eq. 4.5) loses the quadrant; written as
    atan2(my sin(2 pi xi2), mx cos(2 pi xi2)) it keeps it, so phi_h runs over
    [0, 2 pi) monotonically with xi2 (and phi_h = 2 pi xi2 when mx = my).
    """
    mx, my = clamp_roughness(mx, my)
    xi1 = np.clip(np.asarray(xi1, dtype=float), XI_MIN, 1.0)  # -log(xi1) needs xi1 in (0, 1]
    xi2 = np.asarray(xi2, dtype=float)
    a = 2.0 * np.pi * xi2
    phi = np.arctan2(my * np.sin(a), mx * np.cos(a))  # Eq. 4.5, quadrant-correct
    phi = np.where(phi < 0.0, phi + 2.0 * np.pi, phi)
    cp, sp = np.cos(phi), np.sin(phi)
    # Eq. 4.6: theta_h = arctan(sqrt(-log(xi1) / (cos^2 phi/mx^2 + sin^2 phi/my^2)))
    A = cp * cp / (mx * mx) + sp * sp / (my * my)  # >= 1/max(mx,my)^2 > 0
    theta = np.arctan(np.sqrt(np.maximum(-np.log(xi1), 0.0) / A))  # < pi/2: cos(theta) > 0
    st, ct = np.sin(theta), np.cos(theta)
    return np.stack(np.broadcast_arrays(st * cp, st * sp, ct), axis=-1)  # Eq. 4.7


def sample_lobe(wo, xi1, xi2, mx, my, kind):
    """Sampled incident direction wi = 2 (wo.h) h - wo (Eq. 4.8), shape (..., 3).

    For kind "transmit" the reflected sample is mirrored through the surface
    plane. Samples whose h faces away from wo (wo.h <= 0) or that end on the
    wrong side of the surface are returned as they are; their pdf (lobe_pdf)
    and weight (sample_weight) are 0, so an estimator simply drops them.
    """
    _check_kind(kind)
    wo = np.asarray(wo, dtype=float)
    h = sample_half_vector(xi1, xi2, mx, my)
    wi = 2.0 * dot3(wo, h)[..., None] * h - wo  # Eq. 4.8
    return mirror(wi) if kind == "transmit" else wi


def lobe_pdf(wi, wo, mx, my, kind):
    """Solid-angle pdf of sample_lobe producing wi (Eq. 4.9).

    p = exp(-tan^2(th)(cos^2(ph)/mx^2 + sin^2(ph)/my^2)) / (4 pi mx my cos^3(th) (wo.h))
      = D(h) cos(th) / (4 (wo.h)),  h = half vector of wi (mirrored for "transmit") and wo.
    Over the whole sphere it integrates to the mass of half vectors with wo.h > 0
    (<= 1); samples that land below the horizon still count in it.
    """
    _check_kind(kind)
    wi = np.asarray(wi, dtype=float)
    wo = np.asarray(wo, dtype=float)
    if kind == "transmit":
        wi = mirror(wi)
    h, ok = half_vector(wi, wo)
    oh = dot3(wo, h)
    p = beckmann_D(h, mx, my) * h[..., 2] / (4.0 * np.maximum(oh, DOT_MIN))
    return np.where(ok & (oh > 0.0) & (h[..., 2] > 0.0), p, 0.0)


def sample_weight(wi, wo, r0, alpha, kind):
    """Importance-sampling weight f_lobe |cos(theta_i)| / p of a sample from sample_lobe (Eq. 4.4).

    Eq. 3.4 divided by Eq. 4.9: D and 4 (wo.h) cancel, leaving
    F(wo.h) |wi.n| / (cos(theta_h) ((wi'.n)(wo.n))^alpha)
    (1 - F for transmission), so near-mirror lobes (D ~ 1e7) never form D/D.
    Zero where the sample is invalid (wo.h <= 0, wrong side, wi = -wo).
    Independent of mx, my: the roughness only enters through where wi lies.
    """
    _check_kind(kind)
    wi = np.asarray(wi, dtype=float)
    wo = np.asarray(wo, dtype=float)
    wr = mirror(wi) if kind == "transmit" else wi  # the lobe is always evaluated on the +n side
    h, ok = half_vector(wr, wo)
    ci, co, hz = wr[..., 2], wo[..., 2], h[..., 2]
    oh = dot3(wo, h)
    F = schlick_F(oh, r0)
    if kind == "transmit":
        F = 1.0 - F
    w = F * ci / (np.maximum(hz, HZ_MIN) * _shadowing(ci, co, alpha))
    valid = ok & (ci >= 0.0) & (co >= 0.0) & (oh > 0.0) & (hz > 0.0)
    return np.where(valid, w, 0.0)


# ----------------------------------------------------------------------------- directional albedo

ALBEDO_N = 1 << 14
ALBEDO_CHUNK = 4096


def qmc_points(n):
    """A fixed 2-D point set in (0, 1)^2: Hammersley with midpoints, ((i + 1/2)/n, radical_inverse_2(i)).

    Deterministic, and xi1 never 0 (so Eq. 4.6 never needs its guard here).
    """
    i = np.arange(n, dtype=np.uint64)
    # base-2 radical inverse: reverse the bits of i (32 bits)
    r = i.copy()
    r = ((r & 0x55555555) << 1) | ((r & 0xAAAAAAAA) >> 1)
    r = ((r & 0x33333333) << 2) | ((r & 0xCCCCCCCC) >> 2)
    r = ((r & 0x0F0F0F0F) << 4) | ((r & 0xF0F0F0F0) >> 4)
    r = ((r & 0x00FF00FF) << 8) | ((r & 0xFF00FF00) >> 8)
    r = ((r & 0x0000FFFF) << 16) | ((r & 0xFFFF0000) >> 16)
    xi2 = r.astype(float) / 2.0 ** 32
    xi1 = (np.arange(n) + 0.5) / n
    return xi1, xi2


def lobe_albedo(wo, mx, my, r0, alpha, kind, n=ALBEDO_N):
    """Directional albedo of one lobe: int f_lobe(wi, wo) |cos(theta_i)| dwi, shape wo.shape[:-1] (+ params).

    Importance-sampled (Eq. 4.4-4.9) with the fixed point set of `qmc_points`,
    so it is deterministic. Without k_s. The white-furnace test uses it.
    """
    _check_kind(kind)
    wo = np.asarray(wo, dtype=float)
    xi1, xi2 = qmc_points(n)
    shape = np.broadcast_shapes(wo.shape[:-1], np.shape(mx), np.shape(my), np.shape(r0), np.shape(alpha))
    wo = np.broadcast_to(wo, shape + (3,))[..., None, :]  # (..., 1, 3) against n points
    mx, my, r0, alpha = (np.broadcast_to(np.asarray(v, dtype=float), shape)[..., None]
                         for v in (mx, my, r0, alpha))
    total = np.zeros(shape)
    for start in range(0, n, ALBEDO_CHUNK):  # chunks bound the memory of (..., n) intermediates
        x1, x2 = xi1[start:start + ALBEDO_CHUNK], xi2[start:start + ALBEDO_CHUNK]
        wi = sample_lobe(wo, x1, x2, mx, my, kind)
        total += sample_weight(wi, wo, r0, alpha, kind).sum(axis=-1)
    return total / n


def theta_thresh(phi_h, mx, my):
    """The lobe border's half-vector angle in the direction phi_h (Eq. 4.10):
    theta_thresh = arctan(sqrt(-log(xi1_border) / (cos^2 phi_h / mx^2 + sin^2 phi_h / my^2))),
    roughness floored at M_MIN. At phi_h = 0 with mx = my = m: arctan(sqrt(-log xi1_border) m)."""
    mx, my = clamp_roughness(mx, my)
    phi_h = np.asarray(phi_h, dtype=float)
    return np.arctan(np.sqrt(-np.log(XI1_BORDER) / (np.cos(phi_h) ** 2 / mx ** 2 + np.sin(phi_h) ** 2 / my ** 2)))
