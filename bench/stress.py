"""`glint bench --stress`: the numerical stress suite.

    glint bench --stress                                  # reduced size: minutes on a 2-core machine
    glint bench --stress --stress-size full -o out/       # full size (2 M triangles, 10,000 frames)
    glint bench --stress --stress-cases furnace,scale-1mm,scale-1m --walkthrough-frames 200

The cases are the glTF scenes of scenes/stress.py. Each is baked (draft quality, --jobs), then
every camera of it is rendered as a walkthrough frame and as a still camera's running mean
(STILL_FRAMES frames), at STRESS_SIZE. Per case:

- NaN / Inf: counted in every frame's linear radiance (Renderer.read_linear) and in the bake's
  light maps and cube maps as read back from their EXR files. Must be zero.
- energy: no pixel brighter than the brightest emitter's radiance Le_max times ENERGY_FACTOR.
  A surface returns at most its albedo times the brightest light arriving, and the albedo of
  section 3.3's lobes is at most 1 for alpha = 0 (tests/test_specular.py); Kurt's alpha > 0 and
  the sum of several lobes can exceed 1 at grazing angles, hence a factor 2 rather than 1.
  The furnace case has an exact answer, Le / (1 - kd): every pixel within FURNACE_TOLERANCE.
- scale: a case with `compare_with` (the 1 mm and 10 km rooms) must give the 1 m room's image
  (the scene is scale-invariant when emission is radiance): mean relative difference of the
  still-camera images at most SCALE_TOLERANCE.
- black: a case with `max_black_fraction` (the many-objects rooms, whose every visible surface is
  lit) has at most that fraction of black pixels in its still-camera images: an object drawn
  without its light or its cube map fails it.
- times: bake seconds (wall), frame ms (the renderer's per-pass timers, median), and memory:
  the process RSS and the GPU memory -- GL_NVX_gpu_memory_info on NVIDIA, elsewhere the bytes of
  the textures and buffers glint allocated (`allocated_bytes`).

The walkthrough (--walkthrough-frames, WALKTHROUGH_SIZE) walks the camera path of the first case
that has one (the rooms' `walk`), cycling along it. Checks: RSS grows by at most RSS_GROWTH_BOUND
and the GPU memory glint holds not at all between frame WARMUP_FRAMES and the last; frame 0's
view rendered again at the end equals the first render (no drift: max |difference| <= DRIFT_TOLERANCE
relative to the image's largest value); and the still camera's running mean after DRIFT_FRAMES
frames of one sample equals one of DRIFT_FRAMES / 64 frames of 64 samples each (the same
quasi-random samples, viewer/progressive.py) within ACCUMULATION_TOLERANCE.

Writes stress.json and stress.md into the output directory; exits 1 with one line naming
what failed when a count is not zero or a bound does not hold.
"""
from __future__ import annotations

import ctypes
import os
import sys
import time
from pathlib import Path

import moderngl
import numpy as np
import OpenImageIO as oiio
from tqdm import tqdm

from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.bench.report import write_json
from glint.core.atomic import atomic_write_text
from glint.core.bake_dir import Bake
from glint.core.errors import GlintError
from glint.core.manifest import Manifest
from glint.scenes import stress as stress_scenes
from glint.services import bake_scene
from glint.viewer.camera import ViewCamera, camera_path_at, clip_range, find_named, path_span
from glint.viewer.context import headless_context
from glint.viewer.cubemaps import CubeClass
from glint.viewer.gl import describe, gl_functions
from glint.viewer.renderer import Renderer

STRESS_SIZE = (96, 54)
WALKTHROUGH_SIZE = (48, 27)
STILL_FRAMES = 8             # still-camera frames per camera (8 quasi-random samples each)
ENERGY_FACTOR = 2.0          # pixel radiance <= ENERGY_FACTOR x brightest emitter radiance
FURNACE_TOLERANCE = 0.02     # relative, per pixel: the light maps' noise at scenes/stress.py FURNACE_SAMPLES (256 paths
                             # per texel, denoised) is ~1.1 %; it is noise, not bias (32 paths: 3.8 %, 1024: 0.4 %)
SCALE_TOLERANCE = 0.01       # mean relative difference to the 1 m room's image (light-map noise; before the
                             # scale fixes 2.1-2.2 %)
