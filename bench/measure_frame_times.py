"""Frame time per pass of the built-in scenes at several sizes (as the thesis' Table 4.2; docs/VIEWER.md).

    python3 -m glint.bench.measure_frame_times [--sizes 1920x1080,3840x2160] [--supersample 1,2] [--frames 60]
                                        [--scenes living-room,...] [--bake-root DIR] [--out DIR]
                                        [--weights albedo,eq4.25] [--gbuffer auto,raster,visibility]
                                        [--quality draft]

For every scene, camera, size and supersampling factor: --warmup untimed frames, then --frames
walkthrough frames of the same view; printed and written (DIR/frame_times.json, .md) are the
medians of the renderer's per-pass times (viewer/timing.py: GPU timer queries on a GPU, the
glFinish-bracketed wall clock on llvmpipe), their sum ("gpu total") and the wall-clock time per
frame as the program sees it (the frames back to back, one glFinish at the end, divided by their
number: CPU work and driver overhead included) and the CPU time of the drawing thread per frame
("cpu": Python and the driver's calls on it, up to the glFinish; with the GPU's frames in flight
the wall time is about the larger of the two). Then the same for still-camera frames
("converge": 4 quasi-random samples per lobe and pixel, added to the running mean). The bakes
are the scenes' default bakes (`glint bake SCENE`); --bake-root DIR uses DIR/STEM.bake instead (made when
missing; there scenes may also be many-N, N boxes, or .glb/.gltf files: measure_draw_count.py `bake_for`);
--quality PRESET bakes them at that preset. --weights: the walkthrough
estimators to time, each a renderer of its own (Renderer(weights=...): "albedo", the default,
"eq4.25", "eq4.24"), one after the other per view.
--gbuffer likewise: the G-buffer and mirror passes rasterised ("raster") or through a visibility buffer
("visibility"; viewer/passes/gbuffer.py), or as the renderer picks ("auto", the default: the
visibility buffer on a GPU); the rows say which ran.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from glint.bake.settings import resolve_settings
from glint.bench.measure_draw_count import bake_for
from glint.core.atomic import atomic_write_text
from glint.core.bake_dir import Bake, default_bake_dir
from glint.services import bake_scene, open_scene
from glint.viewer.camera import ViewCamera
from glint.viewer.context import headless_context
from glint.viewer.gl import describe
from glint.viewer.renderer import GBUFFER_WAYS, Renderer

SCENES = ("living-room", "material-classes", "planar-classes", "cornell-box")


def load_bake(scene: str, bake_root: Path | None, quality: str | None = None):
    if bake_root:  # built-in, many-N or a glTF file, baked in bake_root
        return Bake(bake_for(scene, bake_root, quality))
    loaded, builtin = open_scene(scene)
    settings = resolve_settings(loaded.bake_settings, quality=quality)
    out = default_bake_dir(loaded.source, builtin)
    bake_scene(loaded, settings, out, progress=False)  # no-op when up to date
    return Bake(out)


def time_view(renderer, camera, size, frames: int, warmup: int, mode: str) -> dict:
    for _ in range(warmup):
        renderer.render(camera, *size, mode=mode)
    renderer.ctx.finish()
    renderer.timer.reset()
    start, cpu = time.perf_counter(), time.thread_time()
    for _ in range(frames):
        if mode == "converge":
            renderer.progressive.invalidate()  # every frame a first still frame: the same work each time
        renderer.render(camera, *size, mode=mode)
    cpu_ms = (time.thread_time() - cpu) * 1e3 / frames  # this thread's: Python and the driver's calls
    renderer.ctx.finish()
    wall_ms = (time.perf_counter() - start) * 1e3 / frames
    ms = renderer.stats["gpu_ms_median"]
    return {"passes_ms": {k: round(v, 3) for k, v in ms.items() if k != "total"},
            "gpu_total_ms": round(ms.get("total", 0.0), 3), "wall_ms_per_frame": round(wall_ms, 3),
            "cpu_ms_per_frame": round(cpu_ms, 3),
            "specular": renderer.stats["specular"], "mirror_passes": renderer.stats["mirror"].get("passes_run")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1920x1080,3840x2160")
    ap.add_argument("--supersample", default="1,2")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--warmup", type=int, default=10)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--bake-root", type=Path)
    ap.add_argument("--out", type=Path, default=Path("/tmp/glint-frame-times"))
    ap.add_argument("--weights", default="albedo")
    ap.add_argument("--gbuffer", default="auto")
    ap.add_argument("--quality", help="the bakes' quality preset (default: the scene's own settings)")
    args = ap.parse_args()
    sizes = [tuple(int(x) for x in s.lower().split("x")) for s in args.sizes.split(",")]
    factors = [int(s) for s in args.supersample.split(",")]
    ctx = headless_context()
    rows = []
    header = (f"{'scene':17s} {'camera':14s} {'size':>9s} ss {'weights':7s} {'mode':11s} {'gpu total':>9s} {'wall':>8s} "
              f"{'cpu':>7s}  G-buffer    passes (ms)")
    print(describe(ctx))
    print(header)
    for scene in args.scenes.split(","):
        bake = load_bake(scene, args.bake_root, args.quality)
        for cam in bake.model.cameras:
            camera = ViewCamera.from_manifest(cam)
            for ss in factors:
                for weights, gbuffer in ((w, g) for w in args.weights.split(",") for g in args.gbuffer.split(",")):
                    renderer = Renderer(ctx, bake, supersample=ss, samples_per_frame=4, weights=weights,
                                        visibility=GBUFFER_WAYS[gbuffer])
                    gbuffer = "visibility" if renderer.gbuffer.visibility else "raster"
                    for size in sizes:
                        for mode in ("walkthrough", "converge"):
                            r = time_view(renderer, camera, size, args.frames, args.warmup, mode)
                            r.update(scene=scene, camera=cam.name, size=f"{size[0]}x{size[1]}", supersample=ss,
                                     mode=mode, weights=weights, gbuffer=gbuffer)
                            rows.append(r)
                            passes = " ".join(f"{k}={v:.2f}" for k, v in r["passes_ms"].items())
                            print(f"{scene:17s} {cam.name[:14]:14s} {r['size']:>9s} {ss:2d} {weights:7s} {mode:11s} "
                                  f"{r['gpu_total_ms']:9.2f} {r['wall_ms_per_frame']:8.2f} {r['cpu_ms_per_frame']:7.2f}  "
                                  f"{gbuffer:10s}  {passes}",
                                  flush=True)
                    renderer.release()
    device = describe(ctx)
    ctx.release()
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out / "frame_times.json", json.dumps(
        {"device": device, "frames": args.frames, "warmup": args.warmup, "rows": rows}, indent=1) + "\n")
    lines = [f"Device: {device}; medians of {args.frames} frames after {args.warmup} warm-up frames.", "",
             ("| scene | camera | size | supersample | weights | G-buffer | mode | GPU ms (sum of passes) | wall ms/frame "
              "| CPU ms/frame (the drawing thread) | passes (ms) |"),
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        passes = ", ".join(f"{k} {v:.2f}" for k, v in r["passes_ms"].items())
        lines.append(f"| {r['scene']} | {r['camera']} | {r['size']} | {r['supersample']} | {r['weights']} "
                     f"| {r['gbuffer']} | {r['mode']} | "
                     f"{r['gpu_total_ms']:.2f} | {r['wall_ms_per_frame']:.2f} | {r['cpu_ms_per_frame']:.2f} | {passes} |")
    atomic_write_text(args.out / "frame_times.md", "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
