"""Tests of core/bsdf.py (section 3.3 BSDF, Eq. 3.3-3.6; importance sampling, Eq. 4.5-4.9).

Expected values come from elsewhere than the code under test: Gauss-Legendre x
trapezoid quadrature on (theta, phi) grids, the trigonometric form of Eq. 3.3
as printed, and analytic limits (normalisation, the mirror limit m -> 0).
"""
import numpy as np
import pytest

from glint.core import bsdf as B
from glint.core.scene import Lobe

# ----------------------------------------------------------------------------- helpers

def sph(theta, phi):
    theta, phi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(phi, float))
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)


def grid(nt, nphi, theta_max=np.pi / 2):
    """Directions and solid-angle weights: Gauss-Legendre in theta on [0, theta_max], midpoints in phi."""
    x, w = np.polynomial.legendre.leggauss(nt)
    th = (x + 1) * theta_max / 2
    wt = w * theta_max / 2
    ph = (np.arange(nphi) + 0.5) * 2 * np.pi / nphi
    T, P = np.meshgrid(th, ph, indexing="ij")
    dw = (wt * np.sin(th))[:, None] * (2 * np.pi / nphi) * np.ones_like(P)
    return sph(T, P), dw


def frame_about(axis):
    """Rotation matrix whose third column is `axis` (unit)."""
    a = np.asarray(axis, float)
    t = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
    t /= np.linalg.norm(t)
    return np.stack([t, np.cross(a, t), a], -1)


def sphere_grid_about(axis, nt, nphi):
    """The whole sphere, with the grid's pole at `axis` (resolves a peak or singularity there)."""
    d, dw = grid(nt, nphi, np.pi)
    return d @ frame_about(axis).T, dw


def fibonacci_lattice(seed, n=17711, g=10946):
    """Rank-1 Fibonacci lattice (n, g consecutive Fibonacci numbers), randomly shifted: QMC in [0, 1)^2."""
    shift = np.random.default_rng(seed).random(2)
    i = np.arange(n)
    return np.mod(np.stack([i / n, i * g / n], -1) + shift, 1.0)


def wo_at(theta, phi=0.3):
    return sph(theta, phi)


# ----------------------------------------------------------------------------- Eq. 2.9, 3.3

@pytest.mark.parametrize("mx,my", [(0.05, 0.05), (0.2, 0.2), (0.8, 0.8), (0.05, 0.4), (0.8, 0.1), (0.3, 0.6)])
def test_D_is_normalised(mx, my):
    # int_H D(h) cos(theta_h) dh = 1 (the normalisation of Eq. 3.3)
    h, dw = grid(200, 512)
    total = np.sum(B.beckmann_D(h, mx, my) * h[..., 2] * dw)
    assert total == pytest.approx(1.0, abs=1e-5)


def test_D_matches_trig_form_of_eq_3_3():
    rng = np.random.default_rng(1)
    th = rng.uniform(0, 1.4, 500)
    ph = rng.uniform(0, 2 * np.pi, 500)
    mx, my = 0.3, 0.07
    expect = np.exp(-np.tan(th) ** 2 * (np.cos(ph) ** 2 / mx**2 + np.sin(ph) ** 2 / my**2)) / (
        np.pi * mx * my * np.cos(th) ** 4)
    np.testing.assert_allclose(B.beckmann_D(sph(th, ph), mx, my), expect, rtol=1e-10, atol=1e-300)
    assert B.beckmann_D(np.array([0, 0, 1.0]), mx, my) == pytest.approx(1 / (np.pi * mx * my))
    assert B.beckmann_D(np.array([1.0, 0, 0]), mx, my) == 0.0
    assert B.beckmann_D(np.array([0, 0.6, -0.8]), mx, my) == 0.0


def test_schlick():
    assert B.schlick_F(1.0, 0.04) == pytest.approx(0.04)
    assert B.schlick_F(0.0, 0.04) == pytest.approx(1.0)
    assert B.schlick_F(0.5, 0.2) == pytest.approx(0.2 + 0.8 / 32)
    # rounding past [0, 1] is clamped
    assert B.schlick_F(1.0 + 1e-12, 0.04) == pytest.approx(0.04)
    assert B.schlick_F(-1e-12, 0.04) == pytest.approx(1.0)


