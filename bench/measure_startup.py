"""Start-up time of the `glint` command: wall seconds of `python -m glint ARGS` for the commands that
do no work (`--version`, `--help`, `bake --help`, `capture --help`), medians over fresh processes.

    python3 -m glint.bench.measure_startup [--runs 20]
    python3 -m glint.bench.measure_startup --renderer SCENE --bake-root DIR [--runs 3]

The second form times loading a bake into the renderer instead (`Renderer(ctx, bake)` on a headless
context, glFinish included: meshes, textures, cube maps, light maps, programs), each run in a fresh
process; SCENE is a built-in scene, many-N or a glTF file, baked at draft quality in DIR first.

Measured, never asserted (tests/test_startup.py checks what is imported); figures in docs/VIEWER.md,
"Start-up times".
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

CASES = (["--version"], ["--help"], ["bake", "--help"], ["capture", "--help"])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=None, help="fresh processes per case (default 20; 3 with --renderer)")
    parser.add_argument("--renderer", metavar="SCENE", help="time Renderer(ctx, bake) of SCENE's draft bake instead")
    parser.add_argument("--bake-root", type=Path, help="with --renderer: where the draft bakes are (made when missing)")
    parser.add_argument("--one", action="store_true", help=argparse.SUPPRESS)  # a child process: one timing
    args = parser.parse_args()
    if args.renderer:
        return renderer_startup(args)
    args.runs = args.runs or 20
    for case in CASES:
        subprocess.run([sys.executable, "-m", "glint", *case], capture_output=True, check=True)  # warm the caches
        seconds = []
        for _ in range(args.runs):
            start = time.perf_counter()
            subprocess.run([sys.executable, "-m", "glint", *case], capture_output=True, check=True)
            seconds.append(time.perf_counter() - start)
        print(json.dumps({"args": " ".join(case), "median_ms": round(1e3 * statistics.median(seconds), 1),
                          "min_ms": round(1e3 * min(seconds), 1), "runs": args.runs}), flush=True)
    return 0


def renderer_startup(args) -> int:
    """Seconds of `Renderer(ctx, bake)` for args.renderer's draft bake, each in a fresh process."""
    if args.bake_root is None:
        raise SystemExit("measure_startup: --renderer needs --bake-root")
    if args.one:
        from glint.bench.measure_frame_times import load_bake
        from glint.viewer.context import headless_context
        from glint.viewer.renderer import Renderer

        ctx = headless_context()
        bake = load_bake(args.renderer, args.bake_root, "draft")
        start = time.perf_counter()
        Renderer(ctx, bake)
        ctx.finish()
        print(time.perf_counter() - start)
        return 0
    child = [sys.executable, "-m", "glint.bench.measure_startup", "--one", "--renderer", args.renderer,
             "--bake-root", str(args.bake_root)]
    subprocess.run(child, capture_output=True, check=True)  # bakes when missing, warms the caches
    seconds = [float(subprocess.run(child, capture_output=True, check=True, text=True).stdout.split()[-1])
               for _ in range(args.runs or 3)]
    print(json.dumps({"renderer": args.renderer, "seconds": [round(x, 2) for x in seconds],
                      "median_s": round(statistics.median(seconds), 2)}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
