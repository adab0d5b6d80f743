"""Measures the figures of docs/BAKE.md "On a cluster (Dask)": the wall time of `glint bake` with the
local executor against `--scheduler local:1` and `--scheduler local:2` (the engine's overhead), where
that overhead goes, and the model of the time on larger clusters made from them.

    python3 -m glint.bench.measure_cluster [--scenes cornell-box living-room] [--quality preview]
        [--rounds 5] [--configs local local:1 local:2] [--json docs/bench/cluster/preview.json]
    python3 -m glint.bench.measure_cluster --overhead [--json docs/bench/cluster/task_overhead.json]
    python3 -m glint.bench.measure_cluster --model docs/bench/cluster/A.json [B.json ...] [--cores 8 64 512]
    python3 -m glint.bench.measure_cluster --sizes SCENE [--quality preview] [--bake-dir DIR] [--json ...]

Runs: each round bakes every scene with every configuration once, in turn (interleaved, so that
other work on a shared machine weighs on all alike), as `python -m glint bake SCENE -q QUALITY
--force -o DIR [--scheduler X]` in a subprocess (the `glint` script beside this Python), exactly the
command a user types; its wall clock
is the figure. Kept per run: the load average (1 min) before it, the manifest's stage seconds
(unwrap, light maps and their tracing, cube maps), the cluster's statistics (start, waiting, scatter,
MiB scattered, tasks) and whether every light map and cube map is the bytes of the round's local
bake. Printed: the median, min and max per scene and configuration, and each median against the
local executor's.

--overhead: what a task costs on the engine beyond its work: 400 tasks that return a light-map tile's
result (2048 x 3 + 2048 float32) and do nothing else, on local:2 (once started) and on the local
executor's two processes; seconds per task. And the phases of a local:2 cluster's start in a fresh
interpreter (median of 5), in the `glint` command's order: forking the worker server, importing
glint meanwhile, the cluster ready (its client process connected, the workers in) after that,
closing. --model: the time of each measured bake on 8, 64 and 512
cores (docs/BAKE.md states the model and what it assumes). --sizes: what travels for a scene (the
light-map stage's scattered inputs and a tile's task and result, pickled; with --bake-dir the
cube-map stage's inputs and its probe files).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from glint.bench.report import write_json

CONFIGS = ("local", "local:1", "local:2")
ROOT = Path(__file__).resolve().parents[1]
# The model (--model): what it takes of a cluster it was not measured on
NETWORK_MIB_PER_SECOND = 110.0  # 1 Gbit/s Ethernet, what the client and each worker send and receive
# Dask's replicate (scatter(broadcast=True)): in each generation every holder sends to up to this many
# workers that lack the data (distributed's Scheduler.replicate, branching_factor), so the holders
# triple per generation and a generation takes this many copies' time on a holder's network link
REPLICATE_BRANCHING = 2
CORES = (8, 64, 512)


def commit() -> str | None:
    """The checkout's commit (and "+changes" when the tree differs from it), None outside a checkout."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT, capture_output=True,
                               text=True).stdout.strip()
        return head + ("+changes" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return None


def glint_command() -> list[str]:
    """The `glint` command beside this Python (what a user runs), else `python -m glint`."""
    script = Path(sys.executable).with_name("glint")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "glint"]