RSS_GROWTH_BOUND = 32 << 20  # bytes over the whole walkthrough
DRIFT_TOLERANCE = 1e-6       # relative to the image's largest value
DRIFT_FRAMES = 256
ACCUMULATION_TOLERANCE = 1e-4  # relative: float32 sums of 256 terms in a different order
WARMUP_FRAMES = 20
WALKTHROUGH_FRAMES = {"reduced": 1000, "full": 10_000}
# GL_NVX_gpu_memory_info (NVIDIA): kB
GL_GPU_MEMORY_INFO_TOTAL_AVAILABLE_MEMORY_NVX = 0x9048
GL_GPU_MEMORY_INFO_CURRENT_AVAILABLE_VIDMEM_NVX = 0x9049


# -- measurements -----------------------------------------------------------------------------------
def nonfinite(a: np.ndarray) -> tuple[int, int]:
    """(NaN count, Inf count) of an array."""
    a = np.asarray(a)
    return int(np.isnan(a).sum()), int(np.isinf(a).sum())


def bake_nonfinite(bake_dir: Path, manifest: Manifest) -> dict:
    """NaN and Inf in the bake's light maps and cube maps, read back from their files, and their
    stored precision (half float only where every value fits, bake/lightmap.py)."""
    out = {"nan": 0, "inf": 0, "files": 0, "float32_files": [], "max_value": 0.0}
    files = list(manifest.lightmaps) + list(manifest.lightmaps_back) + [o.cubemap.file for o in manifest.objects
                                                                        if o.cubemap is not None]
    for name in files:
        image = oiio.ImageInput.open(str(Path(bake_dir) / name))
        if image is None:
            raise GlintError(f"cannot read {Path(bake_dir) / name}: {oiio.geterror()}")
        try:
            fmt = str(image.spec().format)
            data = image.read_image(0, 0, 0, -1, "float")
        finally:
            image.close()
        nan, inf = nonfinite(data)
        out["nan"] += nan
        out["inf"] += inf
        out["files"] += 1
        rgb = np.asarray(data)[..., :3]
        out["max_value"] = max(out["max_value"], float(np.nanmax(np.where(np.isinf(rgb), np.nan, rgb), initial=0.0)))
        if fmt == "float":
            out["float32_files"].append(name)
    return out


def rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def allocated_bytes(root) -> int:
    """Bytes of the GL textures and buffers reachable from `root` (a Renderer): moderngl objects
    found by walking its attributes, plus the cube-map arrays viewer/cubemaps.py makes through
    ctypes (their size from their class: faces, layers, MIP levels, texel format)."""
    seen, total, stack = set(), 0, [root]
    texel = {"f1": 1, "f2": 2, "f4": 4, "u1": 1, "u2": 2, "u4": 4, "i1": 1, "i2": 2, "i4": 4}
    while stack:
        obj = stack.pop()
        if id(obj) in seen or obj is None:
            continue
        seen.add(id(obj))
        if isinstance(obj, moderngl.Buffer):
            total += obj.size
        elif isinstance(obj, (moderngl.Texture, moderngl.TextureArray, moderngl.TextureCube, moderngl.Texture3D)):
            dims = obj.size if not isinstance(obj, moderngl.TextureCube) else (*obj.size, 6)
            count = int(np.prod(dims)) * obj.components * texel.get(obj.dtype, 4)
            total += count  # (MIP levels of the few mipmapped ones not counted)
        elif isinstance(obj, CubeClass):
            base = 6 * obj.size ** 2 * len(obj.probes) * 4 * (2 if obj.dtype == "f2" else 4)
            total += base * 4 // 3  # with the MIP chain
        elif isinstance(obj, dict):
            stack.extend(obj.values())
        elif isinstance(obj, (list, tuple, set)):
            stack.extend(obj)
        elif hasattr(obj, "__dict__") and type(obj).__module__.startswith("glint."):
            stack.extend(vars(obj).values())
    return total


def gpu_memory(ctx, renderer=None) -> dict:
    """{"nvx_used_bytes", "nvx_total_bytes"} from GL_NVX_gpu_memory_info where the driver has it
    (the whole GPU's use, all processes), and glint's own allocation where a renderer is given."""
    out = {}
    if "GL_NVX_gpu_memory_info" in ctx.extensions:
        get = gl_functions(ctx)("glGetIntegerv", None, ctypes.c_uint, ctypes.POINTER(ctypes.c_int))
        total, free = ctypes.c_int(0), ctypes.c_int(0)
        get(GL_GPU_MEMORY_INFO_TOTAL_AVAILABLE_MEMORY_NVX, ctypes.byref(total))
        get(GL_GPU_MEMORY_INFO_CURRENT_AVAILABLE_VIDMEM_NVX, ctypes.byref(free))
        out["nvx_total_bytes"] = total.value * 1024
        out["nvx_used_bytes"] = (total.value - free.value) * 1024
    if renderer is not None:
        out["allocated_bytes"] = allocated_bytes(renderer)
    return out


