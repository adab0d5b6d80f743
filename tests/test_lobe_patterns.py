"""Regular lobe patterns (section 4.4.3): viewer/lobe_patterns.py and shaders/lobe_sampling.glsl.

Expected values come from the thesis' own listings (the n = 5 line pattern), from hand
calculation (MIP levels, ellipse areas at normal incidence), from quadrature of the
Beckmann distribution (Eq. 4.10's 99%), from core/bsdf.py (importance samples, the
directional albedo) and, for the GLSL, from the numpy reference in lobe_patterns.py
evaluated in float64 on the same float32 inputs.
"""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from glint.bench import glsl_eval
from glint.core import bsdf as B
from glint.viewer import lobe_patterns as P

KINDS = {"reflect": 0.0, "transmit": 1.0}  # LOBE_REFLECT, LOBE_TRANSMIT in ks.a (viewer/gpu_materials.py)


def f32(a):
    return np.asarray(a, np.float32).astype(np.float64)


def sph(theta, phi):
    theta, phi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(phi, float))
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)


def run(body, outputs, defines=None, **inputs):
    return glsl_eval.evaluate("lobe_sampling.glsl", body, inputs, outputs, defines)


# ----------------------------------------------------------------------------- patterns in (xi1, xi2)

def test_line_pattern_is_the_thesis_listing():
    # section 4.4.3: "in case of n=5 this produces the pairs (1/5, .25), (3/5, .25), (5/5, .75), (3/5, .75), (1/5, .75)"
    want = [(1 / 5, 0.25), (3 / 5, 0.25), (5 / 5, 0.75), (3 / 5, 0.75), (1 / 5, 0.75)]
    np.testing.assert_allclose(P.pattern_xi("line_y", 5), want, rtol=0, atol=1e-7)
    np.testing.assert_allclose(P.pattern_xi("line_x", 5), [(x, y - 0.25) for x, y in want], rtol=0, atol=1e-7)
    # n = 4 by the listed rule: k = 0, 1, 2 at xi1 = 1/4, 3/4, 5/4 (i.e. 3/4 on the other side), k = 3 at 2 - 7/4
    np.testing.assert_allclose(P.pattern_xi("line_y", 4), [(0.25, 0.25), (0.75, 0.25), (0.75, 0.75), (0.25, 0.75)])
    assert P.pattern_xi("line_x", 1).tolist() == [[1.0, 0.5]]  # the lobe centre


@pytest.mark.parametrize("n", range(1, 20))
def test_line_samples_are_equally_spaced_and_symmetric(n):
    # signed position along the line: (1 - xi1) on the first side, -(1 - xi1) on the other
    for kind, first in (("line_x", 0.0), ("line_y", 0.25)):
        xi = P.pattern_xi(kind, n).astype(float)
        assert xi.dtype == float and xi.shape == (n, 2)
        assert np.all((xi[:, 0] > 0) & (xi[:, 0] <= 1))
        s = np.where(np.isclose(xi[:, 1], first), 1.0, -1.0) * (1.0 - xi[:, 0])
        np.testing.assert_allclose(np.sort(s), (2 * np.arange(n) - (n - 1)) / n, atol=1e-6)


def test_ring_pattern():
    # "one sample at the lobe center xi1 = 1, xi2 = 0, the other samples at xi1 = radius, xi2 = (k-1)/(n-1)"
    np.testing.assert_allclose(P.pattern_xi("ring", 7), [(1, 0)] + [(0.6, k / 6) for k in range(6)], atol=1e-7)
    assert P.pattern_xi("ring", 1).tolist() == [[1.0, 0.0]]
    assert P.pattern_xi("ring", 3).dtype == np.float32


