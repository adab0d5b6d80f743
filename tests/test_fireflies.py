"""No fireflies in the light maps: texels far brighter than their neighbourhood that the converged
irradiance at their own sample point does not explain (issue 25).

A texel is an outlier when its (denoised, stored) light-map value is more than 4 x the median of its
5 x 5 neighbourhood on the same chart (the texels of its object connected to it, path traced, not
dilated), and above 5 % of the page's median (black corners are not fireflies). An outlier can be
real: the edge of a shadow, the mouth of a 1 mm gap that light enters from one end (the skirting
board's back face in tests/seam_scenes.py's interior), a book's side at the front of a shelf. So each
outlier is traced again at its sample point with 4096 paths: it is a firefly when its light-map
value is more than twice that converged value (a few of its paths found a narrow gap or a caustic
with a huge weight). Where the bright texels of issue 25 came from (samples on chart borders'
edges and inside covering meshes) is tests/test_seams.py's.

Scenes: the interior and cornell-box at preview; metal-floor-room (polished metal floor, the
caustic case) at draft.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

import seam_scenes as S
from glint.bake.gltf_loader import load_scene
from glint.bake.irradiance import compute_irradiance
from glint.bake.lightmap import bake_lightmaps
from glint.bake.raytrace import RayTracer
from glint.bake.sample_points import adjust_samples
from glint.bake.settings import resolve_settings
from glint.bake.texels import rasterize_texels
from glint.bake.unwrap import unwrap
from glint.scenes import builtin_path

OUTLIER = 4.0  # x the 5 x 5 median on the same chart
FLOOR = 0.05  # x the page's median: darker texels are not looked at
FIREFLY = 2.0  # x the converged value at the texel's sample point
CONVERGED = 4096


def outliers(image: np.ndarray, baked: np.ndarray, objects: np.ndarray) -> list[tuple[int, int, float, float]]:
    """(y, x, value, median) of the texels of one page over OUTLIER x their 5 x 5 same-chart median."""
    lum = image[..., :3].mean(axis=2)
    lit = lum[baked]
    if not lit.size or not (lit > 0).any():
        return []
    floor = FLOOR * float(np.median(lit[lit > 0]))
    charts = np.zeros(objects.shape, np.int64)
    for k in np.unique(objects[objects >= 0]):
        label, count = ndimage.label(objects == k, structure=np.ones((3, 3)))
        charts[label > 0] = label[label > 0] + charts.max()
    out = []
    H, W = lum.shape
    for y, x in zip(*np.nonzero(baked & (lum > floor))):
        y0, y1, x0, x1 = max(y - 2, 0), min(y + 3, H), max(x - 2, 0), min(x + 3, W)
        same = (charts[y0:y1, x0:x1] == charts[y, x]) & baked[y0:y1, x0:x1]
        median = float(np.median(lum[y0:y1, x0:x1][same]))
        if lum[y, x] > OUTLIER * median:
            out.append((int(y), int(x), float(lum[y, x]), median))
    return out


def fireflies(scene, quality: str, **settings):
    """(outliers, fireflies): the front pages' outliers and, of them, those whose value is over FIREFLY x
    the converged irradiance at their (moved) sample point, as (y, x, value, median, converged)."""
    s = resolve_settings(scene.bake_settings, quality=quality, **settings)
    atlas = unwrap(scene.objects, s.texels_per_metre, s.padding, s.max_page_size)
    pages = rasterize_texels(scene.objects, atlas)
    result = bake_lightmaps(scene, pages, replace(s, jobs=1))
    tracer = RayTracer(scene)
    found, bad = [], []
    for page, image, baked in zip(pages, result.irradiance, result.baked):
        hits = outliers(image, baked, page.object)
        if not hits:
            continue
        ys, xs = np.array([h[0] for h in hits]), np.array([h[1] for h in hits])
        normals = page.normal[ys, xs].astype(np.float64)
        moved = adjust_samples(tracer, page.position[ys, xs], normals, page.size[ys, xs], page.object[ys, xs])
        E = compute_irradiance(scene, tracer, moved.points, normals, CONVERGED, seed=12345).irradiance.mean(axis=1)
        found += hits
        bad += [(*h, float(e)) for h, e in zip(hits, E) if h[2] > FIREFLY * e]
    return found, bad


@pytest.mark.slow
@pytest.mark.parametrize("name", ["interior", "cornell-box", "metal-floor-room"])
def test_no_fireflies(tmp_path: Path, name):
    """Measured (this build): no outlier at all in the three (before bake/sample_points.py's sliver
    rule, the interior had 11, two of them fireflies: 0.057 and 0.052 against converged 0.028 and
    0.025, on the skirting board's back face in its 1 mm gap).

    Bug this catches (tried): the sliver rule off (bake/sample_points.py SLIVER = 0) fails the
    interior with those two fireflies. (Path regularisation off, scatter.py M_REGULARISE = 1e-4, does
    not make fireflies in metal-floor-room at draft: its lamp is an area light, found by next-event
    estimation with MIS.)"""
    if name == "interior":
        scene, quality = load_scene(S.write_interior(tmp_path / "interior.glb")), "preview"
    else:
        scene, quality = load_scene(builtin_path(name)), "draft" if name == "metal-floor-room" else "preview"
    found, bad = fireflies(scene, quality)
    print(f"{name}: {len(found)} outliers, {len(bad)} fireflies", bad[:10])
    assert not bad
