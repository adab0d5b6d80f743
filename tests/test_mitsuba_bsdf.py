"""bench/mitsuba_bsdf.py (the section 3.3 BSDF as a Mitsuba 3 plugin) against core/bsdf.py (numpy).

Everything runs in Mitsuba's scalar_rgb variant (CI has no usable LLVM). The plugin is evaluated
at real surface interactions: a ray hits a quad in the z = 0 plane whose vertex attributes carry a
tangent rotated by `angle` about +z and a bitangent sign, so the viewer's frame (t, b, n) is known
here and numpy's local directions follow from it independently of the plugin's frame code.
"""
from __future__ import annotations

import math

import mitsuba as mi  # noqa: E402  (the test extra installs it; CI has it)
import numpy as np
import pytest

from glint.bake.lights import LUMA
from glint.core import bsdf as ref
from glint.core.scene import Lobe


@pytest.fixture(scope="module")
def variant():
    mi.set_variant("scalar_rgb")
    from glint.bench import mitsuba_bsdf

    mitsuba_bsdf.register()
    return mitsuba_bsdf


_SCENES = []


def quad_interaction(angle: float, sign: float, back: bool = False):
    """A surface interaction on a unit quad at z = 0 (counter-clockwise seen from +z) whose tangent
    is (cos a, sin a, 0) and bitangent sign `sign`; hit from above, or from below when `back`.
    The scene is kept alive (in _SCENES): the interaction points into its mesh's attributes."""
    from glint.bench import mitsuba_bsdf

    mesh = mi.Mesh("quad", 4, 2, has_vertex_normals=True)
    params = mi.traverse(mesh)
    params["vertex_positions"] = type(params["vertex_positions"])([-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0])
    params["faces"] = type(params["faces"])([0, 1, 2, 0, 2, 3])
    params["vertex_normals"] = type(params["vertex_normals"])([0, 0, 1] * 4)
    params.update()
    mesh.add_attribute(mitsuba_bsdf.TANGENT, 3, type(params["vertex_normals"])([math.cos(angle), math.sin(angle), 0] * 4))
    mesh.add_attribute(mitsuba_bsdf.BITANGENT_SIGN, 1, type(params["vertex_normals"])([sign] * 4))
    scene = mi.load_dict({"type": "scene", "quad": mesh})
    _SCENES.append(scene)
    z = -1.0 if back else 1.0
    si = scene.ray_intersect(mi.Ray3f(mi.Point3f(0.1, 0.2, z), mi.Vector3f(0, 0, -z)))
    assert si.is_valid()
    frame = np.array([[math.cos(angle), math.sin(angle), 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    frame[1] = sign * np.cross(frame[2], frame[0])
    return si, frame


def random_lobes(rng, transmit: bool, m_range=(0.05, 1.0)) -> list[Lobe]:
    lo, hi = np.log10(m_range[0]), np.log10(m_range[1])
    lobes = []
    for kind in ("reflect", "transmit") if transmit else ("reflect", "reflect"):
        m = 10.0 ** rng.uniform(lo, hi)
        my = float(np.clip(m * rng.choice([1.0, 0.3, 3.0]), m_range[0], 1.0))  # anisotropy to 1:10
        lobes.append(Lobe(kind, tuple(rng.uniform(0.05, 1.0, 3)), m, my, rng.uniform(0, 1),
                          rng.choice([0.0, rng.uniform(0, 1), 1.0])))
    return lobes


def well_conditioned(l, v, kinds=("reflect", "transmit"), bound=0.1):
    """Where the half vectors of l and v that `kinds` use are well defined in float32: |l + v|
    (reflection) or |mirrored l + v| (transmission) cancels as it -> 0, and float32 rounding of
    the directions then moves h a lot."""
    ok = np.ones(len(l), bool)
    if "reflect" in kinds:
        ok &= np.linalg.norm(l + v, axis=-1) > bound
    if "transmit" in kinds:
        ok &= np.linalg.norm(l * np.array([1.0, 1.0, -1.0]) + v, axis=-1) > bound
    return ok


def unit(rng, n):
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def mixture_pdf(kd, lobes, l, v):
    """The pdf the plugin documents, from core/bsdf.py's numpy functions: components by luminance."""
    w = np.array([np.dot(kd, LUMA)] + [np.dot(lobe.ks, LUMA) for lobe in lobes])
    w = w / w.sum()
    same = (l[:, 2] >= 0) & (v[:, 2] >= 0)
    p = w[0] * np.where(same, np.maximum(l[:, 2], 0) / np.pi, 0.0)
    for wk, lobe in zip(w[1:], lobes):
        p = p + wk * ref.lobe_pdf(l, v, lobe.mx, lobe.my, lobe.kind)
    return p


def plugin(kd, lobes, two_sided=False):
    from glint.bench import mitsuba_bsdf

    return mi.load_dict({"type": mitsuba_bsdf.PLUGIN, "kd": {"type": "rgb", "value": list(map(float, kd))},
                         "lobes": mitsuba_bsdf.lobes_json(lobes), "two_sided": two_sided})


def evaluate(b, si, frame, l_local, v_local, flip=False):
    """Plugin eval / pdf for directions given in the viewer's frame (z flipped for a back side)."""
    to_world = frame.T * (np.array([1, 1, -1.0]) if flip else 1.0)
    ctx = mi.BSDFContext()
    f, p = np.zeros((len(l_local), 3)), np.zeros(len(l_local))
    for k in range(len(l_local)):
        si.wi = si.to_local(mi.Vector3f(to_world @ v_local[k]))
        value, pdf = b.eval_pdf(ctx, si, si.to_local(mi.Vector3f(to_world @ l_local[k])))
        f[k], p[k] = np.array(value), pdf
    return f, p


@pytest.mark.parametrize("case", range(8))
def test_eval_and_pdf_equal_numpy(variant, case):
    """Mitsuba's scalar_rgb is float32: 1e-4 relative where the half vectors are well conditioned,
    for lobes with m >= 0.05; near-mirror lobes (cases 6, 7: m 1e-3 .. 0.05) 1e-2 (the exponent of
    Eq. 3.3 amplifies float32 rounding of the directions by ~1/m). Near wi = -wo (a transmission
    lobe's peak) the reflection lobes' half vector is rounding noise: finite, not compared."""
    rng = np.random.default_rng(case)
    kd = rng.uniform(0, 1, 3)
    near_mirror = case >= 6
    lobes = random_lobes(rng, transmit=case % 2 == 1, m_range=(1e-3, 0.05) if near_mirror else (0.05, 1.0))
    back = case in (4, 5)  # a two-sided (transmissive or double-sided) material seen from below
    si, frame = quad_interaction(rng.uniform(0, 2 * np.pi), rng.choice([-1.0, 1.0]), back=back)
    b = plugin(kd, lobes, two_sided=back)
    n = 450
    v = unit(rng, n)
    v[:, 2] = np.abs(v[:, 2])
    l = unit(rng, n)  # a third uniform, a third near each lobe's peak, where the values are large
    for k, lobe in enumerate(lobes):
        rows = slice((k + 1) * n // 3, (k + 2) * n // 3)
        m = len(range(n)[rows])
        l[rows] = ref.sample_lobe(v[rows], rng.uniform(0, 1, m), rng.uniform(0, 1, m), lobe.mx, lobe.my, lobe.kind)
    l /= np.linalg.norm(l, axis=1, keepdims=True)
    f, p = evaluate(b, si, frame, l, v, flip=back)
    f_ref = ref.bsdf(l, v, kd, lobes) * np.abs(l[:, 2:3])
    p_ref = mixture_pdf(kd, lobes, l, v)
    assert np.all(np.isfinite(f)) and np.all(np.isfinite(p)) and f.min() >= 0 and p.min() >= 0
    # f: a reflection lobe is 0 below the horizon and a transmission lobe above it, so only the
    # half vector of the side l is on matters; the pdf sums every lobe's, wherever l is.
    good_f = np.where(l[:, 2] >= 0, well_conditioned(l, v, ("reflect",)), well_conditioned(l, v, ("transmit",)))
    good_p = well_conditioned(l, v, {lobe.kind for lobe in lobes})
    assert good_f.sum() > 0.8 * n and good_p.sum() > 0.3 * n
    rtol = 1e-2 if near_mirror else 1e-4
    for got, want, good in ((f, f_ref, good_f), (p[:, None], p_ref[:, None], good_p)):
        rel = (np.abs(got - want) / (np.abs(want) + 1e-7 * want.max())).max(axis=1)
        assert rel[good].max() < rtol, rel[good].max()


def test_one_sided_back_is_black(variant):
    rng = np.random.default_rng(7)
    kd, lobes = np.array([0.5, 0.5, 0.5]), random_lobes(rng, transmit=False)
    si, frame = quad_interaction(0.3, 1.0, back=True)
    v, l = unit(rng, 50), unit(rng, 50)
    v[:, 2], l[:, 2] = np.abs(v[:, 2]), np.abs(l[:, 2])
    f, p = evaluate(plugin(kd, lobes), si, frame, l, v, flip=True)
    assert not f.any() and not p.any()
    f2, _ = evaluate(plugin(kd, lobes, two_sided=True), si, frame, l, v, flip=True)
    assert np.allclose(f2, ref.bsdf(l, v, kd, lobes) * l[:, 2:3], rtol=1e-4, atol=1e-6)


def sample_many(b, si, frame, v_local, n, rng):
    ctx = mi.BSDFContext()
    si.wi = si.to_local(mi.Vector3f(frame.T @ v_local))
    out = []
    for _ in range(n):
        bs, weight = b.sample(ctx, si, float(rng.uniform()), mi.Point2f(*rng.uniform(0, 1, 2)))
        wo = np.array(si.to_world(bs.wo))
        out.append((frame @ wo, float(bs.pdf), np.array(weight)))
    return out


def test_sample_weight_is_eval_over_pdf(variant):
    rng = np.random.default_rng(11)
    kd = np.array([0.2, 0.3, 0.1])
    lobes = [Lobe("reflect", (0.6, 0.5, 0.4), 0.05, 0.2, 0.1, 0.3), Lobe("transmit", (0.3, 0.3, 0.3), 0.1, 0.1, 0.04, 0.0)]
    b = plugin(kd, lobes)
    si, frame = quad_interaction(1.1, -1.0)
    ctx = mi.BSDFContext()
    checked = 0
    for v in unit(rng, 40):
        v[2] = abs(v[2])
        for l, pdf, weight in sample_many(b, si, frame, v, 10, rng):
            if pdf == 0.0:
                assert not weight.any()
                continue
            value, p = b.eval_pdf(ctx, si, si.to_local(mi.Vector3f(frame.T @ l)))
            rtol = 2e-3 if well_conditioned(l[None], v[None])[0] else 0.1  # see test_eval_and_pdf_equal_numpy
            assert p == pytest.approx(pdf, rel=rtol)
            assert np.allclose(weight, np.array(value) / p, rtol=rtol, atol=1e-6)
            checked += 1
    assert checked > 300


def numpy_samples(kd, lobes, v, n, rng):
    """The documented sampling procedure, from core/bsdf.py: (directions, valid)."""
    w = np.array([np.dot(kd, LUMA)] + [np.dot(lobe.ks, LUMA) for lobe in lobes])
    c = rng.choice(len(w), n, p=w / w.sum())
    x1, x2 = rng.uniform(size=n), rng.uniform(size=n)
    r, phi = np.sqrt(x1), 2 * np.pi * x2
    out = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - x1)], axis=1)  # cosine sampling
    valid = np.ones(n, bool)
    for k, lobe in enumerate(lobes, start=1):
        h = ref.sample_half_vector(x1, x2, lobe.mx, lobe.my)
        out[c == k] = ref.sample_lobe(v, x1, x2, lobe.mx, lobe.my, lobe.kind)[c == k]
        valid[c == k] = (h @ v > 0)[c == k]
    return out, valid


@pytest.mark.parametrize("view", [(0.5, 0.2, 0.8), (0.9, -0.3, 0.12)])
def test_sampling_matches_numpy_and_the_albedo(variant, view):
    """Histogram of the plugin's sampled directions against core/bsdf.py's sampling (two-sample
    chi-square over (cos theta, phi) bins), and the mean sample weight f cos / pdf against the
    directional albedo kd + sum ks x glint.core.bsdf.lobe_albedo (numpy QMC), which holds only if the pdf
    is the density the samples have. At the grazing view many lobe samples have wo.h <= 0 and must
    be dropped. (The pdf's quadrature over bins is no reference here: it has an integrable
    singularity at wi = -wo.)"""
    from scipy import stats

    rng = np.random.default_rng(3)
    kd = np.array([0.3, 0.3, 0.3])
    lobes = [Lobe("reflect", (0.5, 0.5, 0.5), 0.15, 0.4, 0.3, 0.2), Lobe("transmit", (0.4, 0.4, 0.4), 0.3, 0.3, 0.1, 0.0)]
    b = plugin(kd, lobes)
    si, frame = quad_interaction(0.4, 1.0)
    v = np.array(view)
    v /= np.linalg.norm(v)
    n = 6000
    samples = sample_many(b, si, frame, v, n, rng)
    weights = np.array([s[2] for s in samples])
    albedo = kd + sum(np.asarray(lobe.ks) * float(ref.lobe_albedo(v, lobe.mx, lobe.my, lobe.r0, lobe.alpha, lobe.kind))
                      for lobe in lobes)
    mean, err = weights.mean(axis=0), weights.std(axis=0) / math.sqrt(n)
    assert np.all(np.abs(mean - albedo) < 4 * err + 1e-3), (mean, albedo, err)

    def histogram(d, valid, nc=10, nphi=12):
        d = d[valid]
        ci = np.clip(((d[:, 2] + 1) / 2 * nc).astype(int), 0, nc - 1)
        pj = np.clip(((np.arctan2(d[:, 1], d[:, 0]) % (2 * np.pi)) / (2 * np.pi) * nphi).astype(int), 0, nphi - 1)
        return np.bincount(ci * nphi + pj, minlength=nc * nphi).astype(float)

    n2 = 200_000
    ours = histogram(np.array([s[0] for s in samples]), np.array([s[1] > 0 for s in samples]))
    theirs = histogram(*numpy_samples(kd, lobes, v, n2, rng))
    keep = ours + theirs >= 10
    k1, k2 = math.sqrt(n2 / n), math.sqrt(n / n2)
    chi2 = (((k1 * ours[keep] - k2 * theirs[keep]) ** 2) / (ours[keep] + theirs[keep])).sum()
    assert stats.chi2.sf(chi2, keep.sum() - 1) > 1e-3, (chi2, keep.sum())