def test_multi_ring_pattern():
    """Planar reflectors (section 4.5.3, viewer/lobe_patterns.py "Planar reflectors"): the centre,
    then rings at theta_h = 0.4 and 0.8 theta_thresh, the outer one turned by half its spacing."""
    want = ([(1, 0)] + [(0.6, k / 5) for k in range(5)] + [(0.2, (k + 0.5) / 4) for k in range(4)])
    np.testing.assert_allclose(P.pattern_xi("multi_ring", 10), want, atol=1e-7)
    np.testing.assert_allclose(P.pattern_xi("multi_ring", 5), [(1, 0), (0.6, 0), (0.6, 0.5), (0.2, 0.25), (0.2, 0.75)],
                               atol=1e-7)
    for n in range(1, 5):  # up to 3 ring samples: one ring, the curved ring itself
        np.testing.assert_array_equal(P.pattern_xi("multi_ring", n), P.pattern_xi("ring", n))
    for n in range(5, 20):
        xi = P.pattern_xi("multi_ring", n).astype(float)
        assert xi.shape == (n, 2) and np.all((xi >= 0) & (xi <= 1))
        outer, inner = np.sum(np.isclose(xi[:, 0], 0.2)), np.sum(np.isclose(xi[:, 0], 0.6))
        assert inner + outer == n - 1 and inner - outer in (0, 1)


def test_planar_lobes_get_the_multi_ring_when_isotropic():
    assert P.choose_pattern(0.1, 0.1, planar=True) == "multi_ring"
    assert P.choose_pattern(0.1, 0.1 * P.LINE_RATIO, planar=True) == "line_y"  # lines stay lines
    assert P.choose_pattern(0.1, 0.1) == "ring"                                # cube maps keep the ring
    assert [P.samples_for_lobe(m, m, planar=True) for m in (0.005, 0.015, 0.03, 0.06, 0.15, 0.5)] == [1, 3, 5, 10, 10, 25]
    assert P.samples_for_lobe(0.01, 0.1, planar=True) == P.samples_for_lobe(0.01, 0.1)


def test_bad_patterns_are_refused():
    with pytest.raises(ValueError, match="kind"):
        P.pattern_xi("spiral", 5)
    with pytest.raises(ValueError, match="at least one"):
        P.pattern_xi("ring", 0)


def test_choose_pattern_by_anisotropy():
    t = P.LINE_RATIO
    assert P.choose_pattern(0.1, 0.1) == "ring"
    assert P.choose_pattern(0.1, 0.1 * t * 0.99) == "ring"
    assert P.choose_pattern(0.1, 0.1 * t) == "line_y"      # m_x << m_y: long along b
    assert P.choose_pattern(0.1 * t, 0.1) == "line_x"      # m_x >> m_y: long along t
    assert P.choose_pattern(0.001, 0.1) == "line_y"
    assert P.choose_pattern(0.0, 0.0) == "ring"            # clamped to M_MIN like the BSDF
    assert P.choose_pattern(0.0, 0.01) == "line_y"


def test_samples_for_lobe():
    assert P.samples_for_lobe(1e-4, 1e-4) == 1            # mirror: one sample, the Fresnel-weighted mirror direction
    assert P.samples_for_lobe(0.0, 0.0) == 1
    widths = np.geomspace(1e-4, 1.0, 60)
    ring = [P.samples_for_lobe(m, m) for m in widths]
    assert ring == sorted(ring)                            # never fewer samples for a wider lobe
    assert ring[-1] > ring[0] and max(ring) <= 19
    line = [P.samples_for_lobe(m / 10, m) for m in widths]
    assert line == sorted(line) and line[-1] >= ring[-1]
    assert all(P.samples_for_lobe(mx, my) == P.samples_for_lobe(my, mx) for mx, my in [(0.01, 0.3), (0.05, 0.2)])
    assert all(n % 2 == 1 for n in ring + line)            # odd: a line keeps its centre sample


# ----------------------------------------------------------------------------- Eq. 4.10

@pytest.mark.parametrize("mx,my", [(0.05, 0.05), (0.2, 0.2), (0.6, 0.6), (0.05, 0.3)])
def test_theta_thresh_holds_99_percent_of_the_importance_samples(mx, my):
    """Eq. 4.10 at xi1 = 0.01: the share of Eq. 4.5-4.7 half vectors inside the border, and of D's mass."""
    xi1, xi2 = B.qmc_points(1 << 14)
    h = B.sample_half_vector(xi1, xi2, mx, my)
    theta = np.arccos(np.clip(h[:, 2], -1, 1))
    phi = np.arctan2(h[:, 1], h[:, 0])
    inside = theta < B.theta_thresh(phi, mx, my)
    assert inside.mean() == pytest.approx(0.99, abs=0.002)
    # the same by quadrature of the normalised distribution (Eq. 3.3): int_{theta < thresh} D cos dh = 0.99
    x, w = np.polynomial.legendre.leggauss(400)
    ph = (np.arange(720) + 0.5) * 2 * np.pi / 720
    th_max = B.theta_thresh(ph, mx, my)                  # integrate theta over [0, thresh(phi)] per phi
    th = (x[:, None] + 1) / 2 * th_max
    dth = w[:, None] / 2 * th_max
    hh = sph(th, ph[None, :])
    mass = np.sum(B.beckmann_D(hh, mx, my) * np.cos(th) * np.sin(th) * dth) * 2 * np.pi / 720
    assert mass == pytest.approx(0.99, abs=1e-4)