# ----------------------------------------------------------------------------- Eq. 3.4-3.6

def random_upper(rng, n):
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2])
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@pytest.mark.parametrize("alpha", [0.0, 0.4, 1.0])
def test_reflection_lobe_is_reciprocal(alpha):
    rng = np.random.default_rng(2)
    wi, wo = random_upper(rng, 2000), random_upper(rng, 2000)
    mx, my = rng.uniform(0.05, 1, 2000), rng.uniform(0.05, 1, 2000)
    a = B.reflect_lobe(wi, wo, mx, my, 0.1, alpha)
    b = B.reflect_lobe(wo, wi, mx, my, 0.1, alpha)
    assert np.mean(a > 1e-3) > 0.3  # not vacuous: most pairs sit inside some lobe
    np.testing.assert_allclose(a, b, rtol=1e-9)


def test_reflection_lobe_explicit_value():
    # one point written out from Eq. 3.4 / 3.3 / 2.9 by hand
    wi, wo = sph(0.5, 0.2), sph(0.7, 3.0)
    mx, my, r0, alpha = 0.3, 0.2, 0.05, 0.5
    h = (wi + wo) / np.linalg.norm(wi + wo)
    th, ph = np.arccos(h[2]), np.arctan2(h[1], h[0])
    D = np.exp(-np.tan(th) ** 2 * (np.cos(ph) ** 2 / mx**2 + np.sin(ph) ** 2 / my**2)) / (
        np.pi * mx * my * np.cos(th) ** 4)
    F = r0 + (1 - r0) * (1 - wo @ h) ** 5
    f = F * D / (4 * (wo @ h) * (wi[2] * wo[2]) ** alpha)
    assert B.reflect_lobe(wi, wo, mx, my, r0, alpha) == pytest.approx(f, rel=1e-12)


def test_reflection_lobe_zero_below_horizon():
    wo = sph(0.4, 0.0)
    assert B.reflect_lobe(sph(2.0, 1.0), wo, 0.3, 0.3, 0.04, 0.0) == 0.0
    assert B.reflect_lobe(sph(0.4, 1.0), sph(2.0, 0.0), 0.3, 0.3, 0.04, 0.0) == 0.0


@pytest.mark.parametrize("alpha", [0.0, 0.7])
def test_transmit_is_mirrored_reflection_times_complementary_fresnel(alpha):
    rng = np.random.default_rng(3)
    wo = random_upper(rng, 1000)
    wi = -random_upper(rng, 1000)  # other side
    mx, my, r0 = 0.25, 0.6, 0.08
    wi_m = wi * [1, 1, -1]
    h = (wi_m + wo) / np.linalg.norm(wi_m + wo, axis=-1, keepdims=True)
    F = r0 + (1 - r0) * (1 - np.sum(wo * h, -1)) ** 5
    ft = B.transmit_lobe(wi, wo, mx, my, r0, alpha)
    fr = B.reflect_lobe(wi_m, wo, mx, my, r0, alpha)
    assert np.mean(ft > 1e-3) > 0.3
    np.testing.assert_allclose(ft, fr * (1 - F) / F, rtol=1e-9)
    # zero on the viewer's side, largest straight through (wi = -wo)
    assert np.all(B.transmit_lobe(-wi, wo, mx, my, r0, alpha)[np.abs(wi[:, 2]) > 1e-9] == 0)
    w0 = sph(0.3, 1.0)
    peak = B.transmit_lobe(-w0, w0, 0.1, 0.1, r0, 0.0)
    near = B.transmit_lobe(-sph([0.35, 0.25, 0.3], [1.0, 1.0, 1.1]), w0, 0.1, 0.1, r0, 0.0)
    assert np.all(near < peak)


