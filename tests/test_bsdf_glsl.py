"""shaders/bsdf.glsl against core/bsdf.py, its numpy reference (Eq. 2.9, 3.3-3.5, 4.5-4.9).

The GLSL runs on llvmpipe in float32 (bench/glsl_eval.py); the expected values are
core/bsdf.py in float64 on the very same float32-rounded inputs, so what is compared is
the arithmetic alone. The grid covers the numerics of docs/ARCHITECTURE.md: roughness 1e-4..1,
anisotropy 1:100, alpha 0..1, r0 0..1, both lobe kinds, views from the normal to exactly
along the surface, and directions in the lobe (importance samples), anywhere on the
sphere, and on the special cases (mirror direction, wi = -wo, horizon, zero vectors).
"""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from glint.bench import glsl_eval
from glint.core import bsdf as B

RTOL = 1e-4
KINDS = {"reflect": 0.0, "transmit": 1.0}  # LOBE_REFLECT, LOBE_TRANSMIT in ks.a (viewer/gpu_materials.py)
ROUGHNESS = [(1e-4, 1e-4), (1e-3, 1e-3), (0.01, 0.01), (0.1, 0.1), (0.3, 0.3), (1.0, 1.0),
             (0.01, 1.0), (1.0, 0.01), (1e-4, 1e-2), (0.5, 0.005)]
R0 = [0.0, 0.04, 0.5, 1.0]
ALPHA = [0.0, 0.5, 1.0]
VIEW_THETA = [0.0, 0.5, 1.2, 1.55, 1.5707, np.pi / 2]  # the last one is replaced by an exact z = 0


def f32(a):
    """The float32 value of a, back in float64: what the GPU is given."""
    return np.asarray(a, np.float32).astype(np.float64)


def sph(theta, phi):
    theta, phi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(phi, float))
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)


def views():
    wo = sph(np.repeat(VIEW_THETA, 2), np.tile([0.3, 2.2], len(VIEW_THETA)))
    wo[-2:, 2] = 0.0  # exactly along the surface
    return wo


def lobe_table():
    """Every lobe of the sweep: (mx, my, r0, alpha, kind)."""
    return [(mx, my, r0, a, k) for (mx, my), r0, a, k in itertools.product(ROUGHNESS, R0, ALPHA, KINDS)]


def directions(wo, mx, my, kind, rng):
    """Incident directions for one view and lobe: in the lobe, anywhere, and the special cases."""
    xi1, xi2 = B.qmc_points(12)
    in_lobe = B.sample_lobe(wo, xi1, xi2, mx, my, kind)
    anywhere = rng.normal(size=(12, 3))
    anywhere /= np.linalg.norm(anywhere, axis=1, keepdims=True)
    mirror = np.array([-wo[0], -wo[1], wo[2]])
    special = [mirror, -mirror, -wo, wo, B.mirror(wo), [1.0, 0, 0], [0, -1.0, 0], [0, 0, 1.0], [0, 0, -1.0]]
    return np.concatenate([in_lobe, anywhere, np.array(special, float)])


@pytest.fixture(scope="module")
def sweep():
    """All (wi, wo, lobe) rows of the sweep, float32-rounded, and the lobe parameters per row."""
    rng = np.random.default_rng(4)
    rows, group = [], []
    for mx, my, r0, alpha, kind in lobe_table():
        for wo in views():
            wi = directions(wo, mx, my, kind, rng)
            params = np.tile([mx, my, r0, alpha, KINDS[kind]], (len(wi), 1))
            rows.append(np.concatenate([wi, np.tile(wo, (len(wi), 1)), params], axis=1))
            group.append(np.full(len(wi), len(group)))
    rows = f32(np.concatenate(rows))
    wi, wo, p = rows[:, 0:3], rows[:, 3:6], rows[:, 6:]
    ks = np.concatenate([np.ones((len(p), 3)), p[:, 4:5]], axis=1)
    return wi, wo, p, ks, np.concatenate(group)


def assert_close(got, want, rtol=RTOL, group=None, atol=0.0, what=""):
    """|got - want| <= rtol |want| + 1e-6 max|want in its group| + atol.

    A group is one lobe and view: relative agreement, except for values a million times
    below that lobe's largest, where float32's exp() (underflow below e^-87) and float64's
    (e^-745) part ways.
    """
    got, want = np.asarray(got, float), np.asarray(want, float)
    assert np.all(np.isfinite(got)), f"{what}: non-finite GLSL values"
    if group is not None:
        peak = np.zeros(group.max() + 1)
        np.maximum.at(peak, group, np.abs(want))
        atol = atol + 1e-6 * peak[group]
    bad = np.abs(got - want) > rtol * np.abs(want) + atol
    if np.any(bad):
        i = np.flatnonzero(bad)[:5]
        pytest.fail(f"{what}: {bad.sum()} of {bad.size} differ, e.g. rows {i}: GLSL {got[i]} numpy {want[i]}")