# ----------------------------------------------------------------------------- pattern directions, GLSL == numpy

LOBES = [(1e-4, 1e-4), (0.01, 0.01), (0.1, 0.1), (0.5, 0.5), (1.0, 1.0), (0.01, 1.0), (1.0, 0.01), (0.3, 0.003)]
VIEWS = [(0.0, 0.0), (0.6, 0.3), (1.2, 2.0), (1.5, 4.0), (np.pi / 2, 1.0)]


def lobe_rows(xi_table):
    """(xi, wo, shape, ks, kind) rows: every pattern position of xi_table for every lobe, view and kind."""
    rows = []
    for (mx, my), (th, ph), (kind, flag) in itertools.product(LOBES, VIEWS, KINDS.items()):
        wo = sph(th, ph)
        if th == np.pi / 2:
            wo[2] = 0.0  # exactly along the surface
        for xi in xi_table:
            rows.append(np.r_[xi, wo, mx, my, 0.04, 0.5, flag])
    rows = f32(rows)
    ks = np.concatenate([np.ones((len(rows), 3)), rows[:, 9:10]], axis=1)
    return rows[:, 0:2], rows[:, 2:5], rows[:, 5:9], ks, rows[:, 9]


def numpy_by_kind(fn, kind, *args):
    out = None
    for name, flag in KINDS.items():
        k = kind == flag
        part = fn(*(a[k] for a in args), name)
        if out is None:
            out = np.zeros((len(kind),) + part.shape[1:])
        out[k] = part
    return out


def test_pattern_direction_matches_numpy():
    table = np.concatenate([P.pattern_xi("ring", 7), P.pattern_xi("line_x", 5), P.pattern_xi("line_y", 4),
                            P.pattern_xi("multi_ring", 10), [[0.0, 0.0], [0.0, 0.25], [0.3, 0.9]]])
    xi, wo, shape, ks, kind = lobe_rows(table)
    got = run("wi = pattern_direction(wo, xi, Lobe(ks, shape));", {"wi": 3}, xi=xi, wo=wo, ks=ks, shape=shape)["wi"]
    want = numpy_by_kind(lambda x, w, s, k: P.pattern_direction(w, x[:, 0], x[:, 1], s[:, 0], s[:, 1], k),
                         kind, xi, wo, shape)
    np.testing.assert_allclose(got, want, rtol=0, atol=2e-6)
    # the centre sample is the mirror direction (reflection) or straight through (transmission)
    centre = (xi[:, 0] == 1.0) & (kind == KINDS["reflect"])
    np.testing.assert_allclose(got[centre], wo[centre] * [-1, -1, 1], atol=1e-6)
    centre = (xi[:, 0] == 1.0) & (kind == KINDS["transmit"])
    np.testing.assert_allclose(got[centre], -wo[centre], atol=1e-6)


def test_pattern_border_is_theta_thresh_from_the_lobe_centre():
    """At normal incidence a border sample (xi1 = 0) lies 2 theta_thresh from the mirror direction n."""
    for mx, my, xi2 in [(0.1, 0.1, 0.3), (0.05, 0.4, 0.0), (0.05, 0.4, 0.25)]:
        wi = P.pattern_direction(np.array([0, 0, 1.0]), 0.0, xi2, mx, my, "reflect")
        phi = P.pattern_phi(xi2, mx, my)
        assert np.arccos(wi[2]) == pytest.approx(2 * B.theta_thresh(phi, mx, my), rel=1e-12)
        assert np.arctan2(wi[1], wi[0]) == pytest.approx(phi)  # wi = 2 cos(th) h - n leans the way h does