def test_bsdf_sums_diffuse_and_lobes():
    rng = np.random.default_rng(4)
    wo = random_upper(rng, 300)
    wi = rng.normal(size=(300, 3))
    wi /= np.linalg.norm(wi, axis=-1, keepdims=True)
    kd = np.array([0.5, 0.4, 0.3])
    lobes = [Lobe("reflect", (1.0, 0.5, 0.2), 0.1, 0.3, 0.04, 0.0),
             Lobe("reflect", (0.2, 0.2, 0.2), 0.5, 0.5, 0.9, 0.5),
             Lobe("transmit", (0.7, 0.8, 0.9), 0.05, 0.05, 0.04, 0.0)]
    got = B.bsdf(wi, wo, kd, lobes)
    up = (wi[:, 2] > 0)[:, None]
    expect = np.where(up, kd / np.pi, 0.0)
    for lb in lobes:
        fn = B.reflect_lobe if lb.kind == "reflect" else B.transmit_lobe
        expect = expect + np.array(lb.ks) * fn(wi, wo, lb.mx, lb.my, lb.r0, lb.alpha)[:, None]
    assert got.shape == (300, 3)
    np.testing.assert_allclose(got, expect, rtol=1e-12)
    # only the transmission lobe reaches the far side; nothing when the viewer is behind
    far = ~up[:, 0]
    t = lobes[2]
    np.testing.assert_allclose(got[far], np.array(t.ks) * B.transmit_lobe(
        wi[far], wo[far], t.mx, t.my, t.r0, t.alpha)[:, None], rtol=1e-12)
    assert np.all(B.bsdf(wi, -wo, kd, lobes) == 0)
    # broadcasting: one wo, many wi
    assert B.bsdf(wi, wo[0], kd, lobes).shape == (300, 3)
    assert B.bsdf(wi, wo[0], kd, []).shape == (300, 3)


# ----------------------------------------------------------------------------- Eq. 4.5-4.9

def test_half_vector_quadrant_follows_xi2():
    xi2 = (np.arange(400) + 0.5) / 400
    for mx, my in [(0.3, 0.3), (0.01, 1.0), (1.0, 0.01), (0.2, 0.05)]:
        h = B.sample_half_vector(0.5, xi2, mx, my)
        np.testing.assert_allclose(np.linalg.norm(h, axis=-1), 1, rtol=1e-12)
        assert np.all(h[:, 2] > 0)
        phi = np.mod(np.arctan2(h[:, 1], h[:, 0]), 2 * np.pi)
        assert np.all(np.diff(phi) > 0)  # monotone over [0, 2 pi): no quadrant folding
        # same quadrant as 2 pi xi2 (Eq. 4.5 maps quadrants onto themselves)
        np.testing.assert_array_equal(np.floor(phi / (np.pi / 2)), np.floor(4 * xi2))
        if mx == my:
            np.testing.assert_allclose(phi, 2 * np.pi * xi2, rtol=1e-12)
    # Eq. 4.6 at phi = 0: tan(theta_h) = mx sqrt(-log xi1)
    h = B.sample_half_vector(0.3, 0.0, 0.2, 0.7)
    assert np.arctan2(h[0], h[2]) == pytest.approx(np.arctan(0.2 * np.sqrt(-np.log(0.3))))


def h_space_mass(wo, mx, my):
    """Mass of D(h) cos(theta_h) with wo.h > 0: what the pdf of Eq. 4.9 integrates to over the sphere."""
    h, dw = grid(300, 1024)
    return np.sum(B.beckmann_D(h, mx, my) * h[..., 2] * (h @ wo > 0) * dw)


@pytest.mark.parametrize("kind", ["reflect", "transmit"])
@pytest.mark.parametrize("theta_o,mx,my", [(0.0, 0.05, 0.05), (0.0, 0.1, 0.4), (1.2, 0.5, 0.5), (1.45, 0.8, 0.3)])
def test_pdf_integrates_to_half_vector_mass(kind, theta_o, mx, my):
    wo = wo_at(theta_o)
    # the pdf is singular like 1/|wi + wo| where h is perpendicular to wo: put the grid's pole there
    wi, dw = sphere_grid_about(-wo if kind == "reflect" else -wo * [1, 1, -1], 300, 600)
    total = np.sum(B.lobe_pdf(wi, wo, mx, my, kind) * dw)
    mass = h_space_mass(wo, mx, my)
    assert total <= 1 + 1e-3
    assert total == pytest.approx(mass, abs=2e-3)
    if theta_o == 0:
        assert total == pytest.approx(1.0, abs=1e-4)


