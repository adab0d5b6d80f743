"""Frame cost against the object count: the many-objects stress scenes (scenes/stress.py `many_objects`).

    python3 -m glint.bench.measure_many_objects [--counts 10,300,1000,3000,10000] [--kind diffuse|metal]
                                                 [--size 640x360] [--frames 20] [--root DIR] [--out DIR]

For every count N: writes the room of N boxes (`--kind diffuse`: all diffuse; `metal`: every third
box rough metal, with cube maps) into DIR/scenes, bakes it (draft; reused when up to date, the bake
time is the sum of the manifest's stage times, as the bake that wrote it measured them), then renders --frames walkthrough frames of its `view` camera at --size
after --warmup frames and reports:

- the renderer's per-pass times and their sum (viewer/timing.py: on llvmpipe the glFinish-bracketed
  wall clock), and the wall time per frame (frames back to back, one glFinish at the end);
- the *Python* time per frame: the same frames again under cProfile, the summed own time of every
  Python function (the time spent inside C calls -- moderngl, the GL driver, numpy -- excluded), in
  the main thread's CPU time (time.thread_time: llvmpipe's raster threads, which take the other
  core while Python runs, do not count as Python's time); the
  profiler's own overhead makes it an upper bound ("cProfile"), and "net" takes off that overhead,
  measured on this machine as the cost per profiled call of an empty function, once per call the
  frame made; each of 5 blocks of --frames frames is profiled on its own and the median block's
  figures are reported (the others in the JSON);
- the GL calls per frame and the time in them (cProfile's built-in calls of moderngl's objects).

Writes DIR/many_objects.json and .md.
"""
from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import time
from pathlib import Path

from glint.bake.settings import resolve_settings
from glint.bench.measure_frame_times import time_view
from glint.core.atomic import atomic_write_text
from glint.core.bake_dir import Bake
from glint.scenes.stress import MANY_COUNTS, many_objects
from glint.services import bake_scene, open_scene
from glint.viewer.camera import ViewCamera, find_named
from glint.viewer.context import headless_context
from glint.viewer.gl import describe
from glint.viewer.renderer import Renderer


def profiler_overhead_s(calls: int = 200_000) -> float:
    """Seconds cProfile adds to one call of an empty Python function (median of 5 tries)."""
    def empty():
        pass

    tries = []
    for _ in range(5):
        t = time.thread_time()
        for _ in range(calls):
            empty()
        plain = time.thread_time() - t
        profile = cProfile.Profile(time.thread_time)
        profile.enable()
        t = time.thread_time()
        for _ in range(calls):
            empty()
        profiled = time.thread_time() - t
        profile.disable()
        tries.append(max(profiled - plain, 0.0) / calls)
    return sorted(tries)[2]