# ----------------------------------------------------------------------------- Eq. 4.14-4.17 and Colbert-Krivanek

def test_ellipse_area_by_hand():
    # normal incidence, isotropic m: U, V at 2 theta_thresh from n, theta_thresh = atan(m sqrt(ln 100))
    for m in (0.01, 0.1, 0.3):
        t = np.arctan(m * np.sqrt(np.log(100.0)))
        assert P.lobe_ellipse_area(np.array([0, 0, 1.0]), m, m, "reflect") == pytest.approx(np.pi * np.tan(2 * t) ** 2)
        assert P.lobe_ellipse_area(np.array([0, 0, 1.0]), m, m, "transmit") == pytest.approx(np.pi * np.tan(2 * t) ** 2)
    # anisotropic: u from m_x, v from m_y
    tx, ty = np.arctan(0.02 * np.sqrt(np.log(100.0))), np.arctan(0.2 * np.sqrt(np.log(100.0)))
    assert P.lobe_ellipse_area(np.array([0, 0, 1.0]), 0.02, 0.2, "reflect") == pytest.approx(
        np.pi * np.tan(2 * tx) * np.tan(2 * ty))
    # m = 1: 2 theta_thresh = 130 deg, past 90: both axes capped
    assert P.lobe_ellipse_area(np.array([0, 0, 1.0]), 1.0, 1.0, "reflect") == pytest.approx(np.pi * P.LOBE_TAN_MAX ** 2)


def test_cap_solid_angle_by_hand():
    """The cap's solid angle at normal incidence is 2 pi (1 - cos 2 theta_thresh) (a round cap whose
    border lies 2 theta_thresh from n), for narrow lobes and for lobes past 90 degrees alike. Catches
    the cap measured as Eq. 4.15's tangent-plane area (pi tan^2: 1.7x too large at m = 0.2, pi
    LOBE_TAN_MAX^2 at m = 1)."""
    n = np.array([0, 0, 1.0])
    for m in (0.01, 0.2, 0.75, 1.0):
        t = np.arctan(m * np.sqrt(np.log(100.0)))
        for kind in ("reflect", "transmit"):
            assert P.lobe_cap_solid_angle(n, m, m, kind) == pytest.approx(2 * np.pi * (1 - np.cos(2 * t)), rel=1e-9)
    # anisotropic: the ellipse of the two chords, pi (2 sin tx) (2 sin ty)
    tx, ty = np.arctan(0.02 * np.sqrt(np.log(100.0))), np.arctan(0.7 * np.sqrt(np.log(100.0)))
    assert P.lobe_cap_solid_angle(n, 0.02, 0.7, "reflect") == pytest.approx(4 * np.pi * np.sin(tx) * np.sin(ty))
    # narrow lobes: the same as Eq. 4.15's area to first order
    assert P.lobe_cap_solid_angle(n, 0.01, 0.01, "reflect") == pytest.approx(
        P.lobe_ellipse_area(n, 0.01, 0.01, "reflect"), rel=2e-3)


def test_cube_mip_level_by_hand():
    n_texels = 256 ** 2
    # along a face normal: d = 1, cos(beta) = 1, so pixels = A' N / 4; 16 texels -> log4(16) = 2
    area = 16 * 4 / n_texels
    assert P.cube_mip_level(area, [0, 0, 1.0], 256) == pytest.approx(2.0)
    assert P.cube_mip_level(area, [0, -3.0, 0], 256) == pytest.approx(2.0)       # any length, any face
    # towards a cube corner: cos(beta) = 1/sqrt(3), d = sqrt(3): A'_cube = A' 3 sqrt(3)
    assert P.cube_mip_level(area, [1.0, 1.0, -1.0], 256) == pytest.approx(np.log(16 * 3 * np.sqrt(3)) / np.log(4))
    # 45 degrees between two faces: cos(beta) = 1/sqrt(2), d = sqrt(2): factor 2 sqrt(2)
    assert P.cube_mip_level(area, [1.0, 0, 1.0], 256) == pytest.approx(np.log(16 * 2 * np.sqrt(2)) / np.log(4))
    assert P.cube_mip_level(1e-12, [0, 0, 1.0], 256) == 0.0                        # below a texel
    assert P.cube_mip_level(100.0, [0, 0, 1.0], 256) == 8.0                        # past the 1x1 level


