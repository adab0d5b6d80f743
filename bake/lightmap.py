"""Light-map stage: texel samples -> irradiance by path tracing -> invalid texels -> dilation -> denoise.

Stores irradiance E, not radiance, so kd can still change at run time:
diffuse radiance = kd / pi * E (Eq. 4.1).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glint.bake.alpha import cut_out_texels
from glint.bake.denoise import denoise_lightmap
from glint.bake.dilate import dilate
from glint.bake.executor import LocalExecutor
from glint.bake.irradiance import compute_irradiance
from glint.bake.raytrace import RayTracer
from glint.bake.texels import TexelPage
from glint.core.scene import Scene

TILE = 2048  # texels per job: small enough for a smooth progress bar, big enough to amortise numpy


@dataclass
class LightmapPages:
    irradiance: list[np.ndarray]  # (H, W, 3) float32 per page, dilated (and denoised)
    baked: list[np.ndarray]  # (H, W) bool: texels whose value was path traced (not dilated in)
    texels: int  # texels path traced
    invalid: int  # of them, invalidated for seeing back faces
    rays: int


def _setup(scene: Scene) -> tuple[Scene, RayTracer]:
    return scene, RayTracer(scene)


def _job(state, task):
    scene, tracer = state
    points, normals, first, samples, seed, max_depth = task
    result = compute_irradiance(scene, tracer, points, normals, samples, seed=seed,
                                max_depth=max_depth, first_index=first)
    return result.irradiance, result.backface, result.rays


def bake_lightmaps(scene: Scene, pages: list[TexelPage], settings, progress=None) -> LightmapPages:
    # Texels in the cut-out parts of MASK materials are never seen: not traced, left to dilation.
    covered = [(p.object >= 0) & ~_cut_out(scene, p) for p in pages]
    points = np.concatenate([p.position[c] for p, c in zip(pages, covered)])
    normals = np.concatenate([p.normal[c] for p, c in zip(pages, covered)])
    n = len(points)
    tasks = [(points[i:i + TILE], normals[i:i + TILE], i, settings.samples, settings.seed, settings.max_depth)
             for i in range(0, n, TILE)]
    E = np.zeros((n, 3), np.float32)
    backface = np.zeros(n, np.float32)
    rays = 0
    for index, (e, b, r) in LocalExecutor(settings.workers).run(_setup, (scene,), _job, tasks):
        start = index * TILE
        E[start:start + len(e)] = e
        backface[start:start + len(b)] = b
        rays += r
        if progress is not None:
            progress(len(e))
    valid = backface <= settings.backface_threshold

    irradiance, baked = [], []
    offset = 0
    for page, cover in zip(pages, covered):
        count = int(cover.sum())
        image = np.zeros(page.object.shape + (3,), np.float32)
        mask = np.zeros(page.object.shape, bool)
        image[cover] = E[offset:offset + count]
        mask[cover] = valid[offset:offset + count]
        offset += count
        image = _fill(image, mask, settings)
        irradiance.append(image)
        baked.append(mask)
    return LightmapPages(irradiance, baked, n, int((~valid).sum()), rays)


def _cut_out(scene: Scene, page: TexelPage) -> np.ndarray:
    out = np.zeros(page.object.shape, bool)
    if page.texcoord is None or not any(m.alpha_mode == "MASK" for m in scene.materials):
        return out
    where = np.nonzero(page.object >= 0)
    out[where] = cut_out_texels(scene, page.object[where], page.texcoord[where].astype(np.float64))
    return out


def _fill(image: np.ndarray, valid: np.ndarray, settings) -> np.ndarray:
    """Dilate into invalid and empty texels, then denoise, then restore what dilation owns.

    Dilating first gives the denoiser no black chart borders to bleed in.
    """
    grow = settings.padding + 2
    image = dilate(image, valid, grow)
    if settings.denoise and valid.any():
        image = dilate(np.where(valid[..., None], denoise_lightmap(image), 0.0), valid, grow)
    return np.ascontiguousarray(image, dtype=np.float32)
