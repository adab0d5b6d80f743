"""Measures the figures of docs/VIEWER.md "Material edits: the background re-bake": how soon the
light maps reflect a material edit in `glint view`, how the converged re-bake compares with
`glint bake --force` of the edited sidecar, and the frame time while the re-bake runs.

    python3 -m glint.bench.measure_rebake [--quality preview] [--size 640x360] [--json out.json]

The living room (a copy, so its sidecar can be edited) is baked at --quality; then, for each
edit (the sofa's kd; the ceiling lights' emission, their shared material "Light diffuser"):
a `Rebaker` (bake/rebake.py) re-bakes while a headless renderer draws walkthrough frames of the
scene's camera tour at --size, as the window does (polling the re-bake each frame and swapping
its pages in); printed are the seconds from the edit to each pass's pages (worker clock: the
edit's time to the pass's end), the frame times before and during the re-bake (wall clock per
frame, glFinish after each) and the largest frame. The cube maps follow (the worker renders the
probes again after the first and the last pass, glint/cubemap_stage.py ProbeRefresher): printed
are the seconds from the edit to each refresh's last probe and the milliseconds the renderer took
to take them in (Renderer.replace_probes). Then the sidecar gets the edit, `glint bake --force`
bakes it, and its light maps and cube maps are compared with the last pass's (rounded to half
float, as the EXR stores them).
"""
from __future__ import annotations

import argparse
import json
import platform
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from glint.bake.gltf_loader import load_scene
from glint.bake.rebake import NICE, Rebaker
from glint.bake.settings import resolve_settings
from glint.core.atomic import atomic_write_text
from glint.core.bake_dir import Bake
from glint.cubemap_stage import ProbeRefresher
from glint.scenes import builtin_path
from glint.services import bake_scene, parse_size
from glint.viewer.camera import camera_path_at
from glint.viewer.context import headless_context
from glint.viewer.cubemaps import mip_chain, read_cubemap
from glint.viewer.gl import describe
from glint.viewer.renderer import Renderer

SCENE = "living-room"
EDITS = {  # name: (material, key, value)
    "sofa kd": ("Sofa fabric", "kd", [0.6, 0.12, 0.08]),
    "ceiling lights' emission": ("Light diffuser", "emission", [32.0, 22.0, 12.0]),
}
IDLE_FRAMES = 40


def bake(path: Path, quality: str) -> tuple[Bake, float]:
    scene = load_scene(path)
    report = bake_scene(scene, resolve_settings(scene.bake_settings, quality=quality), path.with_suffix(".bake"),
                        force=True, progress=False)
    return Bake(report.bake_dir), report.model.statistics.lightmaps["seconds"]


def tour(model):
    path = model.camera_paths[0]
    return lambda t: camera_path_at(path, t)


def frame_ms(renderer: Renderer, camera, size) -> float:
    start = time.perf_counter()
    renderer.render(camera, *size, mode="walkthrough")
    renderer.ctx.finish()
    return (time.perf_counter() - start) * 1e3