def test_importance_mip_level_by_hand():
    size = 128
    omega_p = 4 * np.pi / (6 * size * size)
    # 5 samples whose omega_s = 1/(n pdf) is 16 texels: level 0.5 log2(16) = 2
    pdf = 1.0 / (5 * 16 * omega_p)
    assert P.importance_mip_level(pdf, 5, size) == pytest.approx(2.0)
    assert P.importance_mip_level(pdf * 16, 5, size) == pytest.approx(0.0)
    assert P.importance_mip_level(0.0, 5, size) == 7.0                            # no pdf: coarsest level
    assert P.importance_mip_level(1e9, 5, size) == 0.0


def test_mip_levels_and_areas_match_numpy():
    xi, wo, shape, ks, kind = lobe_rows([[0.0, 0.0]])
    rng = np.random.default_rng(3)
    n = len(wo)
    d = f32(rng.normal(size=(n, 3)) * rng.choice([1e-3, 1, 50], size=(n, 1)))
    area = f32(10.0 ** rng.uniform(-9, 1, n))
    face = f32(rng.choice([16, 128, 512], n))
    pdf = f32(np.concatenate([10.0 ** rng.uniform(-3, 7, n - 2), [0.0, 1e30]]))
    count = f32(rng.choice([1, 7, 19], n))
    out = run("A = lobe_ellipse_area(wo, Lobe(ks, shape)); level = cube_mip_level(area, d, face);"
              "ilevel = importance_mip_level(pdf, int(count), face); cap = lobe_cap_solid_angle(wo, Lobe(ks, shape));",
              {"A": 1, "level": 1, "ilevel": 1, "cap": 1},
              wo=wo, ks=ks, shape=shape, area=area, d=d, face=face, pdf=pdf, count=count)
    want_a = numpy_by_kind(lambda w, s, k: P.lobe_ellipse_area(w, s[:, 0], s[:, 1], k), kind, wo, shape)
    np.testing.assert_allclose(out["A"], want_a, rtol=2e-4)
    want_cap = numpy_by_kind(lambda w, s, k: P.lobe_cap_solid_angle(w, s[:, 0], s[:, 1], k), kind, wo, shape)
    np.testing.assert_allclose(out["cap"], want_cap, rtol=2e-4, atol=1e-6)
    np.testing.assert_allclose(out["level"], P.cube_mip_level(area, d, face), rtol=0, atol=1e-4)
    np.testing.assert_allclose(out["ilevel"], P.importance_mip_level(pdf, count, face), rtol=0, atol=1e-4)


# ----------------------------------------------------------------------------- Eq. 4.23-4.25

def test_pattern_estimate_by_hand():
    L = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]])
    f, p, c = np.array([2.0, 1.0, 5.0]), np.array([4.0, 1.0, 1.0]), np.array([0.5, 1.0, -0.2])  # the third: below
    # Eq. 4.25: (L1 .25 * 4 / 4 + L2 * 1 * 1 / 1) / (2 * .5 + 1 * 1) = (.25 L1 + L2) / 2
    np.testing.assert_allclose(P.pattern_estimate(L, f, p, c), (0.25 * L[0] + L[1]) / 2)
    # Eq. 4.24: (L1 .25 * 2 + L2) / (4 * .5 + 1) = (.5 L1 + L2) / 3
    np.testing.assert_allclose(P.pattern_estimate(L, f, p, c, "4.24"), (0.5 * L[0] + L[1]) / 3)
    # Eq. 4.23: (L1 .5 * 2 + L2) / (4 + 1)
    np.testing.assert_allclose(P.pattern_estimate(L, f, p, c, "4.23"), (L[0] + L[1]) / 5)
    np.testing.assert_array_equal(P.pattern_estimate(L, f * 0, p, c), 0.0)


def hemisphere(n):
    xi1, xi2 = B.qmc_points(n)
    r = np.sqrt(1 - xi1 ** 2)
    return np.stack([r * np.cos(2 * np.pi * xi2), r * np.sin(2 * np.pi * xi2), xi1], -1)  # uniform in solid angle


