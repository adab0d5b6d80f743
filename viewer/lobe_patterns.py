"""Regular lobe sampling patterns (thesis section 4.4.3) and the numpy reference of shaders/lobe_sampling.glsl.

The walkthrough estimate of a lobe takes n samples at fixed positions (xi1, xi2) of a
pattern, made here (`pattern_xi`) and uploaded once; the shader maps them into each
pixel's lobe by Eq. 4.12-4.13 (`pattern_direction`), filters each look-up at the MIP level
of Eq. 4.16-4.17 for the footprint of `pattern_footprint_area` (the lobe's second moment;
the thesis' A / n of Eq. 4.14-4.15 for transmission lobes), and weights them: their p cos-weighted mean
of the radiance times the lobe's albedo (the default, viewer/lobe_albedo.py), or Eq. 4.25 (4.24). Every function of
lobe_sampling.glsl has its float64 numpy twin below, written from the thesis, with the
BSDF itself from core/bsdf.py; tests/test_lobe_patterns.py holds the two equal.

Which pattern, how many samples
-------------------------------
The thesis leaves both to the user; the rules here were measured in a numpy model of the
filtered look-ups (bench/measure_lobe_patterns.py: environments of spherical Gaussians, each
look-up filtered over its share A / n of the lobe, the relative error of Eq. 4.25 against the
lobe's integral over 280 cases of environment x view). Set-up and tables: docs/BENCHMARKS.md,
"Lobe patterns: how the rules were measured".

Rule (`samples_for_lobe`): the smallest n that keeps the 75th percentile of the error within
1% and the 90th within 2.5%, each switch to more samples placed at the last measured
roughness where the smaller n still does; where no n gets there, the ring keeps 7 (its error
grows again past 7-9: more samples on the one ring at xi1 = 0.6 move the weight off the
centre) and the line grows to 19 (its error keeps falling, slowly: samples spaced along the
one axis keep covering it better). By the larger roughness max(m_x, m_y):

    ring:  < 0.01: 1,  < 0.02: 3,  < 0.05: 5,  else 7
    line:  < 0.01: 1,  < 0.03: 3,  < 0.05: 7,  < 0.1: 11,  < 0.15: 15,  else 19

1 sample (m < MIRROR_M = 0.01, a lobe a few cube-map texels wide) is the mirror direction
with the Fresnel weight: it already meets the criterion there. Wide lobes (m >= 0.1) keep
errors of 10-50% whatever n; those are the bias of the patterns and of Eq. 4.25 (even under
constant radiance the 7-sample ring is off for wide lobes), which grows at grazing views; the
still camera's QMC converges to the reference regardless.

Threshold (`choose_pattern`, LINE_RATIO = 3): ring and line compared at the same n over
anisotropy ratios m_y / m_x. The line wins from a ratio of 2-3 for glossy lobes; for narrow
ones (m_max = 0.03) the ring is better up to ~4, with small errors either way. 3 is the
compromise.

Footprint: how wide each look-up filters
----------------------------------------
The thesis filters each of n samples by a box of the area A / n, A the lobe's 99 % ellipse
(Eq. 4.14-4.17). For n = 1 that box is as wide as the lobe's support: with the border at
D = 1 % of its peak, the border radius is sqrt(-2 log 0.01) = 3.03 standard deviations, and a
trilinear look-up of a box-filtered level of texel area a filters with variance a / 4 per axis
(box * tent), so the look-up's variance is 7.2 times the lobe's: near-mirror lobes look blurred.
`pattern_footprint_area` takes the lobe's second moment instead: per axis of the ellipse the
lobe's variance less the D-weighted variance of the pattern's own positions (what the pattern
already spreads), at least 1 / n of it, as a box of 4 sqrt(k_t k_b) u v. (The ellipse's
variance s^2 u^2 matches the lobe's f cos-weighted variance of incident directions within 10 %
for m = 0.03 and 0.1 at views of 0-70 degrees, by importance sampling.) So the effective MIP
level is about 1.4, 1.0, 0.6 and 0.1 levels finer than the thesis' at n = 1, 3, 7, 19 for the
ring: the offset depends on n, which is why one constant MIP offset could not fix it.

Against the converged still camera (`glint bench`, PSNR per material: docs/BENCHMARKS.md,
"Lobe patterns: how the rules were measured") the second moment gains on every reflection
lobe at every n; scaling its area by 0.5, 2 or 4 lost, and the isotropic MIP filter of an
anisotropic footprint works best as the geometric mean of the axes' variances (better than
their arithmetic mean or their maximum). The frosted glass' transmission lobe is the
exception: at grazing views 1 - F moves its mass off the straight-through centre, so its
second moment about the centre underestimates the spread, and the box of A / n measured
better at every n. Transmission lobes keep the thesis' footprint (`Renderer(footprint="thesis")`
gives it to every lobe; `glint bench` method patterns-thesis). The same footprint, times the
projection's texels per steradian, sets the MIP level of a planar reflector's samples in its
mirror buffer (shaders/specular.glsl).

Planar reflectors: the multi-ring pattern (section 4.5.3)
---------------------------------------------------------
A planar reflector's samples are looked up in the mirror buffer (viewer/passes/mirror.py),
where, unlike in a cube map, a lobe may straddle a depth or object edge; there the pattern's
response to the edge is what shows (the thesis' Fig. 4.33: the single ring behaves like a box
filter, rings of several radii like a tent). `pattern_xi("multi_ring", n)`: the centre, then
the n - 1 others on MULTI_RING_RADII rings -- one ring for n <= 4, two for n >= 5 -- at
theta_h = 0.4 and 0.8 of theta_thresh (xi1 = 0.6, the curved ring's radius, and 0.2; at the
outer ring D has fallen to 100^(-0.64) ~ 5% of its centre value, Eq. 4.10 and 4.13), the
inner ring taking the odd sample, the outer ring turned by half its sample spacing so no two
samples line up radially. `choose_pattern(..., planar=True)` gives it to isotropic lobes;
anisotropic ones keep the line patterns, whose samples are already evenly spaced and fade
towards the ends (the thesis says the same). `samples_for_lobe(..., planar=True)`: 1, 3, 5
as for the ring, 10 (centre + 5 + 4) from m = 0.05 on, and 25 (centre + 12 + 12) from m = 0.2 on:
a wide lobe's ten samples each filter a tenth of its cap (shaders/specular.glsl `planar_sample_sr`),
and the mirror buffer's box-filtered levels that wide read its bright parts (a room's lamp) into
the darker directions around them. The rough metal floor's widest fitted lobe (m 0.33) alone read
1.35 times Mitsuba's rendering of the same lobe with 10 samples, 1.24 with 13, 1.09 with 19, 1.02
with 25 and 1.00 with 31 (unfiltered look-ups: 0.87, the pattern's own bias); its m 0.13 lobe reads
0.97 with 10 (docs/BENCHMARKS.md, "Issue 24: three lobes fitted to Eq. 3.7").

Why these radii and counts (bench/measure_multi_ring.py, the step response of the estimate
across a straight edge in the reflected scene; table: docs/BENCHMARKS.md, "Lobe patterns:
how the rules were measured"): two rings reaching out to 0.8 beat the single ring from
n = 10 on, and at n = 5; three rings (the thesis' 3 x 3 of Fig. 4.34) put too much of the
filtered footprint near the centre and lose to both. The single ring stays a little better
at n = 7, hence 10 samples for glossy planar lobes, the thesis' own count for its planar
figures.
"""
from __future__ import annotations

