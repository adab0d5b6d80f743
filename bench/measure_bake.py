"""Measures the figures in docs/BAKE.md: bake time and rays per second of each built-in
scene at each quality preset, and the light maps' error against Mitsuba 3 on cornell-box.

    python3 -m glint.bench.measure_bake [--presets draft preview final] [--jobs 2] [--json out.json]

The accuracy method is the one of tests/test_bake_vs_mitsuba.py (50 points, bilinear
light-map look-up vs. Mitsuba's irradiance, mean of |a-b|_1/|b|_1).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from glint.bake.gltf_loader import load_scene
from glint.bake.settings import PRESETS, resolve_settings
from glint.bench.mitsuba_reference import MARGIN, POINTS, cornell_box_irradiance, sample_points
from glint.core.atomic import atomic_write_text
from glint.core.bake_dir import Bake
from glint.scenes import BUILTIN, builtin_path
from glint.services import bake_scene


def cornell_error(scene, bake_dir: Path, reference_cache: dict) -> dict:
    chosen, _ = sample_points(scene, POINTS, MARGIN)
    bake = Bake(bake_dir)
    ours = np.array([bake.irradiance(o, np.array([t]), b[None])[0] for o, t, b, _, _ in chosen])
    if "E" not in reference_cache:
        reference_cache["E"] = cornell_box_irradiance(np.array([c[3] for c in chosen]),
                                                      np.array([c[4] for c in chosen]), spp=65536)
    ref = reference_cache["E"]
    rel = np.abs(ours - ref).sum(axis=1) / ref.sum(axis=1)
    return {"mean_relative_error": float(rel.mean()), "max_relative_error": float(rel.max())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--presets", nargs="+", default=list(PRESETS))
    ap.add_argument("--scenes", nargs="+", default=list(BUILTIN))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    rows, cache = [], {}
    for name in args.scenes:
        scene = load_scene(builtin_path(name))
        for preset in args.presets:
            settings = resolve_settings(scene.bake_settings, quality=preset, jobs=args.jobs)
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                report = bake_scene(scene, settings, Path(tmp) / "x.bake", progress=False)
                wall = time.perf_counter() - t0
                stats = report.model.statistics.data
                row = {"scene": name, "preset": preset, "samples": settings.samples,
                       "texels_per_metre": settings.texels_per_metre, "jobs": args.jobs,
                       "wall_seconds": round(wall, 1), "unwrap_seconds": stats["unwrap"]["seconds"],
                       "lightmap_seconds": stats["lightmaps"]["seconds"], "texels": stats["lightmaps"]["texels"],
                       "rays": stats["lightmaps"]["rays"],
                       "rays_per_second": stats["lightmaps"]["rays_per_second"],
                       "cubemaps": stats.get("cubemaps", {}).get("count", 0),
                       "cubemap_seconds": stats.get("cubemaps", {}).get("seconds", 0.0),
                       "load_average": round(os.getloadavg()[0], 1)}
                if name == "cornell-box":
                    row.update(cornell_error(scene, Path(tmp) / "x.bake", cache))
            rows.append(row)
            print(json.dumps(row), flush=True)
    print(f"\nmachine: {platform.machine()}, {platform.processor() or '?'}, "
          f"python {platform.python_version()}\n")
    print("| scene | preset | samples | texels/m | texels | bake s (light maps + cube maps) | rays | M rays/s | vs Mitsuba (mean / max) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        err = (f"{100 * r['mean_relative_error']:.1f} % / {100 * r['max_relative_error']:.1f} %"
               if "mean_relative_error" in r else "")
        print(f"| {r['scene']} | {r['preset']} | {r['samples']} | {r['texels_per_metre']:g} | {r['texels']} "
              f"| {r['wall_seconds']:.1f} ({r['lightmap_seconds']:.1f} + {r['cubemap_seconds']:.1f}) | {r['rays'] / 1e6:.0f} M | {r['rays_per_second'] / 1e6:.2f} | {err} |")
    if args.json:
        atomic_write_text(args.json, json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