@pytest.mark.parametrize("m,theta_o", [(0.05, 0.0), (0.05, 0.7), (0.1, 0.0), (0.1, 0.7), (0.3, 0.0)])
def test_eq_4_23_converges_to_the_albedo(m, theta_o):
    """White furnace for the derivation of Eq. 4.20-4.23: samples uniform in solid angle within the lobe
    region PT (theta_h < theta_thresh), constant radiance: sum cos f / sum p -> the directional albedo."""
    wo = sph(theta_o, 0.3)
    albedo = B.lobe_albedo(wo, m, m, 0.04, 0.0, "reflect")
    errors = []
    for n in (1 << 8, 1 << 12, 1 << 16):
        wi = hemisphere(n)
        h, _ = B.half_vector(wi, wo)
        inside = np.arccos(h[:, 2]) < B.theta_thresh(np.arctan2(h[:, 1], h[:, 0]), m, m)
        wi = wi[inside]
        f = B.reflect_lobe(wi, wo, m, m, 0.04, 0.0)
        pdf = B.lobe_pdf(wi, wo, m, m, "reflect")
        errors.append(abs(P.pattern_estimate(np.ones((len(wi), 3)), f, pdf, wi[:, 2], "4.23")[0] / albedo - 1))
    assert errors[-1] < 0.01
    assert errors[-1] <= errors[0] + 1e-3


@pytest.mark.parametrize("m", [0.05, 0.1, 0.2])
@pytest.mark.parametrize("theta_o", [0.0, 0.7])
@pytest.mark.parametrize("r0", [0.04, 1.0])
def test_eq_4_25_ring_of_7_is_close_to_the_albedo(m, theta_o, r0):
    wo = sph(theta_o, 0.3)
    _, f, pdf, cos_i = P.pattern_samples(wo, P.pattern_xi("ring", 7), m, m, r0, 0.0, "reflect")
    estimate = P.pattern_estimate(np.ones(f.shape + (3,)), f, pdf, cos_i)[0]
    assert estimate == pytest.approx(B.lobe_albedo(wo, m, m, r0, 0.0, "reflect"), rel=0.05)


ESTIMATOR = """
    Lobe lobe = Lobe(ks, shape);
    LobeSum s = LobeSum(vec3(0.0), 0.0);
    for (int k = 0; k < N; ++k) {
        vec3 wi = pattern_direction(wo, vec2(xi[2 * k], xi[2 * k + 1]), lobe);
        float cos_i = lobe_is_transmit(lobe) ? -wi.z : wi.z;
        vec3 L = scale * vec3(1.0 + wi.x * wi.x, 1.0 + wi.y, 2.0 - wi.z);   // a smooth test environment
        add_pattern_sample(s, L, lobe_value(wi, wo, lobe), lobe_pdf(wi, wo, lobe), cos_i, EST);
    }
    result = lobe_sum_result(s);
"""


def environment(wi, scale):
    return scale[..., None, None] * np.stack([1 + wi[..., 0] ** 2, 1 + wi[..., 1], 2 - wi[..., 2]], -1)


@pytest.mark.parametrize("weights,define", [("4.25", {"EST": "ESTIMATE_EQ_4_25"}), ("4.24", {"EST": "ESTIMATE_EQ_4_24"}),
                                            ("mean", {"EST": "ESTIMATE_ALBEDO"})])
