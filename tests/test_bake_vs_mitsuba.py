"""The baked light maps of `cornell-box` against Mitsuba 3 (the bake's end-to-end accuracy).

At 50 points spread over every surface, away from edges and contacts, the light
map's bilinear look-up (what the viewer's texture unit does) is compared with
Mitsuba 3's irradiance at the same point (bench/mitsuba_reference.py explains
the method). Metric: mean over points of |E_bake - E_mitsuba|_1 / |E_mitsuba|_1
(L1 over RGB), at most 3 %.
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
    print(f"mean relative error {rel.mean():.4f}, max {rel.max():.4f}")
    assert rel.mean() <= 0.03
    assert rel.max() <= 0.12