def bake_once(scene: str, quality: str, config: str, out: Path) -> dict:
    command = [*glint_command(), "bake", scene, "-q", quality, "--force", "-o", str(out)]
    if config != "local":
        command += ["--scheduler", config]
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    run = subprocess.run(command, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if run.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{run.stderr[-2000:]}")
    stats = json.loads((out / "manifest.json").read_text())["statistics"]
    lm, cm = stats["lightmaps"], stats.get("cubemaps", {})
    return {"scene": scene, "config": config, "wall_seconds": round(wall, 3), "load_average": round(load, 2),
            "unwrap_seconds": stats["unwrap"]["seconds"], "lightmap_seconds": lm["seconds"],
            "trace_seconds": lm.get("trace_seconds"), "tiles": lm.get("tiles"), "texels": lm["texels"],
            "cubemap_seconds": cm.get("seconds", 0.0), "cubemaps": cm.get("rendered", 0),
            "cubemap_processes": cm.get("processes"), "cubemap_task_seconds_max": cm.get("task_seconds_max"),
            "cubemap_worker_setup_seconds_max": cm.get("worker_setup_seconds_max"),
            "cluster": stats.get("cluster"), "command": " ".join(["glint", *command[command.index("bake"):]])}


def baked_files(bake_dir: Path) -> dict[str, bytes]:
    return {p.relative_to(bake_dir).as_posix(): p.read_bytes()
            for folder in ("lightmaps", "cubemaps") for p in sorted((bake_dir / folder).glob("*.exr"))}


def measure_runs(scenes, quality: str, rounds: int, configs) -> list[dict]:
    runs = []
    with tempfile.TemporaryDirectory(prefix="glint-cluster-bench-") as tmp:
        for r in range(rounds):
            for scene in scenes:
                reference = None
                for config in configs:
                    out = Path(tmp) / f"{Path(scene).stem}-{config.replace(':', '')}.bake"
                    row = bake_once(scene, quality, config, out)
                    files = baked_files(out)
                    if config == configs[0]:
                        reference = files
                    row.update(round=r, same_bytes_as_first_config=files == reference)
                    runs.append(row)
                    print(f"round {r}  {Path(scene).stem:18} {config:8} {row['wall_seconds']:8.2f} s  load "
                          f"{row['load_average']:.2f}  same bytes: {row['same_bytes_as_first_config']}", flush=True)
                    shutil.rmtree(out)
    return runs


def summarise(runs: list[dict]) -> list[dict]:
    out = []
    for scene in dict.fromkeys(r["scene"] for r in runs):
        base = None
        for config in dict.fromkeys(r["config"] for r in runs if r["scene"] == scene):
            walls = [r["wall_seconds"] for r in runs if r["scene"] == scene and r["config"] == config]
            median = statistics.median(walls)
            base = median if base is None else base
            out.append({"scene": scene, "config": config, "runs": len(walls), "median_seconds": round(median, 2),
                        "min_seconds": min(walls), "max_seconds": max(walls),
                        "median_vs_first_config": round(median / base, 3)})
    return out


def _tile_result(state, task):
    """A light-map tile's result without its work (bench --overhead)."""
    return np.zeros((2048, 3), np.float32), np.zeros(2048, np.float32), 0


def _no_state():
    return None


# Run in a fresh interpreter (`python -c`), as `glint bake --scheduler local:2` meets them: the phases of
# starting a local:N cluster (parallel/executor.py DaskExecutor.start and _connect, parallel/local_cluster.py),
# each timed on its own.
STARTUP = """
import json, time
t0 = time.perf_counter()
from glint.parallel import local_cluster as L
L.fork_server()  # as glint/entry.py does, first of all
t1 = time.perf_counter()
import glint.cli  # what the glint command imports meanwhile
from glint.parallel import executor as E
t2 = time.perf_counter()
executor = E.DaskExecutor("local:2")
executor.start()
assert list(executor.run(E._init_worker, (None, (), None), max, [])) == []  # no tasks: until it is ready
t3 = time.perf_counter()
executor.close()
t4 = time.perf_counter()
print(json.dumps({"fork_server_seconds": t1 - t0, "import_glint_cli_seconds": t2 - t1,
                  "cluster_ready_after_import_seconds": t3 - t2, "close_seconds": t4 - t3,
                  "dask_imported_here": "distributed" in __import__("sys").modules}))
"""


def measure_startup(runs: int = 5) -> dict:
    """The median of `runs` fresh interpreters' start-up phases (STARTUP)."""
    rows = []
    for _ in range(runs):
        run = subprocess.run([sys.executable, "-c", STARTUP], capture_output=True, text=True, check=True)
        rows.append(json.loads(run.stdout.strip().splitlines()[-1]))
    return {key: round(statistics.median(r[key] for r in rows), 3) for key in rows[0]}


def measure_overhead(tasks: int = 400) -> dict:
    """Seconds per task beyond its work, on local:2 (started beforehand) and on two local processes."""
    from glint.parallel.executor import DaskExecutor, LocalExecutor

    out = {"tasks": tasks, "startup_phases_median_of_5": measure_startup()}
    with DaskExecutor("local:2") as cluster:
        t0 = time.perf_counter()
        cluster.start()
        cluster.client  # noqa: B018 (waits for the start)
        out["local2_start_seconds"] = round(time.perf_counter() - t0, 3)
        for name, executor in (("local2", cluster), ("local_executor_2", LocalExecutor(2))):
            t0 = time.perf_counter()
            done = sum(1 for _ in executor.run(_no_state, (), _tile_result, range(tasks)))
            assert done == tasks
            out[f"{name}_seconds_per_task"] = round((time.perf_counter() - t0) / tasks, 5)
    return out


def measure_sizes(scene_arg: str, quality: str, bake_dir: Path | None) -> dict:
    """What the light-map stage scatters for `scene_arg` at `quality` (the scene, the texels' points and
    normals; pickled as Dask sends them) and what its tasks carry, and, given a bake directory of it,
    what the cube-map stage scatters (bake_inputs) and its probe files' sizes by face size."""
    import pickle

    from glint.parallel.executor import _pickled_bytes
    from glint.bake.lightmap import TILE, _cut_out
    from glint.bake.settings import resolve_settings
    from glint.bake.texels import rasterize_texels
    from glint.bake.unwrap import unwrap
    from glint.core.bake_dir import read_manifest
    from glint.cubemap_stage import bake_inputs
    from glint.services import open_scene

    scene, _ = open_scene(scene_arg)
    settings = resolve_settings(scene.bake_settings, quality=quality)
    pages = rasterize_texels(scene.objects, unwrap(scene.objects, settings.texels_per_metre, settings.padding,
                                                   settings.max_page_size))
    covered = [(p.object >= 0) & ~_cut_out(scene, p) for p in pages]
    points = np.concatenate([p.position[c] for p, c in zip(pages, covered)])
    normals = np.concatenate([p.normal[c] for p, c in zip(pages, covered)])
    textures = {}  # the materials' images (kd_texture, ...) by attribute, MiB
    for m in scene.materials:
        for name, value in vars(m).items():
            if isinstance(value, np.ndarray) and value.ndim >= 2:
                textures[name] = textures.get(name, 0.0) + value.nbytes / 2 ** 20
    out = {"scene": scene_arg, "quality": quality, "scene_mib": _pickled_bytes(scene) / 2 ** 20,
           "material_textures_mib": {name: round(mib, 3) for name, mib in textures.items()},
           "front_texels": len(points), "front_points_normals_mib": _pickled_bytes((points, normals)) / 2 ** 20,
           "tile_task_bytes": len(pickle.dumps((0, TILE, settings.samples, settings.seed, settings.max_depth))),
           "tile_result_bytes": _pickled_bytes((np.zeros((TILE, 3), np.float32), np.zeros(TILE, np.float32), 0))}
    if bake_dir is not None:
        files = bake_inputs(bake_dir)
        out.update(cubemap_inputs_mib=sum(map(len, files.values())) / 2 ** 20, cubemap_inputs_files=len(files))
        by_size = {}
        for entry in read_manifest(bake_dir)["objects"]:
            if entry.get("cubemap"):
                by_size.setdefault(entry["cubemap"]["size"], set()).add(entry["cubemap"]["file"])
        out["cubemap_file_kib_by_face_size"] = {
            size: sorted(round((bake_dir / f).stat().st_size / 1024, 1) for f in names)
            for size, names in sorted(by_size.items())}
    return {k: round(v, 3) if isinstance(v, float) else v for k, v in out.items()}


def model(runs: list[dict], overhead: dict, cores=CORES) -> list[dict]:
    """The time of each measured bake on `cores` cores (one worker thread each), from the median of its
    local-executor runs (serial parts, work) and its cluster runs (the cube-map workers' set-up, the
    longest cube-map task, the inputs scattered) and the engine's time per task (`overhead`, --overhead).
    docs/BAKE.md "A model for larger clusters" states it and what it assumes."""
    from glint.parallel.executor import TASKS_PER_WORKER
    from glint.bake.lightmap import MIN_CLUSTER_TILE, TILE
    from glint.cubemap_stage import PROBES_PER_TASK

    per_task_seconds = overhead["local2_seconds_per_task"]
    out = []
    for scene in dict.fromkeys(r["scene"] for r in runs):
        local = [r for r in runs if r["scene"] == scene and r["config"] == "local"]
        cluster = [r for r in runs if r["scene"] == scene and r["config"] != "local" and r.get("cluster")]
        if not local or not cluster:
            continue

        def med(rows, key):
            values = [r[key] for r in rows if r.get(key) is not None]
            return statistics.median(values) if values else 0.0

        wall, trace, cubes = med(local, "wall_seconds"), med(local, "trace_seconds"), med(local, "cubemap_seconds")
        serial = wall - trace - cubes  # start-up, load, unwrap, texels, dilate, denoise, writing: the client's
        work = trace * 2  # core-seconds of path tracing: the local executor's two processes kept both cores busy
        texels, probes = int(med(local, "texels")), int(med(local, "cubemaps"))
        cube_work = cubes * (med(local, "cubemap_processes") or 1)
        setup = med(cluster, "cubemap_worker_setup_seconds_max")
        # the longest probe: the cluster run's longest task over the probes in its tasks
        measured_threads = statistics.median([r["cluster"]["threads"] for r in cluster])
        probes_then = max(1, min(PROBES_PER_TASK, probes // (TASKS_PER_WORKER * measured_threads)))
        longest_probe = med(cluster, "cubemap_task_seconds_max") / probes_then
        mib = statistics.median([r["cluster"]["scattered_mib"] for r in cluster])
        for p in cores:
            tile = max(MIN_CLUSTER_TILE, min(TILE, math.ceil(texels / (TASKS_PER_WORKER * p))))
            tiles = math.ceil(texels / tile)
            traced = math.ceil(tiles / p) * work / tiles  # waves of equal tiles
            per_task = max(1, min(PROBES_PER_TASK, probes // (TASKS_PER_WORKER * p)))
            rendered = setup + max(cube_work / p, longest_probe * per_task) if probes else 0.0
            generations = math.ceil(math.log(p) / math.log(1 + REPLICATE_BRANCHING) - 1e-9)
            # the client to one worker, then the tree's generations
            scatter = (1 + REPLICATE_BRANCHING * generations) * mib / NETWORK_MIB_PER_SECOND
            engine = (tiles + math.ceil(probes / per_task)) * per_task_seconds
            total = serial + traced + rendered + scatter + engine
            out.append({"scene": scene, "cores": p, "serial_seconds": round(serial, 1), "tiles": tiles,
                        "trace_seconds": round(traced, 1), "cubemap_seconds": round(rendered, 1),
                        "scatter_seconds": round(scatter, 1), "engine_seconds": round(engine, 1),
                        "total_seconds": round(total, 1), "measured_local_seconds": round(wall, 1),
                        "speed_up": round(wall / total, 1)})
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python3 -m glint.bench.measure_cluster", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", nargs="+", default=["cornell-box", "living-room"])
    parser.add_argument("--quality", default="preview")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--configs", nargs="+", default=list(CONFIGS))
    parser.add_argument("--overhead", action="store_true", help="measure the per-task overhead only")
    parser.add_argument("--model", nargs="+", type=Path, metavar="JSON",
                        help="model larger clusters from these runs' files and --overhead's (task_overhead.json)")
    parser.add_argument("--cores", nargs="+", type=int, default=list(CORES))
    parser.add_argument("--sizes", metavar="SCENE", help="what travels for this scene at --quality (the first of "
                        "--scenes), with --bake-dir its cube-map inputs too")
    parser.add_argument("--bake-dir", type=Path, help="a bake directory of the --sizes scene")
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    about = {"machine": platform.node(), "cpus": os.cpu_count(), "python": platform.python_version(),
             "commit": commit(), "command": " ".join(["python3 -m glint.bench.measure_cluster", *sys.argv[1:]])}
    if args.sizes:
        result = {**about, **measure_sizes(args.sizes, args.quality, args.bake_dir)}
        print(result)
    elif args.model:
        files = [json.loads(path.read_text()) for path in args.model]
        runs = [r for f in files for r in f.get("runs", [])]
        overhead = next(f for f in files if "local2_seconds_per_task" in f)
        result = {**about, "inputs": [str(p) for p in args.model], "network_mib_per_second": NETWORK_MIB_PER_SECOND,
                  "model": model(runs, overhead, args.cores)}
        for row in result["model"]:
            print(row)
    elif args.overhead:
        result = {**about, **measure_overhead()}
        print(result)
    else:
        import distributed

        runs = measure_runs(args.scenes, args.quality, args.rounds, args.configs)
        result = {**about, "dask": distributed.__version__, "quality": args.quality, "rounds": args.rounds,
                  "runs": runs, "summary": summarise(runs)}
        for row in result["summary"]:
            print(row)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        write_json(args.json, result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