def fresnel_allowance(wi, wo, p, f):
    """The error of reflection lobe values f that u = wo.h alone explains, rounded to float32.

    Schlick's F = r0 + (1 - r0)(1 - u)^5 (Eq. 2.9) with r0 ~ 0 and u ~ 1 (light along the
    normal) is a tiny number whose relative precision float32 cannot hold: u carries an
    error of ~2^-23, so F one of (1 - r0) 5 (1 - u)^4 2^-23. (The transmitted share 1 - F
    is computed without that cancellation in the GLSL and gets no allowance.)
    """
    h, _ = B.half_vector(wi, wo)
    u = np.clip(np.sum(wo * h, axis=-1), 0.0, 1.0)
    r0 = p[:, 2]
    F = B.schlick_F(u, r0)
    dF = (1.0 - r0) * 5.0 * (1.0 - u) ** 4 * 2.0 ** -23
    return np.where((p[:, 4] == KINDS["reflect"]) & (F > 0), np.abs(f) * dF / np.where(F > 0, F, 1.0), 0.0)


def run(body, outputs, **inputs):
    return glsl_eval.evaluate("bsdf.glsl", "Lobe lobe = Lobe(ks, shape);\n" + body, inputs, outputs)


# ----------------------------------------------------------------------------- Eq. 2.9, 3.3

def test_schlick_F_matches_numpy():
    u = f32(np.concatenate([np.linspace(-0.5, 1.5, 201), [0.0, 1.0, 1e-6, 1 - 1e-6]]))
    r0 = f32(np.resize(R0, len(u)))
    got = glsl_eval.evaluate("bsdf.glsl", "F = schlick_F(u, r0);", {"u": u, "r0": r0}, {"F": 1})["F"]
    assert_close(got, B.schlick_F(u, r0), what="schlick_F")


def test_beckmann_D_matches_numpy(sweep):
    wi, wo, p, _, group = sweep
    s = wi + wo
    h = f32(s / np.maximum(np.linalg.norm(s, axis=1, keepdims=True), 1e-30))
    got = glsl_eval.evaluate("bsdf.glsl", "D = beckmann_D(h, m.x, m.y);", {"h": h, "m": p[:, :2]}, {"D": 1})["D"]
    want = B.beckmann_D(h, p[:, 0], p[:, 1])
    assert np.count_nonzero(want) > len(want) // 4  # the grid does reach into the lobes
    assert_close(got, want, group=group, what="beckmann_D")


# ----------------------------------------------------------------------------- Eq. 3.4, 3.5, 4.9

def test_lobe_value_and_pdf_match_numpy(sweep):
    wi, wo, p, ks, group = sweep
    out = run("f = lobe_value(wi, wo, lobe); pdf = lobe_pdf(wi, wo, lobe);", {"f": 1, "pdf": 1},
              wi=wi, wo=wo, ks=ks, shape=p[:, :4])
    want_f = np.zeros(len(wi))
    want_p = np.zeros(len(wi))
    for kind, flag in KINDS.items():
        k = p[:, 4] == flag
        want_f[k] = B.lobe_value(wi[k], wo[k], p[k, 0], p[k, 1], p[k, 2], p[k, 3], kind)
        want_p[k] = B.lobe_pdf(wi[k], wo[k], p[k, 0], p[k, 1], kind)
    for kind, flag in KINDS.items():  # both kinds really are exercised, in and out of their lobes
        k = p[:, 4] == flag
        assert np.count_nonzero(want_f[k]) > k.sum() // 4 and np.count_nonzero(want_f[k] == 0) > k.sum() // 10
    assert_close(out["f"], want_f, group=group, atol=fresnel_allowance(wi, wo, p, want_f), what="lobe_value")
    assert_close(out["pdf"], want_p, group=group, what="lobe_pdf")


def test_exactly_horizontal_views_stay_finite_and_match(sweep):
    """wo.z = 0 exactly: the rows of the sweep that have it, checked on their own."""
    wi, wo, p, ks, group = sweep
    k = wo[:, 2] == 0.0
    assert k.sum() > 1000
    out = run("f = lobe_value(wi, wo, lobe);", {"f": 1}, wi=wi[k], wo=wo[k], ks=ks[k], shape=p[k, :4])
    want = np.zeros(k.sum())
    for kind, flag in KINDS.items():
        j = p[k, 4] == flag
        want[j] = B.lobe_value(wi[k][j], wo[k][j], p[k][j, 0], p[k][j, 1], p[k][j, 2], p[k][j, 3], kind)
    assert np.count_nonzero(want) > 0
    assert_close(out["f"], want, group=group[k], atol=fresnel_allowance(wi[k], wo[k], p[k], want),
                 what="lobe_value at wo.z = 0")


# ----------------------------------------------------------------------------- Eq. 4.5-4.8