@pytest.mark.parametrize("kind", ["reflect", "transmit"])
@pytest.mark.parametrize("theta_o,mx,my", [(0.2, 0.1, 0.1), (0.9, 0.4, 0.1), (1.35, 0.6, 0.6)])
def test_samples_follow_pdf(kind, theta_o, mx, my):
    wo = wo_at(theta_o)
    xi = fibonacci_lattice(seed=5)
    wi = B.sample_lobe(wo, 1 - xi[:, 0], xi[:, 1], mx, my, kind)
    np.testing.assert_allclose(np.linalg.norm(wi, axis=-1), 1, rtol=1e-9)
    valid = B.lobe_pdf(wi, wo, mx, my, kind) > 0  # samples with wo.h <= 0 carry no density

    s = -1.0 if kind == "transmit" else 1.0  # which side the lobe lies on
    tests = [lambda w: np.ones(w.shape[:-1]),
             lambda w: w[..., 0],
             lambda w: w[..., 1] ** 2,
             lambda w: np.exp(2 * w[..., 2] * s),
             lambda w: (w[..., 2] * s > 0).astype(float)]  # the part of the lobe on the right side
    axis = -wo if kind == "reflect" else -wo * [1, 1, -1]
    g, dw = sphere_grid_about(axis, 300, 600)
    p = B.lobe_pdf(g, wo, mx, my, kind)
    for fn in tests:
        sampled = np.mean(fn(wi) * valid)
        quad = np.sum(fn(g) * p * dw)
        assert sampled == pytest.approx(quad, abs=3e-3)


def test_transmit_samples_are_mirrored_reflection_samples():
    wo = wo_at(0.6)
    xi1, xi2 = np.linspace(0.01, 0.99, 50), np.linspace(0.99, 0.01, 50)
    r = B.sample_lobe(wo, xi1, xi2, 0.2, 0.3, "reflect")
    t = B.sample_lobe(wo, xi1, xi2, 0.2, 0.3, "transmit")
    np.testing.assert_array_equal(t, r * [1, 1, -1])
    np.testing.assert_allclose(B.lobe_pdf(t, wo, 0.2, 0.3, "transmit"), B.lobe_pdf(r, wo, 0.2, 0.3, "reflect"))


# ----------------------------------------------------------------------------- albedo and energy

def quad_albedo(wo, mx, my, r0, alpha, kind, nt=300, nphi=600):
    wi, dw = grid(nt, nphi)
    if kind == "transmit":
        wi = wi * [1, 1, -1]
    return np.sum(B.lobe_value(wi, wo, mx, my, r0, alpha, kind) * np.abs(wi[..., 2]) * dw)


@pytest.mark.parametrize("kind,theta_o,mx,my,r0,alpha", [
    ("reflect", 0.0, 0.1, 0.1, 1.0, 0.0),
    ("reflect", 0.8, 0.3, 0.3, 0.04, 0.5),
    ("reflect", 1.3, 0.15, 0.6, 0.5, 1.0),
    ("reflect", 1.5, 1.0, 1.0, 1.0, 0.0),
    ("reflect", 1.0, 1.0, 0.2, 0.9, 1.0),
    ("transmit", 0.5, 0.2, 0.2, 0.04, 0.0),
    ("transmit", 1.4, 0.5, 0.1, 0.2, 0.7),
])
def test_albedo_matches_quadrature(kind, theta_o, mx, my, r0, alpha):
    wo = wo_at(theta_o)
    a = B.lobe_albedo(wo, mx, my, r0, alpha, kind)
    assert a == pytest.approx(quad_albedo(wo, mx, my, r0, alpha, kind), rel=5e-3)