import numpy as np

from glint.core import bsdf
from glint.core.constants import LOBE_TAN_MAX, XI1_BORDER

RING_RADIUS = 0.6      # xi1 of the ring: "radius = 0.6 (= 40% off-center)"
LOBE_AXIS_VARIANCE = -0.5 / np.log(XI1_BORDER)  # the lobe's variance per axis, border radius 1

# The rules of choose_pattern and samples_for_lobe (measured: see the module doc).
LINE_RATIO = 3.0       # anisotropy m_max / m_min from which the line patterns replace the ring
MIRROR_M = 0.01        # below this roughness a lobe is sampled once, at its centre
# (width limit, samples): the first row whose limit exceeds max(m_x, m_y)
RING_SAMPLES = ((MIRROR_M, 1), (0.02, 3), (0.05, 5), (np.inf, 7))
LINE_SAMPLES = ((MIRROR_M, 1), (0.03, 3), (0.05, 7), (0.1, 11), (0.15, 15), (np.inf, 19))

# Planar reflectors (module doc): theta_h / theta_thresh of the multi-ring pattern's rings.
MULTI_RING_RADII = (0.4, 0.8)
MULTI_RING_SAMPLES = ((MIRROR_M, 1), (0.02, 3), (0.05, 5), (0.2, 10), (np.inf, 25))  # 25: module doc