def test_glsl_estimator_matches_numpy(weights, define):
    """The whole walkthrough estimate of one lobe: pattern, lobe values, pdf, horizon drop, Eq. 4.24/4.25,
    and the albedo-normalised estimate's weighted mean (without its A)."""
    n = 7
    table = np.concatenate([P.pattern_xi(kind, n) for kind in ("ring", "line_x", "line_y")])
    rows = []
    for (mx, my), (th, ph), (kind, flag), r0, alpha in itertools.product(
            LOBES, VIEWS, KINDS.items(), (0.04, 1.0), (0.0, 1.0)):
        for pattern in table.reshape(3, n, 2):
            rows.append(np.r_[pattern.ravel(), np.cos(ph) * np.sin(th), np.sin(ph) * np.sin(th),
                              0.0 if th == np.pi / 2 else np.cos(th), mx, my, r0, alpha, flag, 10.0 ** (th * 8)])
    rows = f32(rows)
    xi, wo, shape, flag, scale = rows[:, :2 * n], rows[:, 2 * n:2 * n + 3], rows[:, 2 * n + 3:2 * n + 7], \
        rows[:, 2 * n + 7], rows[:, 2 * n + 8]
    ks = np.concatenate([np.ones((len(rows), 3)), flag[:, None]], axis=1)
    got = run(ESTIMATOR, {"result": 3}, {"N": n, **define}, xi=xi, wo=wo, ks=ks, shape=shape, scale=scale)["result"]
    assert np.all(np.isfinite(got))
    want = np.zeros((len(rows), 3))
    for name, value in KINDS.items():
        k = flag == value
        for i in np.flatnonzero(k):
            _, f, pdf, cos_i = P.pattern_samples(wo[i], xi[i].reshape(n, 2), *shape[i], name)
            wi = P.pattern_direction(wo[i][None], xi[i].reshape(n, 2)[:, 0], xi[i].reshape(n, 2)[:, 1],
                                     shape[i, 0], shape[i, 1], name)
            want[i] = P.pattern_estimate(environment(wi, scale[i:i + 1])[0], f, pdf, cos_i, weights)
    assert np.count_nonzero(want[:, 0]) > len(want) // 2
    bad = np.abs(got - want) > 2e-4 * np.abs(want) + 1e-7 * scale[:, None]
    assert not bad.any(), f"{bad.any(axis=1).sum()} rows differ, e.g. {got[bad.any(axis=1)][:3]} vs {want[bad.any(axis=1)][:3]}"


def test_no_nan_or_inf_for_degenerate_inputs():
    """Zero and below-horizon views, zero roughness, a zero look-up direction, pdf 0, huge radiance."""
    views = f32([[0, 0, 0], [0, 0, 1], [1, 0, 0], [0, 0, -1], [0.6, 0, -0.8], [1e-20, 0, 0]])
    shapes = f32([[0, 0, 0, 0], [0, 0, 1, 1], [1e-6, 1, 0.5, 1], [1, 1, 1, 0], [1e-4, 1e-2, 0.04, 0.5]])
    xis = f32([[0, 0], [1, 1], [0, 0.5], [1, 0.25], [0.6, 0.999999]])
    rows = f32([np.r_[w, s, x, k] for w, s, x, k in itertools.product(views, shapes, xis, (0.0, 1.0))])
    ks = np.concatenate([np.ones((len(rows), 3)), rows[:, -1:]], axis=1)
    out = run("""
        Lobe lobe = Lobe(ks, shape);
        wi = pattern_direction(wo, xi, lobe);
        A = lobe_ellipse_area(wo, lobe) + lobe_cap_solid_angle(wo, lobe);
        level = cube_mip_level(A, wi, 128.0) + cube_mip_level(0.0, vec3(0.0), 128.0);
        ilevel = importance_mip_level(lobe_pdf(wi, wo, lobe), 7, 128.0) + importance_mip_level(0.0, 0, 128.0);
        result = lobe_sum_result(LobeSum(vec3(0.0), 0.0));
        for (int k = ESTIMATE_ALBEDO; k <= ESTIMATE_EQ_4_24; ++k) {  // every estimator
            LobeSum s = LobeSum(vec3(0.0), 0.0);
            add_pattern_sample(s, vec3(1e30), lobe_value(wi, wo, lobe), lobe_pdf(wi, wo, lobe), abs(wi.z), k);
            add_pattern_sample(s, vec3(1.0), 1e27, 1e20, 1.0, k);
            add_pattern_sample(s, vec3(1.0), 1e-30, 1e-30, 1e-30, k);
            result += lobe_sum_result(s);
        }""",
              {"wi": 3, "A": 1, "level": 1, "ilevel": 1, "result": 3},
              wo=rows[:, 0:3], shape=rows[:, 3:7], xi=rows[:, 7:9], ks=ks)
    for name, values in out.items():
        assert np.all(np.isfinite(values)), name
    assert np.all(out["A"] >= 0) and np.all(out["level"] >= 0) and np.all(out["ilevel"] >= 0)
    assert np.all(out["result"] >= 0)