def energy_bound(case) -> float:
    """The brightest radiance a pixel may have: the exact answer plus its tolerance where the case
    has one (the furnace), else ENERGY_FACTOR x the brightest emitter's radiance."""
    if case.expected_radiance is not None:
        return case.expected_radiance * (1 + FURNACE_TOLERANCE)
    return ENERGY_FACTOR * case.emitter_radiance


# -- one case ---------------------------------------------------------------------------------------
def bake_case(case, out: Path, jobs: int | None, denoise: bool | None = None):
    scene = load_scene(case.path)
    settings = resolve_settings(scene.bake_settings, quality="draft", jobs=jobs, denoise=denoise)
    started = time.perf_counter()
    report = bake_scene(scene, settings, out / "bakes" / f"{case.name}.bake", force=True, progress=False)
    return report, time.perf_counter() - started, len(scene.warnings)


def render_case(ctx, bake, size=STRESS_SIZE) -> dict:
    """Walkthrough and still-camera images of every camera: {camera: {"walk", "still"}} and the
    renderer's statistics."""
    images = {}
    with Renderer(ctx, bake, samples_per_frame=8, max_frames=STILL_FRAMES) as r:
        for entry in bake.model.cameras:
            camera = ViewCamera.from_manifest(entry)
            r.render(camera, *size)
            walk = r.read_linear()
            for _ in range(STILL_FRAMES):
                r.render(camera, *size, mode="converge")
            images[camera.name] = {"walk": walk, "still": r.read_linear()}
        for _ in range(3):  # a few more walkthrough frames for the medians
            r.render(camera, *size)
        stats = r.stats
        stats["gpu"] = gpu_memory(ctx, r)
    return {"images": images, "stats": stats}


def check_case(case, rendered: dict, bake_counts: dict, reference: dict | None) -> dict:
    nan = bake_counts["nan"] + sum(nonfinite(im[k])[0] for im in rendered["images"].values() for k in im)
    inf = bake_counts["inf"] + sum(nonfinite(im[k])[1] for im in rendered["images"].values() for k in im)
    peak = max((float(np.nanmax(np.where(np.isfinite(im[k]), im[k], np.nan), initial=0.0))
                for im in rendered["images"].values() for k in im), default=0.0)
    bound = energy_bound(case)
    result = {"nan": nan, "inf": inf, "max_radiance": peak, "energy_bound": bound, "failures": []}
    if nan or inf:
        result["failures"].append(f"{nan} NaN and {inf} Inf")
    if peak > bound:
        result["failures"].append(f"pixel radiance {peak:.4g} > the bound {bound:.4g} (emitter radiance "
                                  f"{case.emitter_radiance:g})")
    if case.expected_radiance is not None:
        err = max(float(np.abs(im["still"] / case.expected_radiance - 1).max()) for im in rendered["images"].values())
        result["furnace_error"] = err
        if not err <= FURNACE_TOLERANCE:
            result["failures"].append(f"furnace: radiance off by {err:.1%} of Le/(1-kd) = {case.expected_radiance:g} "
                                      f"(tolerance {FURNACE_TOLERANCE:.0%})")
    if case.max_black_fraction is not None:
        black = max(float(np.mean(np.max(im["still"], axis=-1) <= 0.0)) for im in rendered["images"].values())
        result["black_fraction"] = black
        if not black <= case.max_black_fraction:
            result["failures"].append(f"{black:.2%} of the pixels are black (bound {case.max_black_fraction:.2%})")
    if reference is not None:
        diffs = []
        for name, im in rendered["images"].items():
            ref = reference["images"][name]["still"]
            diffs.append(float((np.abs(im["still"] - ref).sum() / max(np.abs(ref).sum(), 1e-30))))
        result["scale_difference"] = max(diffs)
        if not result["scale_difference"] <= SCALE_TOLERANCE:
            result["failures"].append(f"differs from {case.compare_with} by {result['scale_difference']:.2%} "
                                      f"(tolerance {SCALE_TOLERANCE:.0%})")
    return result