KINDS = ("ring", "line_x", "line_y", "multi_ring")
LINE_XI2 = {"line_x": (0.0, 0.5), "line_y": (0.25, 0.75)}  # the two sides of the line: phi_h and phi_h + 180 deg


# ----------------------------------------------------------------------------- patterns in (xi1, xi2)

def pattern_xi(kind: str, n: int) -> np.ndarray:
    """The n sample positions (xi1, xi2) of a pattern, (n, 2) float32, as section 4.4.3 lists them.

    "ring" (isotropic lobes): one sample at the lobe centre (1, 0), the others
    on the ring xi1 = 0.6 at xi2 = (k - 1)/(n - 1), k = 1 .. n-1.
    "line_x" (m_x >> m_y) and "line_y" (m_x << m_y): samples equally spaced
    along the lobe's long axis; k = 0 .. floor(n/2) at xi1 = (2k + 1)/n on the
    first side (xi2 = 0, resp. 0.25), the rest at xi1 = 2 - (2k + 1)/n on the
    other (xi2 = 0.5, resp. 0.75). A first-side xi1 >= 1 (the centre for odd
    n, 1 + 1/n for even n) means theta_h = (1 - xi1) theta_thresh <= 0 in
    Eq. 4.13, which is the direction at 2 - xi1 on the other side; it is
    written that way, keeping xi1 in (0, 1] (for n = 5 this gives the thesis'
    own example, (1/5, .25), (3/5, .25), (5/5, .75), (3/5, .75), (1/5, .75)).
    "multi_ring" (isotropic lobes of planar reflectors, section 4.5.3; module doc): the
    centre, then one ring at xi1 = 1 - MULTI_RING_RADII[0] for n <= 4, else two rings at
    xi1 = 1 - MULTI_RING_RADII[j], the inner taking ceil((n - 1) / 2) samples at
    xi2 = k / count, the outer the rest, turned by half its spacing: xi2 = (k + 1/2) / count.
    """
    n = int(n)
    if n < 1:
        raise ValueError(f"a pattern needs at least one sample, got n = {n}")
    if kind == "ring":
        xi = [(1.0, 0.0)] + [(RING_RADIUS, (k - 1) / (n - 1)) for k in range(1, n)]
    elif kind in LINE_XI2:
        first, other = LINE_XI2[kind]
        xi = []
        for k in range(n):
            x1, x2 = ((2 * k + 1) / n, first) if k <= n // 2 else (2 - (2 * k + 1) / n, other)
            xi.append((2 - x1, other) if x1 >= 1.0 else (x1, x2))
    elif kind == "multi_ring":
        xi = [(1.0, 0.0)]
        rest = n - 1
        rings = 1 if rest < 4 else len(MULTI_RING_RADII)
        for j in range(rings if rest else 0):
            count = rest // rings + (1 if j < rest % rings else 0)
            radius = MULTI_RING_RADII[j]  # one ring: the inner one, the curved ring's radius
            turn = 0.5 * j / count  # the outer ring sits between the inner ring's samples
            xi += [(1.0 - radius, (k / count + turn) % 1.0) for k in range(count)]
    else:
        raise ValueError(f"pattern kind must be one of {KINDS}, got {kind!r}")
    return np.array(xi, dtype=np.float32).reshape(n, 2)