def sample_inputs():
    n = 16
    xi = f32(np.stack(np.meshgrid((np.arange(n) + 0.5) / n, np.arange(n) / n, indexing="ij"), -1).reshape(-1, 2))
    xi = np.concatenate([xi, f32([[0.0, 0.0], [0.0, 0.5], [1.0, 0.25], [1e-30, 0.9], [1.0, 1.0]])])
    rows = []
    for (mx, my), kind in itertools.product(ROUGHNESS, KINDS):
        for wo in views():
            rows.append(np.concatenate([xi, np.tile(np.r_[wo, mx, my, 0.04, 0.5, KINDS[kind]], (len(xi), 1))], 1))
    group = np.repeat(np.arange(len(rows)), len(xi))
    rows = f32(np.concatenate(rows))
    ks = np.concatenate([np.ones((len(rows), 3)), rows[:, 9:10]], axis=1)
    return rows[:, 0:2], rows[:, 2:5], rows[:, 5:9], ks, rows[:, 9], group


def test_sample_lobe_matches_numpy():
    xi, wo, shape, ks, kind, group = sample_inputs()
    out = run("wi = sample_lobe(wo, xi, lobe);", {"wi": 3}, xi=xi, wo=wo, ks=ks, shape=shape)
    # core/bsdf.py clamps xi1 at 1e-38, the GLSL at 2^-126 (a float32 normal): compare at the GLSL's clamp
    xi1 = np.maximum(xi[:, 0], np.float64(np.finfo(np.float32).tiny))
    want = np.zeros((len(xi), 3))
    for name, flag in KINDS.items():
        k = kind == flag
        want[k] = B.sample_lobe(wo[k], xi1[k], xi[k, 1], shape[k, 0], shape[k, 1], name)
    assert np.all(np.isfinite(out["wi"]))
    np.testing.assert_allclose(out["wi"], want, rtol=0, atol=RTOL)
    # the pdf of each GLSL sample, against numpy's pdf of that same float32 direction (in a second
    # run: within one shader the compiler may simplify (2 (wo.h) h - wo) + wo back to 2 (wo.h) h)
    wi32 = f32(out["wi"])
    got_p = run("pdf = lobe_pdf(wi, wo, lobe);", {"pdf": 1}, wi=wi32, wo=wo, ks=ks, shape=shape)["pdf"]
    want_p = np.zeros(len(xi))
    for name, flag in KINDS.items():
        k = kind == flag
        want_p[k] = B.lobe_pdf(wi32[k], wo[k], shape[k, 0], shape[k, 1], name)
    assert np.count_nonzero(want_p) > len(xi) // 2
    assert_close(got_p, want_p, group=group, what="lobe_pdf of samples")


def test_transmission_samples_lie_across_the_surface():
    """Eq. 4.8 then the thin-surface mirror: transmitted samples of a view above are below (wi.z <= 0)."""
    xi, wo, shape, ks, kind, _ = sample_inputs()
    k = (kind == KINDS["transmit"]) & (wo[:, 2] > 0.1) & (shape[:, 0] <= 0.01) & (shape[:, 1] <= 0.01)
    out = run("wi = sample_lobe(wo, xi, lobe);", {"wi": 3}, xi=xi[k], wo=wo[k], ks=ks[k], shape=shape[k])
    assert np.all(out["wi"][:, 2] < 0)
    # a narrow lobe's samples pass nearly straight through, wi ~ -wo: with m <= 0.01 even xi1 = 0
    # (-log(xi1) <= 87.4 in Eq. 4.6) gives theta_h <= atan(0.0935), wi at most 2 theta_h = 10.7 deg off
    assert np.all(np.sum(out["wi"] * -wo[k], axis=1) > np.cos(2 * np.arctan(0.0935)))


# ----------------------------------------------------------------------------- stability

def test_no_nan_or_inf_for_degenerate_inputs():
    """Zero vectors, wi = -wo, directions below both horizons, xi at 0 and 1, roughness 0 and 1e-6."""
    vecs = f32([[0, 0, 0], [0, 0, 1], [1, 0, 0], [0, 0, -1], [0.6, 0, 0.8], [-0.6, 0, 0.8], [-1, 0, 0],
                [1e-20, 0, 0], [0.6, 0.0, -0.8]])
    shapes = f32([[0, 0, 0, 0], [0, 0, 1, 1], [1e-6, 1, 0.5, 1], [1, 1, 1, 0], [1e-4, 1e-4, 0, 1], [1, 1e-2, 0.04, 0.5]])
    xis = f32([[0, 0], [1, 1], [0, 0.5], [1, 0.25], [0.5, 0.999999]])
    rows = np.array([np.r_[a, b, s, x, k] for a, b, s, x, k in
                     itertools.product(vecs, vecs, shapes, xis, (0.0, 1.0))])
    ks = np.concatenate([np.ones((len(rows), 3)), rows[:, -1:]], axis=1)
    out = run("f = lobe_value(wi, wo, lobe); pdf = lobe_pdf(wi, wo, lobe); s = sample_lobe(wo, xi, lobe);"
              "D = beckmann_D(wi, shape.x, shape.y);",
              {"f": 1, "pdf": 1, "s": 3, "D": 1},
              wi=rows[:, 0:3], wo=rows[:, 3:6], shape=rows[:, 6:10], xi=rows[:, 10:12], ks=ks)
    for name, values in out.items():
        assert np.all(np.isfinite(values)), name
        assert np.all(values >= 0) or name == "s", name