# -- walkthrough ------------------------------------------------------------------------------------
def walkthrough(ctx, bake, path_name: str, frames: int, size=WALKTHROUGH_SIZE, progress=None) -> dict:
    """`frames` walkthrough frames cycling along the camera path `path_name`; memory at frame
    WARMUP_FRAMES and at the end, and frame 0's view rendered again at the end."""
    path = find_named(bake.model.camera_paths, path_name, "camera path")
    t0, t1 = path_span(path)
    near, far = clip_range(bake.model)
    period = max(min(frames, 600), 2)  # frames per trip along the path

    def view(k):
        return camera_path_at(path, t0 + (t1 - t0) * (k % period) / (period - 1), znear=near, zfar=far)

    with Renderer(ctx, bake) as r:
        r.render(view(0), *size)
        first = r.read_linear()
        start = None
        nan = inf = 0
        for k in range(1, frames):
            r.render(view(k), *size)
            if k == WARMUP_FRAMES or (start is None and k == frames - 1):
                start = {"frame": k, "rss": rss_bytes(), **gpu_memory(ctx, r)}
            if k % 50 == 0:  # reading back stalls the pipeline: sample the frames
                a, b = nonfinite(r.read_linear())
                nan, inf = nan + a, inf + b
            if progress is not None:
                progress(1)
        end = {"frame": frames - 1, "rss": rss_bytes(), **gpu_memory(ctx, r)}
        r.render(view(0), *size)
        again = r.read_linear()
        frame_ms = r.stats["gpu_ms_median"].get("total")
    scale = max(float(np.abs(first).max()), 1e-30)
    drift = float(np.abs(again - first).max()) / scale
    if start is None:
        start = end
    return {"frames": frames, "size": list(size), "path": path_name, "start": start, "end": end,
            "rss_growth": end["rss"] - start["rss"],
            "allocated_growth": end.get("allocated_bytes", 0) - start.get("allocated_bytes", 0),
            "nvx_growth": (end["nvx_used_bytes"] - start["nvx_used_bytes"]) if "nvx_used_bytes" in end else None,
            "frame0_drift": drift, "nan": nan, "inf": inf, "frame_ms": frame_ms}