def measure_edit(renderer: Renderer | None, base: Bake, scene_path: Path, size, material: str, key: str, value,
                 nice: int) -> dict:
    """One edit's re-bake; with a `renderer`, walkthrough frames drawn back to back meanwhile."""
    materials = [m.to_json() for m in base.model.materials]  # the re-bake takes material entries (JSON)
    next(m for m in materials if m["name"] == material)[key] = value
    at = tour(base.model)
    with Rebaker(scene_path, base.path, nice=nice, probes=ProbeRefresher) as rebaker:
        while rebaker.ready is None:  # the worker has loaded the scene, as it has long before a user's first edit
            rebaker.poll()
            time.sleep(0.05)
        idle = [frame_ms(renderer, at(0.1 * k), size) for k in range(IDLE_FRAMES)] if renderer else [0.0]
        rebaker.edit(materials)
        busy, passes, swaps, probe_swaps, refreshes, probes, t = [], [], [], [], [], {}, 0.0
        final = len(rebaker.schedule) - 1
        while not (passes and passes[-1].final and refreshes and refreshes[-1][0] == final):
            t += 0.05
            pages = rebaker.poll()
            new_probes = rebaker.poll_probes()
            if pages is not None:
                passes.append(rebaker.last)
                if renderer is not None:
                    start = time.perf_counter()
                    renderer.replace_lightmaps(*pages)
                    swaps.append((time.perf_counter() - start) * 1e3)
            if new_probes:
                probes.update(new_probes)
                if renderer is not None:
                    start = time.perf_counter()
                    renderer.replace_probes(new_probes)
                    probe_swaps.append((time.perf_counter() - start) * 1e3)
            if rebaker.probes_done is not None and (not refreshes or refreshes[-1] != rebaker.probes_done):
                refreshes.append(rebaker.probes_done)
            if rebaker.error or rebaker.probe_error:
                raise SystemExit(rebaker.error or rebaker.probe_error)
            if renderer is not None:
                busy.append(frame_ms(renderer, at(t), size))
            else:
                time.sleep(0.02)
        ready = rebaker.ready
    row = {"edit": f"materials.\"{material}\".{key} = {value}", "frames_drawn_meanwhile": renderer is not None,
           "worker_nice": nice, "worker_setup_seconds": round(ready["seconds"], 2), "texels": ready["texels"],
           "passes": [{"samples": u.samples, "seconds_after_edit": round(u.seconds, 2)} for u in passes],
           "probes": ready["probes"],
           "probe_refreshes": [{"after_pass": k, "seconds_after_edit": round(sec, 2)} for k, sec in refreshes],
           "_last": passes[-1].front, "_probes": probes}
    if renderer is not None:
        row.update(swap_ms=[round(s, 2) for s in swaps], probe_swap_ms=[round(s, 2) for s in probe_swaps],
                   frame_ms_idle_median=round(float(np.median(idle)), 2),
                   frame_ms_during_rebake_median=round(float(np.median(busy)), 2),
                   frame_ms_during_rebake_max=round(float(np.max(busy)), 2), frames_during_rebake=len(busy))
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quality", default="preview")
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--edits", nargs="+", default=list(EDITS), choices=list(EDITS))
    ap.add_argument("--frames", action=argparse.BooleanOptionalAction, default=True,
                    help="draw walkthrough frames while re-baking (--no-frames: the re-bake alone)")
    ap.add_argument("--nice", type=int, default=NICE, help="the worker's niceness")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    size = parse_size(args.size)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        source = builtin_path(SCENE)
        scene_path = Path(tmp) / "base" / source.name
        scene_path.parent.mkdir()
        shutil.copy(source, scene_path)
        sidecar = source.with_name(source.stem + ".glint.toml")
        shutil.copy(sidecar, scene_path.parent / sidecar.name)
        base, bake_seconds = bake(scene_path, args.quality)
        ctx = headless_context() if args.frames else None
        renderer = Renderer(ctx, base) if ctx is not None else None
        for name in args.edits:
            rows.append(measure_edit(renderer, base, scene_path, size, *EDITS[name], args.nice))
            rows[-1]["name"] = name
            if renderer is not None:  # back to the bake's light maps for the next edit
                renderer.replace_lightmaps([base.lightmap(k) for k in range(len(base.model.lightmaps))],
                                           [base.lightmap(k, back=True) for k in range(len(base.back_pages))])
                renderer.replace_probes({f: mip_chain(read_cubemap(base.path / f)) for f in renderer.scene.cubemaps.slots})
        renderer_name = describe(ctx) if ctx is not None else None
        if renderer is not None:
            renderer.release()  # before the bakes: their cube-map stage makes its own GL contexts
        for row in rows:  # the same edits through the sidecar and a whole `glint bake --force`
            material, key, value = EDITS[row["name"]]
            edited_path = Path(tmp) / row["name"].replace(" ", "-").replace("'", "") / source.name
            edited_path.parent.mkdir()
            shutil.copy(scene_path, edited_path)
            (edited_path.parent / sidecar.name).write_text(
                sidecar.read_text() + f"\n[materials.\"{material}\"]\n{key} = {value}\n")
            reference, seconds = bake(edited_path, args.quality)
            diffs = [np.abs(p.astype(np.float16).astype(np.float32) - reference.lightmap(k))
                     for k, p in enumerate(row.pop("_last"))]
            cube_diffs = [np.abs(chain[0].astype(np.float16).astype(np.float32)[..., :3]
                                 - read_cubemap(reference.path / file)[..., :3]) for file, chain in row.pop("_probes").items()]
            row.update(bake_force_lightmap_seconds=seconds,
                       max_abs_difference_from_bake_force=float(max(d.max() for d in diffs)),
                       differing_values=int(sum((d > 0).sum() for d in diffs)),
                       cubemaps_compared=len(cube_diffs),
                       cubemap_max_abs_difference_from_bake_force=float(max(d.max() for d in cube_diffs)),
                       cubemap_differing_values=int(sum((d > 0).sum() for d in cube_diffs)))
            print(json.dumps(row), flush=True)
    result = {"scene": SCENE, "quality": args.quality, "size": list(size), "base_lightmap_seconds": bake_seconds,
              "machine": platform.node(), "renderer": renderer_name, "edits": rows}
    if args.json:
        atomic_write_text(args.json, json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