@pytest.mark.parametrize("kind", ["reflect", "transmit"])
def test_albedo_mirror_limit(kind):
    # m -> 0: one sample at the mirror (or straight-through) direction, h = n, wi.z = wo.z = c:
    # int f cos = F(c) c / c^(2 alpha)  (Eq. 3.4 with int D dh -> 1), 1 - F for transmission
    c = np.array([1.0, 0.7, 0.3, 0.1])
    wo = np.stack([np.sqrt(1 - c**2), 0 * c, c], -1)
    for alpha in (0.0, 0.5, 1.0):
        F = 0.04 + 0.96 * (1 - c) ** 5
        F = F if kind == "reflect" else 1 - F
        a = B.lobe_albedo(wo, 1e-4, 1e-4, 0.04, alpha, kind)
        np.testing.assert_allclose(a, F * c / c ** (2 * alpha), rtol=1e-3)


def test_importance_sampling_estimator_converges_to_albedo():
    rng = np.random.default_rng(6)
    n = 1 << 17
    for kind, wo, mx, my, r0, alpha in [("reflect", wo_at(0.7), 0.2, 0.5, 0.1, 0.3),
                                        ("transmit", wo_at(1.2), 0.3, 0.3, 0.04, 0.0),
                                        ("reflect", wo_at(1.4), 0.8, 0.8, 1.0, 0.0)]:
        xi1, xi2 = 1 - rng.random(n), rng.random(n)  # xi1 in (0, 1]
        wi = B.sample_lobe(wo, xi1, xi2, mx, my, kind)
        f = B.lobe_value(wi, wo, mx, my, r0, alpha, kind)
        p = B.lobe_pdf(wi, wo, mx, my, kind)
        est = np.where(p > 0, f * np.abs(wi[:, 2]) / np.where(p > 0, p, 1), 0.0)  # Eq. 4.4
        # the cancelled form used by lobe_albedo is the same weight
        np.testing.assert_allclose(B.sample_weight(wi, wo, r0, alpha, kind), est, rtol=1e-9, atol=1e-300)
        sigma = est.std() / np.sqrt(n)
        assert abs(est.mean() - B.lobe_albedo(wo, mx, my, r0, alpha, kind)) < 4 * sigma + 1e-4


def test_albedo_alpha0_at_most_one():
    # alpha = 0 is energy conserving (thesis 3.3). r0 = 1 (F = 1) bounds every reflection lobe,
    # r0 = 0 every transmission lobe; and a reflect + transmit pair with the same roughness
    # shares one budget: F + (1 - F) on the same half vectors = the r0 = 1 reflection albedo.
    ms = np.array([1e-4, 1e-2, 0.1, 0.3, 1.0])
    th = np.linspace(0, np.pi / 2, 13)
    wo = np.stack([np.sin(th), 0.6 * np.sin(th), np.cos(th)], -1)
    wo = (wo / np.linalg.norm(wo, axis=-1, keepdims=True))[:, None, None, :]
    mx, my = ms[None, :, None], ms[None, None, :]
    ok = np.broadcast_to(np.maximum(mx, my) / np.minimum(mx, my) <= 100, (13, 5, 5))
    ar = B.lobe_albedo(wo, mx, my, 1.0, 0.0, "reflect", n=2048)
    at = B.lobe_albedo(wo, mx, my, 0.0, 0.0, "transmit", n=2048)
    assert ar.shape == (13, 5, 5)
    assert np.all(ar[ok] <= 1 + 1e-9) and np.all(at[ok] <= 1 + 1e-9)
    assert np.all(ar >= 0) and np.all(at >= 0)
    assert ar[0, 0, 0] == pytest.approx(1.0, abs=1e-6)  # mirror at normal incidence keeps everything
    pair = (B.lobe_albedo(wo, mx, my, 0.3, 0.0, "reflect", n=2048)
            + B.lobe_albedo(wo, mx, my, 0.3, 0.0, "transmit", n=2048))
    np.testing.assert_allclose(pair, ar, rtol=1e-9)


