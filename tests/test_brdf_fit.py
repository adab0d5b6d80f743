"""bake/brdf_fit.py: fits recover known materials, and their albedo, within stated tolerances.

Expected values are the parameters the data was made from; the albedo is compared with core/bsdf.py's
`lobe_albedo` (its own importance-sampled estimate, not the fitter's quadrature).

Tolerances: kd within 0.01, ks within 3 %, m within 3 %, r0 within 0.01, alpha within 0.03, and the
directional albedo within 2 % at view angles 0-80 degrees (issue 24 asks for 3 %). The MERL file is
read through its nearest-bin lookup, which shifts ks and alpha slightly (ks 0.790, alpha 0.302 for
0.8, 0.3) while the albedo stays within 0.3 %.

Deliberate bugs tried: a fitter stuck in a local minimum (LEVELS = 1: the hierarchical search stops
at its first 9^3 grid) fails `test_merl_file_fits_back_to_its_lobe` (kd 0.237 against 0.2 +- 0.01); the
refinement box centred on the first grid point instead of the best one fails it too (kd 0.235); a
Schlick term (1 - u)^4 in the search's fast path fails `test_fit_albedo_agrees_with_the_reference_bsdf`
(error 7.5e-5 against the limit 1e-5) and the fit-back test.
"""
from __future__ import annotations

import numpy as np
import pytest

from glint.bake import brdf_fit, merl
from glint.core import bsdf
from glint.core.errors import GlintError
from glint.core.scene import Lobe

KNOWN = Lobe(ks=(0.8, 0.8, 0.8), mx=0.1, my=0.1, r0=0.05, alpha=0.3)
KD = (0.2, 0.2, 0.2)


def true_albedo(kd, lobes, theta_o):
    wo = np.stack([np.sin(theta_o), 0 * theta_o, np.cos(theta_o)], axis=-1)
    total = np.zeros((len(theta_o), 3)) + np.asarray(kd, float)
    for lobe in lobes:
        total += np.asarray(lobe.ks) * bsdf.lobe_albedo(wo, lobe.mx, lobe.my, lobe.r0, lobe.alpha, lobe.kind)[:, None]
    return total


def check_albedo(result, kd, lobes, limit=0.02):
    theta = np.radians(np.arange(0.0, 81.0, 5.0))
    want, got = true_albedo(kd, lobes, theta), true_albedo(result.kd, result.lobes, theta)
    rel = np.abs(got / want - 1)
    assert rel.max() < limit, np.round(rel, 4)


def check_lobe(lobe, want, ks_rel=0.03):
    assert lobe.kind == want.kind
    np.testing.assert_allclose(lobe.ks, want.ks, rtol=ks_rel)
    assert abs(lobe.mx / want.mx - 1) < 0.03 and lobe.mx == lobe.my, lobe
    assert abs(lobe.r0 - want.r0) < 0.01, lobe
    assert abs(lobe.alpha - want.alpha) < 0.03, lobe


@pytest.fixture(scope="module")
def merl_data(tmp_path_factory):
    path = tmp_path_factory.mktemp("merl") / "known.binary"
    merl.write_merl(path, lambda wi, wo: bsdf.bsdf(wi, wo, KD, [KNOWN]))
    return brdf_fit.BrdfData.from_function(merl.read_brdf_file(path).evaluate)


def test_merl_file_fits_back_to_its_lobe(merl_data):
    result = brdf_fit.fit(merl_data, 1, method="hierarchical")  # the thesis' search; multistart below
    np.testing.assert_allclose(result.kd, KD, atol=0.01)
    assert len(result.lobes) == 1
    check_lobe(result.lobes[0], KNOWN)
    check_albedo(result, KD, [KNOWN])
    assert result.albedo_error < 0.02


def test_coloured_material_by_multistart():
    """RGB kd and ks, a narrow lobe whose alpha makes the albedo rise at grazing angles; a callable."""
    kd, lobe = (0.3, 0.1, 0.05), Lobe(ks=(0.9, 0.6, 0.3), mx=0.05, my=0.05, r0=0.3, alpha=0.6)
    data = brdf_fit.BrdfData.from_function(lambda wi, wo: bsdf.bsdf(wi, wo, kd, [lobe]))
    result = brdf_fit.fit(data, 1, method="multistart")
    np.testing.assert_allclose(result.kd, kd, atol=0.01)
    check_lobe(result.lobes[0], lobe)
    check_albedo(result, kd, [lobe])


def test_fit_albedo_agrees_with_the_reference_bsdf(merl_data):
    """The fit's own albedo (core/bsdf.py on the data's samples) matches the data: the fast path the search
    uses and core/bsdf.py compute the same lobe."""
    result = brdf_fit.fit(merl_data, 1, method="multistart")
    assert result.error < 1e-5
    assert result.albedo_error < 0.005


def test_quadrature_integrates_a_lambertian_and_a_lobe():
    theta_o, wo, wi, weight = brdf_fit.quadrature()
    np.testing.assert_allclose(weight.sum(axis=1) / np.pi, 1.0, atol=0.005)  # int cos / pi = 1
    f = bsdf.reflect_lobe(wi, np.broadcast_to(wo[:, None], wi.shape), 0.05, 0.05, 0.1, 0.4)
    np.testing.assert_allclose((f * weight).sum(axis=1)[:17],
                               bsdf.lobe_albedo(wo, 0.05, 0.05, 0.1, 0.4, "reflect")[:17], rtol=0.002)


def test_missing_data_and_bad_arguments_are_one_line():
    with pytest.raises(GlintError, match="no valid"):
        brdf_fit.BrdfData.from_function(lambda wi, wo: -np.ones(wi.shape))
    with pytest.raises(GlintError, match="RGB values of shape"):
        brdf_fit.BrdfData.from_function(lambda wi, wo: np.ones(wi.shape[:-1]))
    data = brdf_fit.BrdfData.from_function(lambda wi, wo: np.full(wi.shape, 0.1))
    with pytest.raises(GlintError, match="--lobes must be 1 or 2"):
        brdf_fit.fit(data, 3)
    result = brdf_fit.fit(data, 1, method="multistart")  # a Lambertian: kd, no lobe worth keeping
    np.testing.assert_allclose(result.kd, 0.1 * np.pi, rtol=0.01)
    assert all(np.isfinite(result.albedo_fit).ravel())
