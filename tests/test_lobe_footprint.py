"""The per-sample MIP footprint of pattern look-ups in cube maps: the lobe's second moment
(viewer/lobe_patterns.py pattern_footprint_area, shaders/lobe_sampling.glsl) against the
thesis' share A / n of the 99 % ellipse (Eq. 4.16).

The independent expectation: a narrow lobe's integral over an analytic environment (a step
edge) by quasi-random importance sampling of core/bsdf.py, against the single (n = 1) look-up
of a cube map face whose MIP chain is GL's 2 x 2 box filter, read trilinearly. Averaged over
the edge's position within a texel, a bilinear look-up of a box-filtered level of texel size s
filters with box(s) * tent(s), the sum of three uniform variables of width s (Irwin-Hall), so
the look-up's response to a step is that distribution's tail; no glint code filters it.
"""
from __future__ import annotations

import numpy as np
import pytest

from glint.bench import glsl_eval
from glint.core import bsdf as B
from glint.viewer import lobe_patterns as P

FACE = 256  # texels per cube face side: texel size 2 / FACE at unit distance


def irwin_hall3_tail(y):
    """P(U1 + U2 + U3 > y) for U_i uniform on [-1/2, 1/2]."""
    t = np.clip(np.asarray(y, float) + 1.5, 0.0, 3.0)
    cdf = np.where(t <= 1, t ** 3 / 6, np.where(t <= 2, (-2 * t ** 3 + 9 * t ** 2 - 9 * t + 3) / 6,
                                                   1 - (3 - t) ** 3 / 6))
    return 1.0 - cdf


def lookup_step_response(area, d):
    """A trilinear look-up of the face's box-filtered MIP chain at the MIP level of `area`
    (Eq. 4.17 with the look-up along the face's axis, where Eq. 4.16's d = cos(beta) = 1),
    for radiance 1 where the tangent-plane coordinate x > d and 0 elsewhere."""
    texel = 2.0 / FACE
    level = np.clip(0.5 * np.log2(max(area / texel ** 2, 1.0)), 0.0, np.log2(FACE))
    lo = np.floor(level)
    s_lo, s_hi = texel * 2.0 ** lo, texel * 2.0 ** (lo + 1)
    frac = level - lo
    return (1 - frac) * irwin_hall3_tail(d / s_lo) + frac * irwin_hall3_tail(d / s_hi)


def lobe_step_integral(wo, m, axis_dir, c, d, n=1 << 14):
    """int f cos L / int f cos over the lobe (QMC importance samples, weights f cos / p), L = 1
    where the sample's tangent-plane coordinate along axis_dir, (wi . a) / (wi . c), exceeds d."""
    xi1, xi2 = B.qmc_points(n)
    wi = B.sample_lobe(wo, xi1, xi2, m, m, "reflect")
    pdf = B.lobe_pdf(wi, wo, m, m, "reflect")
    ok = (pdf > 0) & (wi[:, 2] > 0)
    w = np.where(ok, B.lobe_value(wi, wo, m, m, 0.04, 0.0, "reflect") * wi[:, 2] / np.where(ok, pdf, 1.0), 0.0)
    x = (wi @ axis_dir) / (wi @ c)
    return float(np.sum(w * (x > d)) / np.sum(w))