def test_extremes_are_finite_and_non_negative():
    ms = np.array([1e-4, 1e-3, 1e-2, 0.3, 1.0])
    mx, my = np.meshgrid(ms, ms, indexing="ij")
    keep = np.maximum(mx, my) / np.minimum(mx, my) <= 100
    mx, my = mx[keep], my[keep]  # (P,)
    c = np.array([0.0, 1e-300, 1e-12, 1e-6, 1e-3, 0.1, 0.5, 1.0])
    wo = np.concatenate([np.stack([np.sqrt(1 - c**2), 0 * c, c], -1),
                         np.stack([0 * c, np.sqrt(1 - c**2), c], -1)])  # (W, 3)
    wi = np.concatenate([wo, -wo, wo * [-1, -1, 1], wo * [1, 1, -1], wo * [-1, 1, 1],
                         [[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0], [0, -1.0, 0]]])  # (I, 3)
    WI, WO = wi[:, None, None, :], wo[None, :, None, :]
    MX, MY = mx[None, None, :], my[None, None, :]
    xi1 = np.array([0.0, 1e-300, 1e-12, 0.5, 1 - 1e-16, 1.0])[:, None, None]
    xi2 = np.array([0.0, 0.25, 0.5, 0.75, 1 - 1e-16, 1.0])[None, :, None]
    with np.errstate(divide="raise", over="raise", invalid="raise"):  # guards, not luck
        h = B.sample_half_vector(xi1, xi2, MX[0], MY[0])
        assert np.all(np.isfinite(h)) and np.all(h[..., 2] > 0)
        np.testing.assert_allclose(np.linalg.norm(h, axis=-1), 1, rtol=1e-12)
        assert np.all(np.isfinite(B.beckmann_D(h, MX[0], MY[0])))
        for alpha in (0.0, 0.5, 1.0):
            for kind in ("reflect", "transmit"):
                f = B.lobe_value(WI, WO, MX, MY, 0.04, alpha, kind)
                p = B.lobe_pdf(WI, WO, MX, MY, kind)
                w = B.sample_weight(WI, WO, 0.04, alpha, kind)
                for v in (f, p, w):
                    assert np.all(np.isfinite(v)) and np.all(v >= 0)
                wo4 = wo[:, None, None, None, :]
                s = B.sample_lobe(wo4, xi1.reshape(1, -1, 1, 1), xi2.reshape(1, 1, -1, 1),
                                  mx.reshape(1, 1, 1, -1), my.reshape(1, 1, 1, -1), kind)
                assert s.shape == (len(wo), 6, 6, len(mx), 3)
                assert np.all(np.isfinite(s))
                np.testing.assert_allclose(np.linalg.norm(s, axis=-1), 1, rtol=1e-9)
                ws = B.sample_weight(s, wo4, 0.04, alpha, kind)
                assert np.all(np.isfinite(ws)) and np.all(ws >= 0)
                a = B.lobe_albedo(wo[:, None, :], mx, my, 0.04, alpha, kind, n=1024)
                assert np.all(np.isfinite(a)) and np.all(a >= 0)
                # the COS_MIN floor bounds the (non-conserving, alpha > 0) lobes
                # (weight <= 1 / (cos(theta_h) COS_MIN^alpha), sampled cos(theta_h) > 0.3 here)
                assert np.all(a <= 3.0 / B.COS_MIN ** alpha)
            rgb = B.bsdf(WI, WO, [0.5, 0.5, 0.5], [Lobe("reflect", (1, 1, 1), 1e-4, 1e-2, 0.04, alpha),
                                                   Lobe("transmit", (1, 1, 1), 1.0, 1e-2, 0.04, alpha)])
            assert np.all(np.isfinite(rgb)) and np.all(rgb >= 0)


def test_unknown_kind_rejected():
    with pytest.raises(ValueError):
        B.lobe_pdf(np.array([0, 0, 1.0]), np.array([0, 0, 1.0]), 0.1, 0.1, "refract")