def python_time(renderer, camera, size, frames: int, blocks: int = 5) -> dict:
    """cProfile over `blocks` runs of `frames` walkthrough frames: Python's own time and the C calls,
    per frame, the median block's (see the module docstring)."""
    overhead = profiler_overhead_s()
    rows = []
    for _ in range(blocks):
        profile = cProfile.Profile(time.thread_time)
        profile.enable()
        for _ in range(frames):
            renderer.render(camera, *size)
        profile.disable()
        renderer.ctx.finish()
        python = builtin = 0.0
        calls = every_call = 0
        for (filename, _, name), (_, ncalls, tottime, _, _) in pstats.Stats(profile).stats.items():
            every_call += ncalls
            if filename == "~":  # a built-in (C) function or method
                builtin += tottime
                if "mgl" in name or "moderngl" in name:
                    calls += ncalls
            else:
                python += tottime
        rows.append({"python_ms_per_frame": round(python * 1e3 / frames, 3),
                     "python_ms_per_frame_net": round(max(python - every_call * overhead, 0.0) * 1e3 / frames, 3),
                     "calls_per_frame": round(every_call / frames, 1),
                     "c_calls_ms_per_frame": round(builtin * 1e3 / frames, 3),
                     "moderngl_calls_per_frame": round(calls / frames, 1)})
    rows.sort(key=lambda r: r["python_ms_per_frame_net"])
    return {**rows[len(rows) // 2], "python_ms_per_frame_net_blocks": [r["python_ms_per_frame_net"] for r in rows]}


def measure(root: Path, n: int, kind: str, size, frames: int, warmup: int, ctx) -> dict:
    name = f"{kind}-{n}"
    scenes = root / "scenes"
    many_objects(scenes, n, metal_every=3 if kind == "metal" else None, name=name)  # the same bytes: no re-bake
    loaded, _ = open_scene(str(scenes / f"{name}.glb"))
    bake_dir = root / f"{name}.bake"
    t0 = time.perf_counter()
    bake_scene(loaded, resolve_settings(loaded.bake_settings), bake_dir, progress=False)
    bake = Bake(bake_dir)
    statistics = bake.model.statistics.data
    with Renderer(ctx, bake) as renderer:
        camera = ViewCamera.from_manifest(find_named(bake.model.cameras, "view"))
        timed = time_view(renderer, camera, size, frames, warmup, "walkthrough")
        stats = renderer.stats
        profiled = python_time(renderer, camera, size, frames)
    return {"scene": name, "objects": stats["objects"], "objects_drawn": stats["objects_drawn"],
            "triangles": stats["triangles"], "bake_seconds_this_run": round(time.perf_counter() - t0, 2),
            "bake_seconds": round(sum((statistics.get(stage) or {}).get("seconds") or 0.0
                                      for stage in ("unwrap", "lightmaps", "cubemaps")), 2),
            "cube_maps": statistics.get("cubemaps"),
            **{k: timed[k] for k in ("passes_ms", "gpu_total_ms", "wall_ms_per_frame")},
            "render_call_ms_median": (stats.get("cpu_ms") or {}).get("median"), **profiled}


def markdown(setup: dict, rows: list[dict]) -> str:
    out = [f"# Frame cost against object count ({setup['kind']})", "",
           f"{setup['device']}; {setup['size'][0]}x{setup['size'][1]}, {setup['frames']} frames after "
           f"{setup['warmup']} warm-up; `{setup['command']}`", "",
           "| objects | G-buffer ms | total ms (passes) | wall ms/frame | Python ms/frame (cProfile) | "
           "Python ms/frame (net) | moderngl calls/frame | bake s |", "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        out.append(f"| {r['objects']} | {r['passes_ms'].get('gbuffer', 0):.2f} | {r['gpu_total_ms']:.2f} | "
                   f"{r['wall_ms_per_frame']:.2f} | {r['python_ms_per_frame']:.3f} | "
                   f"{r['python_ms_per_frame_net']:.3f} | "
                   f"{r['moderngl_calls_per_frame']:.0f} | {r['bake_seconds'] if r['bake_seconds'] is not None else '-'} |")
    return "\n".join(out) + "\n"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--counts", default=",".join(map(str, MANY_COUNTS)))
    p.add_argument("--kind", choices=("diffuse", "metal"), default="diffuse")
    p.add_argument("--size", default="640x360")
    p.add_argument("--frames", type=int, default=20)
    p.add_argument("--warmup", type=int, default=3)
    p.add_argument("--root", default="many-objects", help="scenes and bakes (reused when up to date)")
    p.add_argument("--out", default=None, help="report directory (default: --root)")
    args = p.parse_args()
    size = tuple(int(x) for x in args.size.lower().split("x"))
    root = Path(args.root)
    out = Path(args.out) if args.out else root
    out.mkdir(parents=True, exist_ok=True)
    ctx = headless_context()
    setup = {"device": describe(ctx), "size": size, "frames": args.frames, "warmup": args.warmup, "kind": args.kind,
             "command": "python3 -m glint.bench.measure_many_objects " + " ".join(
                 f"--{k} {v}" for k, v in (("counts", args.counts), ("kind", args.kind), ("size", args.size),
                                           ("frames", args.frames)))}
    rows = []
    for n in (int(x) for x in args.counts.split(",")):
        row = measure(root, n, args.kind, size, args.frames, args.warmup, ctx)
        print(json.dumps({k: row[k] for k in ("scene", "gpu_total_ms", "wall_ms_per_frame", "python_ms_per_frame",
                                              "moderngl_calls_per_frame")}), flush=True)
        rows.append(row)
    atomic_write_text(out / "many_objects.json", json.dumps({"setup": setup, "rows": rows}, indent=1))
    atomic_write_text(out / "many_objects.md", markdown(setup, rows))
    print(markdown(setup, rows))


if __name__ == "__main__":
    main()
