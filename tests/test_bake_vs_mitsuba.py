"""The baked light maps of `cornell-box` against Mitsuba 3 (the bake's end-to-end accuracy).

At 50 points spread over every surface, away from edges and contacts, the light
map's bilinear look-up (what the viewer's texture unit does) is compared with
Mitsuba 3's irradiance at the same point (bench/mitsuba_reference.py explains
the method). Per point, the relative L1 error over RGB |E_bake - E_mitsuba|_1 / |E_mitsuba|_1:
its mean at most 3 %, its largest value at most 12 %; and the signed relative error
sum_c (E_bake - E_mitsuba)_c / |E_mitsuba|_1, whose mean over the points (a bias common to
every point, e.g. a wrong scale of the light maps) must lie within +-1.2 %.

Deliberate bug this catches (tried): irradiance scaled by 1.02 in the light-map read
(core/bake_dir.py `Bake.irradiance`) moves the signed mean from +0.31 % to +2.32 % and fails
the 1.2 % bound, where the mean |error| (1.60 % -> 2.80 %, bound 3 %) and the max (7.3 % ->
8.4 %, bound 12 %) alone let it pass. A scale of 0.98 fails too (signed mean -1.69 %).
"""
from __future__ import annotations

import numpy as np
import pytest

from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.bench.mitsuba_reference import MARGIN, POINTS, cornell_box_irradiance, sample_points
from glint.core.bake_dir import Bake
from glint.scenes import builtin_path
from glint.services import bake_scene

# The quality this test bakes at; the `final` figure is measured by bench/measure_bake.py (docs/BAKE.md).
TEST_SETTINGS = {"quality": "preview", "samples": 256, "texels_per_metre": 16.0}


@pytest.mark.slow
def test_cornell_box_irradiance_matches_mitsuba(tmp_path):
    """Deliberate bug this catches (tried, never committed; the module docstring has the
    figures): the light maps' irradiance x1.02 (or x0.98), through the signed-mean bound."""
    scene = load_scene(builtin_path("cornell-box"))
    settings = resolve_settings(scene.bake_settings, **TEST_SETTINGS)
    bake_scene(scene, settings, tmp_path / "cb.bake", progress=False)
    bake = Bake(tmp_path / "cb.bake")

    chosen, surfaces = sample_points(scene, POINTS, MARGIN)
    assert len(chosen) == POINTS
    assert surfaces >= 7  # 5 walls + the two boxes (their visible faces)

    ours = np.zeros((POINTS, 3))
    for k, (obj, tri, bary, _, _) in enumerate(chosen):
        ours[k] = bake.irradiance(obj, np.array([tri]), bary[None])[0]
    points = np.array([c[3] for c in chosen])
    normals = np.array([c[4] for c in chosen])
    reference = cornell_box_irradiance(points, normals, spp=16384)

    assert np.all(reference.sum(axis=1) > 0.05), "a test point is in the dark: the point selection is wrong"
    rel = np.abs(ours - reference).sum(axis=1) / reference.sum(axis=1)
    signed = (ours - reference).sum(axis=1) / reference.sum(axis=1)
    bias, standard_error = signed.mean(), signed.std(ddof=1) / np.sqrt(POINTS)
    print(f"mean relative error {rel.mean():.4f}, max {rel.max():.4f}, "
          f"signed mean {bias:+.4f} +- {standard_error:.4f} (standard error)")
    assert rel.mean() <= 0.03
    assert rel.max() <= 0.12
    # The bias. Measured noise: the signed mean's standard error over the 50 points is 0.003
    # (the bake's 256 samples per texel, denoised, dominate; the reference's 16384 spp add
    # +-0.0013 per point), and bakes with seeds 0..5 gave +0.31, +0.47, -0.28, +0.21, +0.51,
    # +0.28 % (spread 0.3 %, the same). So the true bake sits at +0.3 % +- 0.3 %, and a 2 %
    # scale error at ~+2.3 %: 1.2 % lies 3 standard errors from each. Tighter would flake with
    # another seed; looser would let a 2 % scale through.
    assert abs(bias) <= 0.012, f"signed mean relative error {bias:+.4f}: the light maps are biased"
