"""Frame time while a material is being edited in `glint view`, against frame time without edits.

    python3 -m glint.bench.measure_editing [--scene living-room] [--material "Sofa fabric"] [--size 640x360]
                                           [--frames 20] [--quality draft] [--out DIR]

The renderer of the window (viewer/renderer.py, mode "auto", supersample 1) at the scene's first
camera, three ways, each --frames frames after two warm-up frames:

- "walking": the camera moves a little every frame (every frame a walkthrough frame: what a user
  walking through the scene gets, with no edit);
- "still": the camera stands still (the refinement's still-camera frames);
- "editing": the camera stands still and every frame changes the material's kd and its first
  lobe's m (a slider being dragged): `Renderer.set_material` (the material, lobe and pattern
  tables re-uploaded) and then a walkthrough frame of the new material.

Printed per way: the median wall time of set_material + render() + glFinish (ms), and of the
passes' times summed (viewer/timing.py: glFinish-bracketed on llvmpipe, timer queries on a GPU),
and the median of set_material alone. The bake is made in DIR (default: a temporary folder) at
--quality.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from statistics import median

import numpy as np

from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.core.bake_dir import Bake
from glint.core.manifest import Material
from glint.scenes import resolve
from glint.services import bake_scene, parse_size
from glint.viewer.camera import ViewCamera
from glint.viewer.context import headless_context
from glint.viewer.renderer import Renderer


def measure(renderer: Renderer, camera: ViewCamera, size, frames: int, way: str, material: int) -> dict:
    entry = Material.from_json(renderer.scene.materials[material])  # the GPU scene keeps manifest entries
    wall, passes, edit = [], [], []
    for k in range(frames + 2):
        view = camera
        if way == "walking":  # a step of 1 mm per frame: a new view, a walkthrough frame
            view = ViewCamera(camera.eye + np.array([0.001 * k, 0, 0]), camera.forward, camera.up, camera.yfov,
                              camera.znear, camera.zfar)
        start = time.perf_counter()
        if way == "editing":
            t = k / max(frames, 1)
            lobes = list(entry.lobes)
            if lobes:
                lobes[0] = replace(lobes[0], mx=0.05 + 0.2 * t, my=0.05 + 0.2 * t)
            renderer.set_material(material, replace(entry, kd=[0.2 + 0.5 * t, 0.3, 0.4], lobes=lobes))
            edit.append((time.perf_counter() - start) * 1e3)
        renderer.render(view, *size, mode="auto")
        renderer.ctx.finish()
        if k >= 2:
            wall.append((time.perf_counter() - start) * 1e3)
            passes.append(sum(v for key, v in renderer.timer.last_ms.items() if key != "total"))
    return {"way": way, "frame_wall_ms": round(median(wall), 2), "passes_ms": round(median(passes), 2),
            "set_material_ms": round(median(edit[2:]), 3) if edit else None, "mode": renderer.mode}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scene", default="living-room")
    parser.add_argument("--material", default="Sofa fabric", help="the material edited (name)")
    parser.add_argument("--size", default="640x360")
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--quality", default="draft")
    parser.add_argument("--out", type=Path, default=None, help="folder for the bake (default: temporary)")
    args = parser.parse_args()
    size = parse_size(args.size)
    out = args.out or Path(tempfile.mkdtemp(prefix="glint-editing-"))
    scene_file = Path(resolve(args.scene))
    scene = load_scene(scene_file)
    report = bake_scene(scene, resolve_settings(scene.bake_settings, quality=args.quality),
                        out / f"{scene_file.stem}.bake", progress=False)
    bake = Bake(report.bake_dir)
    model = bake.model
    names = [m.name for m in model.materials]
    if args.material not in names:
        raise SystemExit(f"no material {args.material!r}; the scene has {', '.join(names)}")
    if not model.cameras:
        raise SystemExit(f"{args.scene} has no camera")
    camera = ViewCamera.from_manifest(model.cameras[0])
    ctx = headless_context()
    results = []
    for way in ("walking", "still", "editing"):
        with Renderer(ctx, bake, blend_frames=4, max_frames=512) as renderer:
            results.append(measure(renderer, camera, size, args.frames, way, names.index(args.material)))
        print(json.dumps(results[-1]), flush=True)


if __name__ == "__main__":
    main()
