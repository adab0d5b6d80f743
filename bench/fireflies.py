"""Fireflies in a scene's light maps (issue 25): the definitions tests/test_fireflies.py checks and
bench/measure_fireflies.py reports.

A texel is an outlier when its (denoised, stored) light-map value is more than OUTLIER x the median
of its 5 x 5 neighbourhood on the same chart (the texels of its object connected to it, path traced,
not dilated), and above FLOOR x the page's median (black corners are not fireflies). An outlier can be
real: the edge of a shadow, the mouth of a gap. So each outlier is traced again at its (moved) sample
point with CONVERGED paths: it is a firefly when its light-map value is more than FIREFLY x that
converged value.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from glint.bake.alpha import Coverage
from glint.bake.irradiance import compute_irradiance
from glint.bake.lightmap import LightmapPages, bake_lightmaps
from glint.bake.raytrace import RayTracer
from glint.bake.sample_points import adjust_samples
from glint.bake.settings import resolve_settings
from glint.bake.texels import rasterize_texels
from glint.bake.unwrap import unwrap
from glint.core.scene import Scene

OUTLIER = 4.0  # x the 5 x 5 median on the same chart
FLOOR = 0.05  # x the page's median: darker texels are not looked at
FIREFLY = 2.0  # x the converged value at the texel's sample point
CONVERGED = 4096  # paths of the converged value
CONVERGED_SEED = 12345  # not the bake's (0)


@dataclass(frozen=True)
class Outlier:
    page: int
    y: int
    x: int
    value: float  # the light map's luminance (mean of RGB)
    median: float  # of its 5 x 5 same-chart neighbourhood
    converged: float  # at its sample point, CONVERGED paths

    @property
    def firefly(self) -> bool:
        return self.value > FIREFLY * self.converged


@dataclass(frozen=True)
class FireflyCount:
    outliers: list[Outlier]  # of the front pages
    lightmaps: LightmapPages
    seconds: float  # the light-map stage, wall clock
    cpu_seconds: float  # the light-map stage, this process's CPU time (jobs = 1)
    lightmaps_samples: int  # the settings' paths per texel (before adaptive sampling)

    @property
    def fireflies(self) -> list[Outlier]:
        return [o for o in self.outliers if o.firefly]


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


def count_fireflies(scene: Scene, quality: str, **settings) -> FireflyCount:
    """The front pages' outliers of `scene` baked at `quality` (and `settings`, bake/settings.py), each
    with its converged value (module docstring); the light-map stage runs in this process (jobs 1)."""
    s = replace(resolve_settings(scene.bake_settings, quality=quality, **settings), jobs=1)
    atlas = unwrap(scene.objects, s.texels_per_metre, s.padding, s.max_page_size)
    pages = rasterize_texels(scene.objects, atlas)
    t0, c0 = time.perf_counter(), time.process_time()
    result = bake_lightmaps(scene, pages, s)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    tracer = RayTracer(scene)
    found = []
    for k, (page, image, baked) in enumerate(zip(pages, result.irradiance, result.baked)):
        hits = outliers(image, baked, page.object)
        if not hits:
            continue
        ys, xs = np.array([h[0] for h in hits]), np.array([h[1] for h in hits])
        normals = page.normal[ys, xs].astype(np.float64)
        moved = adjust_samples(tracer, page.position[ys, xs], normals, page.size[ys, xs], page.object[ys, xs],
                               Coverage(scene, tracer))
        E = compute_irradiance(scene, tracer, moved.points, normals, CONVERGED,
                               seed=CONVERGED_SEED).irradiance.mean(axis=1)
        found += [Outlier(k, *h, float(e)) for h, e in zip(hits, E)]
    return FireflyCount(found, result, seconds, cpu, s.samples)