def accumulation_drift(ctx, bake, camera, frames: int = DRIFT_FRAMES, size=WALKTHROUGH_SIZE) -> float:
    """Largest relative difference between the still camera's mean of `frames` one-sample frames
    and that of frames / 64 frames of 64 samples: the same samples, so equal up to rounding."""
    images = []
    for per_frame in (1, 64):
        with Renderer(ctx, bake, samples_per_frame=per_frame, max_frames=frames // per_frame) as r:
            for _ in range(frames // per_frame):
                r.render(camera, *size, mode="converge")
            images.append(r.read_linear())
    scale = max(float(np.abs(images[1]).max()), 1e-30)
    return float(np.abs(images[0] - images[1]).max()) / scale


# -- the command ------------------------------------------------------------------------------------
def add_stress_options(p) -> None:
    """`glint bench --stress` and its options (glint/bench_command.py's parser)."""
    g = p.add_argument_group("stress suite (--stress: no SCENE; the scenes of scenes/stress.py)")
    g.add_argument("--stress", action="store_true",
                   help="run the numerical stress suite instead: BSDF extremes, grazing and back-facing views, "
                        "1e5 emitters, a furnace box, scenes of 1 mm to 10 km, degenerate geometry, a big scene, "
                        "a long walkthrough; counts NaN/Inf (must be 0), checks energy bounds and drift, "
                        "reports bake s, frame ms and memory into DIR/stress.json and stress.md (default DIR: "
                        "bench-stress); exit status 1 when a check fails")
    g.add_argument("--stress-size", choices=("reduced", "full"), default="reduced",
                   help="reduced (default: minutes on a 2-core machine; 50 objects / 200k triangles) or full "
                        "(500 objects / 2 M triangles, 10,000 walkthrough frames)")
    g.add_argument("--stress-cases", metavar="C,C,...",
                   help=f"run only these cases (default: all of {', '.join(stress_scenes.CASES)})")
    g.add_argument("--walkthrough-frames", type=int, metavar="N",
                   help=f"frames of the walkthrough (default {WALKTHROUGH_FRAMES['reduced']} reduced, "
                        f"{WALKTHROUGH_FRAMES['full']} full) at {WALKTHROUGH_SIZE[0]}x{WALKTHROUGH_SIZE[1]}")


def parse_cases(text: str | None) -> list[str]:
    if not text:
        return list(stress_scenes.CASES)
    names = [s.strip() for s in text.split(",") if s.strip()]
    unknown = [n for n in names if n not in stress_scenes.CASES]
    if unknown or not names:
        raise GlintError(f"bad --stress-cases '{text}': choose from {', '.join(stress_scenes.CASES)}")
    if any(n in ("scale-1mm", "scale-10km") for n in names) and "scale-1m" not in names:
        names.append("scale-1m")  # their reference
    return list(dict.fromkeys(names))


def run_stress(args) -> int:
    size = args.stress_size
    names = parse_cases(args.stress_cases)
    frames = args.walkthrough_frames if args.walkthrough_frames is not None else WALKTHROUGH_FRAMES[size]
    if frames < 2 * WARMUP_FRAMES:
        raise GlintError(f"--walkthrough-frames {frames}: at least {2 * WARMUP_FRAMES} (memory is measured "
                         f"from frame {WARMUP_FRAMES} on)")
    out = Path(args.output) if args.output is not None else Path("bench-stress")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise GlintError(f"cannot write into {out}: {e.strerror}") from e
    cases = stress_scenes.build(out / "scenes", size, names)
    rows, rendered, walk, failures = [], {}, None, []
    ctx = headless_context()
    try:
        device = describe(ctx)
        denoise = False if getattr(args, "no_denoise", False) else None  # --no-denoise; else the preset's
        with tqdm(total=len(cases) + 1, desc="stress", unit="case", disable=None, leave=False,
                  dynamic_ncols=True) as bar:
            for case in sorted(cases, key=lambda c: c.compare_with is not None):  # references first
                bar.set_postfix_str(case.name)
                report, seconds, warnings = bake_case(case, out, args.jobs, denoise)
                bake = Bake(report.bake_dir)
                counts = bake_nonfinite(report.bake_dir, bake.model)
                rendered[case.name] = render_case(ctx, bake)
                result = check_case(case, rendered[case.name], counts, rendered.get(case.compare_with))
                stats = rendered[case.name]["stats"]
                rows.append({"case": case.name, "notes": case.notes, **result, "bake_seconds": round(seconds, 3),
                             "bake_warnings": warnings, "bake_nonfinite": counts,
                             "lightmap_format": stats["lightmap_format"], "triangles": stats["triangles_in_scene"],
                             "objects": stats["objects"], "frame_ms": stats["gpu_ms_median"].get("total"),
                             "gpu_ms_median": stats["gpu_ms_median"], "rss_bytes": rss_bytes(), "gpu": stats["gpu"],
                             "cameras": list(rendered[case.name]["images"])})
                failures += [f"{case.name}: {f}" for f in result["failures"]]
                if walk is None and case.path_name:
                    bar.set_postfix_str(f"{case.name}: walkthrough of {frames} frames")
                    inner = tqdm(total=frames - 1, desc="walkthrough", unit="frame", disable=None, leave=False)
                    with inner:
                        walk = walkthrough(ctx, bake, case.path_name, frames, progress=inner.update)
                    camera = ViewCamera.from_manifest(bake.model.cameras[0])
                    walk["case"] = case.name
                    walk["accumulation_drift"] = accumulation_drift(ctx, bake, camera)
                    failures += [f"walkthrough: {f}" for f in walkthrough_failures(walk)]
                bar.update(1)
            bar.update(1)
    finally:
        ctx.release()
    setup = {"size": size, "cases": names, "device": device, "cpus": os.cpu_count(),
             "image_size": list(STRESS_SIZE), "still_frames": STILL_FRAMES,
             "bounds": {"energy_factor": ENERGY_FACTOR, "furnace_tolerance": FURNACE_TOLERANCE,
                        "scale_tolerance": SCALE_TOLERANCE, "rss_growth_bytes": RSS_GROWTH_BOUND,
                        "frame0_drift": DRIFT_TOLERANCE, "accumulation_drift": ACCUMULATION_TOLERANCE}}
    write_report(out, setup, rows, walk, failures)
    print(f"wrote {out / 'stress.json'}, {out / 'stress.md'} ({len(rows)} case(s))")
    if failures:
        print(f"glint: stress suite failed: {'; '.join(failures)}", file=sys.stderr)
        return 1
    return 0


def walkthrough_failures(walk: dict) -> list[str]:
    fails = []
    if walk["nan"] or walk["inf"]:
        fails.append(f"{walk['nan']} NaN and {walk['inf']} Inf")
    if walk["rss_growth"] > RSS_GROWTH_BOUND:
        fails.append(f"RSS grew by {walk['rss_growth'] / 2**20:.1f} MiB (bound {RSS_GROWTH_BOUND / 2**20:g} MiB)")
    if walk["allocated_growth"] != 0:
        fails.append(f"GPU allocations grew by {walk['allocated_growth']} bytes")
    if not walk["frame0_drift"] <= DRIFT_TOLERANCE:
        fails.append(f"frame 0 rendered again differs by {walk['frame0_drift']:.3g} (tolerance {DRIFT_TOLERANCE:g})")
    if not walk["accumulation_drift"] <= ACCUMULATION_TOLERANCE:
        fails.append(f"still-camera mean drifts by {walk['accumulation_drift']:.3g} "
                     f"(tolerance {ACCUMULATION_TOLERANCE:g})")
    return fails


def _mib(x) -> str:
    return "" if x is None else f"{x / 2**20:.1f}"


def markdown(setup: dict, rows: list, walk: dict | None, failures: list) -> str:
    lines = [f"<!-- glint bench --stress ({setup['size']}); {setup['device']} -->\n",
             "| case | NaN | Inf | energy check | bake s | frame ms | RSS MiB | GPU MiB (glint) | notes |",
             "|---|---:|---:|---|---:|---:|---:|---:|---|"]
    for r in rows:
        energy = f"max {r['max_radiance']:.4g} <= {r['energy_bound']:.4g}"
        if "furnace_error" in r:
            energy += f"; furnace error {r['furnace_error']:.2%}"
        if "scale_difference" in r:
            energy += f"; vs 1 m room {r['scale_difference']:.2%}"
        if "black_fraction" in r:
            energy += f"; black {r['black_fraction']:.2%}"
        gpu = r["gpu"]
        mem = _mib(gpu.get("allocated_bytes")) + (f" (NVX used {_mib(gpu['nvx_used_bytes'])})" if "nvx_used_bytes" in gpu else "")
        notes = ", ".join(r["notes"] + [f"{r['objects']} objects, {r['triangles']} triangles", r["lightmap_format"]]
                          + (["float32: " + ", ".join(r["bake_nonfinite"]["float32_files"])]
                             if r["bake_nonfinite"]["float32_files"] else []))
        frame = "" if r["frame_ms"] is None else f"{r['frame_ms']:.1f}"
        lines.append(f"| {r['case']} | {r['nan']} | {r['inf']} | {'FAIL: ' if r['failures'] else 'ok: '}{energy} | "
                     f"{r['bake_seconds']:.1f} | {frame} | {_mib(r['rss_bytes'])} | {mem} | {notes} |")
    if walk is not None:
        lines += ["", f"**Walkthrough** ({walk['case']}, path `{walk['path']}`, {walk['frames']} frames at "
                      f"{walk['size'][0]}x{walk['size'][1]}): NaN {walk['nan']}, Inf {walk['inf']} (every 50th frame read "
                      f"back); RSS {_mib(walk['start']['rss'])} -> {_mib(walk['end']['rss'])} MiB "
                      f"(frame {walk['start']['frame']} -> {walk['end']['frame']}); GPU allocated "
                      f"{_mib(walk['start'].get('allocated_bytes'))} -> {_mib(walk['end'].get('allocated_bytes'))} MiB"
                      + (f"; NVX used growth {_mib(walk['nvx_growth'])} MiB" if walk["nvx_growth"] is not None else "")
                      + f"; frame 0 again: max difference {walk['frame0_drift']:.3g}; still-camera mean of "
                        f"{DRIFT_FRAMES} x 1 vs {DRIFT_FRAMES // 64} x 64 samples: {walk['accumulation_drift']:.3g}; "
                        f"frame {walk['frame_ms'] or 0:.1f} ms"]
    lines += ["", "Result: " + ("FAILED: " + "; ".join(failures) if failures else "passed") + "\n"]
    return "\n".join(lines)


def write_report(out: Path, setup: dict, rows: list, walk: dict | None, failures: list) -> None:
    write_json(out / "stress.json", {**setup, "cases_run": rows, "walkthrough": walk, "failures": failures})
    atomic_write_text(out / "stress.md", markdown(setup, rows, walk, failures))