@pytest.mark.parametrize("m", [0.02, 0.03])
def test_moment_footprint_is_closer_to_the_lobe_integral_at_n_1(m):
    """Narrow reflection lobes at n = 1 (the walkthrough's near-mirror case): the look-up filtered
    by the second-moment footprint follows a step edge across the lobe more closely than the
    thesis' A / n, which blurs it with a box as wide as the lobe's 99 % support."""
    xi = P.pattern_xi("ring", 1)
    errors = {"thesis": [], "moment": []}
    for theta in (0.0, 30.0, 60.0):
        wo = np.array([np.sin(np.radians(theta)), 0.0, np.cos(np.radians(theta))])
        c = P.pattern_direction(wo, 1.0, 0.0, m, m, "reflect")
        uv = P.lobe_ellipse_axes(wo, m, m, "reflect")
        areas = {"thesis": P.lobe_ellipse_area(wo, m, m, "reflect") / 1, "moment": P.pattern_footprint_area(xi, uv)}
        for xi2, half_axis in ((0.0, uv[0]), (0.25, uv[1])):  # edges across the ellipse's u and v axes
            border = P.pattern_direction(wo, 0.0, xi2, m, m, "reflect")
            a = border - (border @ c) * c
            a /= np.linalg.norm(a)
            for d in np.linspace(-0.6, 0.6, 7) * half_axis:
                want = lobe_step_integral(wo, m, a, c, d)
                for key, area in areas.items():
                    errors[key].append(abs(lookup_step_response(area, d) - want))
    thesis, moment = np.mean(errors["thesis"]), np.mean(errors["moment"])
    assert moment < 0.5 * thesis, (moment, thesis)
    assert moment < 0.04


def test_footprint_by_hand():
    """n = 1: k = s^2 on both axes, area 4 s^2 u v = 2 u v / -log(0.01); a ring of 7 at
    xi1 = 0.6: weights 1 and 6 x 0.01^0.16, positions 0.4 (cos, sin) on the ring."""
    uv = np.array([0.05, 0.02])
    s2 = 1.0 / (-2.0 * np.log(0.01))
    assert P.pattern_footprint_area(P.pattern_xi("ring", 1), uv) == pytest.approx(4 * s2 * 0.05 * 0.02, rel=1e-12)
    w = 0.01 ** 0.16
    v = 6 * w * 0.16 / 2 / (1 + 6 * w)  # mean of cos^2 over 6 evenly spaced angles: 1/2
    assert P.pattern_footprint_area(P.pattern_xi("ring", 7), uv) == pytest.approx(4 * (s2 - v) * 0.05 * 0.02,
                                                                                   rel=1e-6)
    # 19 samples on a line: the pattern's spread takes most of the long axis' variance; the
    # floor s^2 / n keeps a share for each sample
    line = P.pattern_xi("line_x", 19)
    r = 1 - line[:, 0].astype(float)
    x = r * np.cos(2 * np.pi * line[:, 1].astype(float))
    wl = 0.01 ** (r * r)
    vx = np.sum(wl * x * x) / wl.sum() - (np.sum(wl * x) / wl.sum()) ** 2
    kx = max(s2 - vx, s2 / 19)
    assert P.pattern_footprint_area(line, uv) == pytest.approx(4 * np.sqrt(kx * s2) * 0.05 * 0.02, rel=1e-5)


def test_footprint_glsl_matches_numpy():
    rng = np.random.default_rng(5)
    cases = [("ring", 1), ("ring", 3), ("ring", 7), ("line_x", 3), ("line_y", 11), ("line_x", 19)]
    pad = 19
    xi = np.zeros((len(cases), 2 * pad), np.float32)
    for i, (kind, n) in enumerate(cases):
        xi[i, :2 * n] = P.pattern_xi(kind, n).ravel()
    count = np.array([n for _, n in cases], np.float32)
    uv = (10.0 ** rng.uniform(-3, 1, (len(cases), 2))).astype(np.float32)
    body = ("PatternMoment pm = PatternMoment(0.0, vec2(0.0), vec2(0.0));"
            "for (int k = 0; k < int(count); ++k) add_pattern_moment(pm, vec2(xi[2 * k], xi[2 * k + 1]));"
            "area = pattern_footprint_area(pm, int(count), uv);")
    out = glsl_eval.evaluate("lobe_sampling.glsl", body, {"xi": xi, "count": count, "uv": uv}, {"area": 1})
    want = [P.pattern_footprint_area(xi[i, :2 * n].reshape(n, 2), uv[i].astype(float))
            for i, (_, n) in enumerate(cases)]
    np.testing.assert_allclose(out["area"], want, rtol=2e-4)