def choose_pattern(mx: float, my: float, planar: bool = False) -> str:
    """"ring" unless the lobe is LINE_RATIO times longer one way than the other (see the module doc).

    "line_y" when m_y / m_x >= LINE_RATIO (m_x << m_y: the highlight is long along b),
    "line_x" when m_x / m_y >= LINE_RATIO. Roughness is clamped to M_MIN as in the BSDF.
    planar: for a planar reflector's mirror buffer (section 4.5.3), where isotropic lobes
    get "multi_ring" instead of "ring".
    """
    mx, my = (max(float(m), bsdf.M_MIN) for m in (mx, my))
    if my >= LINE_RATIO * mx:
        return "line_y"
    if mx >= LINE_RATIO * my:
        return "line_x"
    return "multi_ring" if planar else "ring"


def samples_for_lobe(mx: float, my: float, planar: bool = False) -> int:
    """The automatic sample count of a lobe: from its width, max(m_x, m_y), and its pattern (module doc).

    1 for near-mirror lobes (m < MIRROR_M): the centre sample alone, i.e. the mirror (or
    straight-through) direction with the Fresnel weight, since the normalised estimators
    reduce to L cos(theta_i) f / p = L F cos(theta_i) / (cos(theta_h) ((wi.n)(wo.n))^alpha).
    planar: the count for a planar reflector's pattern (`choose_pattern(..., planar=True)`).
    """
    kind = choose_pattern(mx, my, planar)
    width = max(float(mx), float(my), bsdf.M_MIN)
    table = {"ring": RING_SAMPLES, "multi_ring": MULTI_RING_SAMPLES}.get(kind, LINE_SAMPLES)
    for limit, n in table:
        if width < limit:
            return n
    raise AssertionError("the sample tables end at infinity")


# ----------------------------------------------------------------------------- Eq. 4.10-4.13

def pattern_phi(xi2, mx, my):
    """phi_h = arctan(my/mx tan(2 pi xi2)) (Eq. 4.12), quadrant-correct as glint.core.bsdf.sample_half_vector."""
    mx, my = bsdf.clamp_roughness(mx, my)
    a = 2.0 * np.pi * np.asarray(xi2, dtype=float)
    return np.arctan2(my * np.sin(a), mx * np.cos(a))


def pattern_direction(wo, xi1, xi2, mx, my, kind):
    """The pattern sample (xi1, xi2) as an incident direction, shape (..., 3).

    phi_h by Eq. 4.12, theta_h = (1 - xi1) theta_thresh (Eq. 4.13), h by Eq. 4.7,
    wi = 2 (wo.h) h - wo (Eq. 4.8), mirrored through the surface plane for kind "transmit".
    """
    bsdf._check_kind(kind)
    wo = np.asarray(wo, dtype=float)
    phi = pattern_phi(xi2, mx, my)
    theta = (1.0 - np.asarray(xi1, dtype=float)) * bsdf.theta_thresh(phi, mx, my)
    h = np.stack(np.broadcast_arrays(np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)), -1)
    wi = 2.0 * np.sum(wo * h, axis=-1, keepdims=True) * h - wo
    return bsdf.mirror(wi) if kind == "transmit" else wi


# ----------------------------------------------------------------------------- Eq. 4.14-4.17, filtered importance sampling

def lobe_ellipse_axes(wo, mx, my, kind):
    """(u, v), shape (..., 2): the half-axes of the lobe's cross-section at unit distance (Eq. 4.14-4.15).

    alpha_U, alpha_V = acos(omega_C . omega_U), acos(omega_C . omega_V), with omega_C the
    lobe centre (xi1 = 1) and omega_U, omega_V its border (xi1 = 0) at phi_h = 0 and 90
    degrees; u, v = tan(alpha_U), tan(alpha_V), each capped at LOBE_TAN_MAX (also for
    alpha >= 90 degrees).
    """
    c = pattern_direction(wo, 1.0, 0.0, mx, my, kind)
    axes = []
    for xi2 in (0.0, 0.25):
        w = pattern_direction(wo, 0.0, xi2, mx, my, kind)
        cos_a = np.sum(c * w, axis=-1) / (np.linalg.norm(c, axis=-1) * np.linalg.norm(w, axis=-1))
        alpha = np.arccos(np.clip(cos_a, -1.0, 1.0))  # Eq. 4.14
        axes.append(np.tan(np.minimum(alpha, np.arctan(LOBE_TAN_MAX))))  # Eq. 4.15
    return np.stack(axes, axis=-1)


