"""The bake's one GPU stage: render the cube maps that glint.bake.cubemap planned.

Reads the bake directory written so far (manifest, meshes, light maps) and writes
`cubemaps/<object index>.exr` (format in bake/cubemap.py's docstring). It sits above
both the bake and the viewer because it needs the bake's plans and the viewer's renderer: the
bake's pipeline is handed `render_cubemaps` (glint.services.bake_scene does that), so the bake never
imports the renderer.
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Callable

import numpy as np

from glint.bake.cubemap import FACES, FAR_MARGIN, NEAR_PER_FAR, SKY_DISTANCE, SUPERSAMPLE, CubeMapPlan
from glint.core.bake_dir import Bake
from glint.core.image_io import write_image
from glint.viewer.camera import ViewCamera
from glint.viewer.context import headless_context
from glint.viewer.gl import describe
from glint.viewer.renderer import Renderer


def diffuse_view(manifest: dict) -> dict:
    """The manifest as the cube-map renders see it: no lobes, no cube maps (bake/cubemap.py: the
    light-mapped scene, rendered diffuse)."""
    return {**manifest, "materials": [{**m, "lobes": []} for m in manifest["materials"]],
            "objects": [{**o, "cubemap": None} for o in manifest["objects"]]}


def render_cubemaps(bake_dir: Path, plans: list[CubeMapPlan],
                    progress: Callable[[], None] | None = None) -> dict:
    """Render `plans` from the bake in `bake_dir` (manifest, meshes and light maps written) into
    its cubemaps/ folder; returns statistics (seconds, device)."""
    t0 = time.perf_counter()
    bake = Bake(bake_dir)
    bake.manifest = diffuse_view(bake.manifest)
    ctx = headless_context()
    try:
        with Renderer(ctx, bake, supersample=SUPERSAMPLE) as renderer:
            lo, hi = renderer.scene.bounds
            for plan in plans:
                # far enough for the farthest corner of the scene, seen from the centre
                far = float(np.linalg.norm(np.maximum(np.abs(lo - plan.centre), np.abs(hi - plan.centre))))
                faces = render_faces(renderer, plan.centre, plan.size, plan.hidden, far=max(far, 1e-9))
                write_cubemap(Path(bake_dir) / plan.file, faces)
                if progress is not None:
                    progress()
        device = describe(ctx)
    finally:
        ctx.release()
    return {"seconds": round(time.perf_counter() - t0, 3), "device": device}


def render_faces(renderer, centre, size: int, hidden=(), *, far: float) -> np.ndarray:
    """(6, S, S, 4) float32: radiance and distance of the six faces in GL order, row 0 at t = 0;
    `far`: the distance from the centre to the farthest point to show."""
    faces = np.zeros((6, size, size, 4), np.float32)
    for k, (_, forward, up) in enumerate(FACES):
        camera = ViewCamera(eye=centre, forward=forward, up=up, yfov=math.pi / 2,
                            znear=NEAR_PER_FAR * far, zfar=FAR_MARGIN * far)
        renderer.render(camera, size, size, hidden_objects=hidden)
        faces[k, ..., :3] = renderer.read_linear()[::-1]  # bottom row first: GL's t = 0
        distance = renderer.read_distance()[::-1]
        faces[k, ..., 3] = np.where(np.isfinite(distance), distance, SKY_DISTANCE)
    return faces


def write_cubemap(path: Path, faces: np.ndarray) -> str:
    """The six faces stacked vertically into one RGBA OpenEXR; returns "half" or "float"."""
    path.parent.mkdir(parents=True, exist_ok=True)
    size = faces.shape[1]
    return write_image(path, faces.reshape(6 * size, size, 4), channels=("R", "G", "B", "A"))
