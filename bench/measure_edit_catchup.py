"""Measures the figures of docs/VIEWER.md "Material edits: how the light catches up": after an
edit in `glint view`, how soon the window shows light maps no worse than those before the edit,
and how long an undo to a state already baked takes.

    python3 -m glint.bench.measure_edit_catchup [--quality draft] [--idle 10] [--json out.json]

The living room (a copy) is baked at --quality; a `Rebaker` (bake/rebake.py, light maps only)
starts and is left idle for --idle seconds (a user looking around before the first edit). Then,
in turn: the sofa's kd edited; the ceiling lights' emission edited on top of it; undo (back to
the sofa edit) and revert (back to the bake). For each edit: the seconds from the edit until
poll() returns the first pages and the last pass's, and the relative RMS error against the last
pass (sqrt(sum (x - c)^2 / sum c^2) over the path-traced texels' RGB) of the pages shown before
the edit, of the raw first pass and of the first pages shown. For undo and revert: the seconds
poll() takes to return the state's pages.
"""
from __future__ import annotations

import argparse
import json
import math
import shutil
import tempfile
import time
from pathlib import Path

from glint.bake.gltf_loader import load_scene
from glint.bake.rebake import Rebaker
from glint.bake.settings import resolve_settings
from glint.core.bake_dir import Bake
from glint.scenes import builtin_path
from glint.services import bake_scene

SCENE = "living-room"
EDITS = [("Sofa fabric", "kd", [0.6, 0.12, 0.08]), ("Light diffuser", "emission", [32.0, 22.0, 12.0])]


def relative_rms(pages, reference) -> float:
    num = den = 0.0
    for x, r in zip(pages, reference):
        valid = r[..., 3] > 0
        num += float(((x[..., :3] - r[..., :3])[valid] ** 2).sum())
        den += float((r[..., :3][valid] ** 2).sum())
    return math.sqrt(num / den)


def poll_until(rebaker: Rebaker, timeout: float = 900.0):
    deadline = time.monotonic() + timeout
    while True:
        pages = rebaker.poll()
        if pages is not None:
            return pages
        if rebaker.error is not None or time.monotonic() > deadline:
            raise SystemExit(f"re-bake: {rebaker.error or 'timed out'}")
        time.sleep(0.01)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quality", default="draft")
    ap.add_argument("--idle", type=float, default=10.0, help="seconds between the worker's start-up and the first edit")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        source = builtin_path(SCENE)
        scene_path = Path(tmp) / source.name
        shutil.copy(source, scene_path)
        sidecar = source.with_name(source.stem + ".glint.toml")
        shutil.copy(sidecar, Path(tmp) / sidecar.name)
        scene = load_scene(scene_path)
        report = bake_scene(scene, resolve_settings(scene.bake_settings, quality=args.quality),
                            scene_path.with_suffix(".bake"), force=True, progress=False)
        base = Bake(report.bake_dir)
        shown = [base.lightmap(k) for k in range(len(base.model.lightmaps))]
        materials = [m.to_json() for m in base.model.materials]
        states = [materials]
        with Rebaker(scene_path, base.path) as rebaker:
            while rebaker.ready is None:
                rebaker.poll()
                time.sleep(0.05)
            time.sleep(args.idle)
            for name, key, value in EDITS:
                new = [dict(m) for m in states[-1]]
                next(m for m in new if m["name"] == name)[key] = value
                states.append(new)
                start = time.perf_counter()
                rebaker.edit(new)
                first = poll_until(rebaker)
                first_seconds, raw = time.perf_counter() - start, rebaker.last
                passes = [rebaker.last]
                while not passes[-1].final:
                    poll_until(rebaker)
                    passes.append(rebaker.last)
                final_seconds = time.perf_counter() - start
                converged = passes[-1].front
                rows.append({"edit": f"materials.\"{name}\".{key} = {value}",
                             "schedule": rebaker.schedule,
                             "seconds_to_first_pages": round(first_seconds, 2),
                             "seconds_to_last_pass": round(final_seconds, 2),
                             "error_before_edit": round(relative_rms(shown, converged), 5),
                             "error_raw_first_pass": round(relative_rms(raw.front, converged), 5),
                             "error_first_pages_shown": round(relative_rms(first[0], converged), 5)})
                print(json.dumps(rows[-1]), flush=True)
                shown = converged
            for label, state in (("undo", states[1]), ("revert", states[0])):
                start = time.perf_counter()
                rebaker.edit(state)
                pages = rebaker.poll()
                seconds = time.perf_counter() - start
                rows.append({"edit": label, "pages_at_once": pages is not None, "from_cache": rebaker.from_cache,
                             "milliseconds": round(seconds * 1e3, 2)})
                print(json.dumps(rows[-1]), flush=True)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