def lobe_ellipse_area(wo, mx, my, kind):
    """A = pi u v, the lobe's cross-section at unit distance (Eq. 4.14-4.15)."""
    uv = lobe_ellipse_axes(wo, mx, my, kind)
    return np.pi * uv[..., 0] * uv[..., 1]


def lobe_cap_solid_angle(wo, mx, my, kind):
    """The solid angle of the lobe's cap (shaders/lobe_sampling.glsl): `lobe_ellipse_area` with its
    half-axes as chords |c - w| = 2 sin(alpha / 2) of the unit sphere instead of tan(alpha)
    (Lambert's equal-area projection; exact for a round cap, 2 pi (1 - cos alpha)). At most 4 pi,
    where Eq. 4.15's area grows without bound past 45 degrees. The mirror buffers' samples filter
    at most their share of it (shaders/specular.glsl planar_sample_sr)."""
    def unit(v, fallback):  # the shader's safe_normalize
        n = np.linalg.norm(v, axis=-1, keepdims=True)
        return np.where(n > 1e-15, v / np.where(n > 1e-15, n, 1.0), fallback)
    c = unit(pattern_direction(wo, 1.0, 0.0, mx, my, kind), 0.0)  # no view: no cap
    u = unit(pattern_direction(wo, 0.0, 0.0, mx, my, kind), c)
    v = unit(pattern_direction(wo, 0.0, 0.25, mx, my, kind), c)
    return np.pi * np.linalg.norm(c - u, axis=-1) * np.linalg.norm(c - v, axis=-1)


def pattern_footprint_area(xi, uv):
    """The area at unit distance that each sample of the pattern xi (n, 2) filters, from the lobe's
    second moment (module doc, "Footprint"; shaders/lobe_sampling.glsl pattern_footprint_area).

    Per axis of the lobe's ellipse (half-axes uv, (..., 2)), in units of the border radius:
    the lobe's variance s^2 = 1 / (-2 log XI1_BORDER) less the D-weighted variance of the
    pattern's positions (1 - xi1) (cos, sin)(2 pi xi2), at least s^2 / n; a bilinear look-up of a
    2 x 2 box-filtered MIP level of texel area a filters with variance a / 4 per axis, so the
    area is 4 sqrt(k_t k_b) u v.
    """
    xi = np.asarray(xi, dtype=float)
    r = 1.0 - xi[:, 0]
    p = r[:, None] * np.stack([np.cos(2 * np.pi * xi[:, 1]), np.sin(2 * np.pi * xi[:, 1])], -1)
    w = XI1_BORDER ** (r * r)
    mean = w @ p / w.sum()
    var = np.maximum(w @ (p * p) / w.sum() - mean ** 2, 0.0)
    k = np.maximum(LOBE_AXIS_VARIANCE - var, LOBE_AXIS_VARIANCE / len(xi))
    uv = np.asarray(uv, dtype=float)
    return 4.0 * np.sqrt(k[0] * k[1]) * uv[..., 0] * uv[..., 1]


def cube_mip_level(sample_area, direction, face_size):
    """log4 of the cube-map texels under one sample (Eq. 4.16-4.17), clamped to 0 .. log2(face_size).

    A'_cube = A' d^2 / cos(beta) with d the distance from the unit sphere's centre to the
    cube [-1, 1]^3 along `direction` and beta the angle between it and the face normal;
    pixels = A'_cube N / 4, N = face_size^2.
    """
    direction = np.asarray(direction, dtype=float)
    u = direction / np.linalg.norm(direction, axis=-1, keepdims=True)
    axis = np.argmax(np.abs(u), axis=-1)
    cos_beta = np.abs(np.take_along_axis(u, axis[..., None], -1)[..., 0])
    d = 1.0 / cos_beta  # where the ray leaves the unit cube: the face axis component reaches 1
    area_cube = np.asarray(sample_area, dtype=float) * d ** 2 / cos_beta       # Eq. 4.16
    pixels = area_cube * face_size ** 2 / 4.0                                   # Eq. 4.17
    return np.clip(np.log(np.maximum(pixels, 1.0)) / np.log(4.0), 0.0, np.log2(face_size))


def importance_mip_level(pdf, n, face_size):
    """Colbert and Krivanek's MIP level 0.5 log2(omega_s / omega_p), clamped to 0 .. log2(face_size).

    omega_s = 1 / (n pdf), the solid angle of one of n importance samples;
    omega_p = 4 pi / (6 face_size^2), that of a cube-map texel.
    """
    omega_s = 1.0 / np.maximum(n * np.asarray(pdf, dtype=float), 1e-30)
    omega_p = 4.0 * np.pi / (6.0 * face_size ** 2)
    return np.clip(0.5 * np.log2(omega_s / omega_p), 0.0, np.log2(face_size))


# ----------------------------------------------------------------------------- Eq. 4.23-4.25, the mean

def pattern_estimate(L, f, pdf, cos_i, weights="4.25"):
    """The normalised estimate of the specular integral from one pattern, shape (..., 3).

    L (..., n, 3): the samples' incident radiance; f, pdf, cos_i (..., n): lobe value,
    importance pdf and cosine on the lobe's side of the surface. Samples with f, pdf or
    cos_i <= 0 are dropped (below the horizon). 0 where no sample counts.
      "4.23": sum L cos f / sum p
      "4.24": sum L cos^2 f / sum p cos
      "4.25": sum L cos^2 f^2 / p / sum f cos
      "mean": sum L p cos / sum p cos, the walkthrough's default times the lobe's albedo A
              (shaders/lobe_sampling.glsl ESTIMATE_ALBEDO; viewer/lobe_albedo.py)
    """
    L = np.asarray(L, dtype=float)
    f, pdf, cos_i = (np.asarray(a, dtype=float) for a in (f, pdf, cos_i))
    keep = (f > 0) & (pdf > 0) & (cos_i > 0)
    f, pdf, cos_i = (np.where(keep, a, 0.0) for a in (f, pdf, cos_i))
    safe_pdf = np.where(keep, pdf, 1.0)
    if weights == "4.23":
        num, den = cos_i * f, pdf
    elif weights == "4.24":
        num, den = cos_i ** 2 * f, pdf * cos_i
    elif weights == "4.25":
        num, den = cos_i ** 2 * f ** 2 / safe_pdf, f * cos_i
    elif weights == "mean":
        num, den = pdf * cos_i, pdf * cos_i
    else:
        raise ValueError(f"weights must be '4.23', '4.24', '4.25' or 'mean', got {weights!r}")
    total = den.sum(axis=-1)
    out = np.sum(num[..., None] * L, axis=-2) / np.where(total > 0, total, 1.0)[..., None]
    return np.where((total > 0)[..., None], out, 0.0)


def pattern_samples(wo, xi, mx, my, r0, alpha, kind):
    """Directions wi, lobe values f, pdf and lobe-side cosines of a pattern xi (n, 2) at views wo (..., 3).

    Shapes (..., n, 3) and (..., n): what the shader computes per sample before its look-up.
    """
    wo = np.asarray(wo, dtype=float)[..., None, :]
    xi = np.asarray(xi, dtype=float)
    wi = pattern_direction(wo, xi[:, 0], xi[:, 1], mx, my, kind)
    f = bsdf.lobe_value(wi, wo, mx, my, r0, alpha, kind)
    pdf = bsdf.lobe_pdf(wi, wo, mx, my, kind)
    cos_i = -wi[..., 2] if kind == "transmit" else wi[..., 2]
    return wi, f, pdf, cos_i
