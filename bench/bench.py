"""`glint bench SCENE`: run time against error of the ways to integrate a lobe over a cube map.

    glint bench living-room                                   # every camera, all methods, n = 1 .. 19
    glint bench material-classes --size 320x180 --reference-samples 512 --lobe-samples 3,7 -o out/

For every camera of the scene (or --camera), every method of `METHODS` and every sample count
n (per lobe and pixel; `split-sum`, which has none, once, reported as n = 1 and plotted as a
single point; its one-time prefilter's ms are in the JSON), it renders the frame the method would show, times its passes and
compares the image with the converged reference. Results: `bench.csv` (one row per camera,
method, n and image region), `bench.json` (the same, plus the set-up), `bench.md` (tables) and `bench.png` (PSNR
against the specular pass's milliseconds, one curve per method, points labelled n) in the
output directory; docs/BENCHMARKS.md has the measured tables and how to read them.

Reference: the renderer's still camera (section 4.4.2) with --reference-samples unfiltered
quasi-random importance samples per lobe and pixel (R2 sequence, per-pixel Cranley-Patterson
rotation, Eq. 4.4 weights): the converged integral of the very cube maps the methods sample,
so the error is that of the lobe integration alone. The `qmc` method's n samples are the
first n of the reference's (its error is thereby underestimated by a factor (1 - n/R)^2 in
MSE: below 4% for n = 19, R = 1024).

Error metrics, per region (`REGIONS`):
- psnr_db: 10 log10(255^2 / MSE) of the displayed 8-bit sRGB images (exposure, the ACES tone
  curve, sRGB; what `glint capture -o x.png` writes), as the thesis' PSNR is of displayed
  images. Identical images: infinite (CSV `inf`, JSON null).
- rel_mse: mean over pixels and channels of (x - r)^2 / (r^2 + 0.01) on linear radiance
  (W/(m^2 sr)), the relative MSE of the rendering literature (the 0.01 keeps black pixels
  from dominating).
- flip: mean of NVIDIA's FLIP error map (LDR-FLIP on the sRGB images, 67 pixels per degree)
  over the region, when the `flip-evaluator` package is installed; empty otherwise.

Timing: after --warmup frames, the median over --frames frames of each pass's time from the
renderer's timers (viewer/timing.py: GPU timer queries; on llvmpipe the wall clock between
glFinish calls). The timed frames go round-robin over all methods and n of a camera (one
renderer each, all alive), so other load on the machine slows them alike. The plot's x axis is
the `specular` pass alone, the only pass that differs between the methods; `frame` is the sum of
the passes that ran. A `qmc` frame is a
still-camera frame: it reuses the G-buffer and the mirror buffers (no `gbuffer` or `mirror_*`
time) and adds `accumulate`.
"""
from __future__ import annotations

import math
import os
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from glint.bench.report import json_safe, num, pyplot, save_figure, slug, write_csv, write_json, write_png
from glint.core.atomic import atomic_write_text
from glint.core.bake_dir import Bake
from glint.core.constants import MIRROR_PLANE_COS
from glint.core.errors import GlintError
from glint.core.manifest import Manifest
from glint.services import number, parse_size, run_bake
from glint.viewer.camera import ViewCamera, find_named, scene_bounds
from glint.viewer.context import headless_context
from glint.viewer.gl import describe
from glint.viewer.passes.gbuffer import read_gbuffer
from glint.viewer.renderer import Renderer
from glint.viewer.skipping import bake_section, frame_section, markdown_table
from glint.viewer.timing import PassTimer

DEFAULT_SAMPLES = (1, 3, 5, 7, 9, 11, 15, 19)
DEFAULT_SIZE = "640x360"
DEFAULT_REFERENCE_SAMPLES = 1024
DEFAULT_FRAMES = 20
DEFAULT_WARMUP = 3
MAX_FRAMES = 60            # the renderer's timers keep the last 60 frames (viewer/timing.py PassTimer)
MAX_SAMPLES = 256          # per lobe and pixel (glint/capture.py MAX_LOBE_SAMPLES)
MAX_REFERENCE_SAMPLES = 1 << 20
REFERENCE_BATCH = 64       # reference samples per still-camera frame
REL_MSE_EPSILON = 0.01     # (W/(m^2 sr))^2 in rel_mse's denominator
FLIP_PPD = 67.0            # FLIP's default viewing condition: pixels per degree
MIN_REGION_PIXELS = 16     # smaller per-material regions are not reported
EXTRA_KEYS = ("lookups_per_pixel", "pixels_with_lobes", "samples_per_lobe", "skipping", "prefilter_ms")
# The renderer's timed passes (viewer/renderer.py), in frame order: the CSV's columns; the JSON has
# whatever the renderer timed.
PASSES = ("mirror_passes", "mirror_mips", "gbuffer", "occlusion_queries", "shading", "specular", "resolve",
          "accumulate", "tonemap")
_LIST = re.compile(r"[,\s]+")


# -- methods ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Method:
    key: str
    label: str
    walkthrough: str | None   # Renderer(walkthrough=...) for a walkthrough frame; None: still camera
    weights: str = "albedo"
    planar_pattern: str = "auto"  # Renderer(planar_pattern=...): "ring" forces the single ring on planar lobes
    ignores_n: bool = False  # one look-up per lobe whatever n: run once, reported as n = 1
    footprint: str = "moment"  # Renderer(footprint=...): "thesis" filters each look-up by A / n (Eq. 4.16)
    auto_samples: bool = False  # Renderer(lobe_samples=None): each lobe's n chosen from its width, as shipped

    def samples(self, ns) -> tuple:
        """The n of the sweep this method runs at."""
        return (1,) if self.ignores_n else tuple(ns)

    def renderer(self, ctx, bake, n: int, supersample: int, exposure: float):
        if self.walkthrough is None:  # one still-camera frame of n quasi-random samples per lobe
            return Renderer(ctx, bake, supersample=supersample, exposure=exposure, samples_per_frame=n,
                            max_frames=1)
        return Renderer(ctx, bake, supersample=supersample, exposure=exposure,
                        lobe_samples=None if self.auto_samples else n, weights=self.weights, walkthrough=self.walkthrough, planar_pattern=self.planar_pattern,
                        footprint=self.footprint)

    def frame(self, renderer, camera, width: int, height: int) -> None:
        if self.walkthrough is None:
            renderer.progressive.invalidate()  # start over: frame 0, samples 0 .. n-1
            renderer.render(camera, width, height, mode="converge")
        else:
            renderer.render(camera, width, height)


METHODS = {m.key: m for m in (
    Method("patterns", "ours: regular patterns + MIP, albedo-normalised", "patterns"),
    # The walkthrough as `glint view` and `glint capture` run it: every lobe's n chosen from its width
    # (viewer/lobe_patterns.py; JSON samples_per_lobe), so the sweep's n means nothing: one point.
    Method("patterns-auto", "ours as shipped: n per lobe from its width", "patterns", ignores_n=True,
           auto_samples=True),
    Method("patterns-eq4.24", "ours with Eq. 4.24 weights", "patterns", "eq4.24"),
    # The thesis' Eq. 4.25 normalisation that the albedo-normalised mean replaced (viewer/lobe_albedo.py).
    Method("patterns-eq4.25", "ours with Eq. 4.25 weights (the thesis')", "patterns", "eq4.25"),
    # The thesis' own MIP footprint per cube-map look-up, A / n (Eq. 4.16), that "patterns" replaced.
    Method("patterns-thesis", "ours with the thesis' footprint A / n (Eq. 4.16)", "patterns", footprint="thesis"),
    Method("patterns-moment-all", "ours with the second-moment footprint on transmission lobes too", "patterns",
           footprint="moment-all"),
    # Planar reflectors: the single ring of curved objects instead of the multi-ring
    # (section 4.5.3); the same as "patterns" on curved objects. Not in the default sweep.
    Method("patterns-ring", "ours with the single ring on planar reflectors", "patterns", planar_pattern="ring"),
    Method("filtered-is", "Colbert-Krivanek filtered importance sampling", "filtered-importance"),
    Method("qmc", "unfiltered per-pixel QMC (still camera, one frame)", None),
    # What game engines and glTF viewers use (viewer/split_sum.py): prefiltered when its renderer
    # is made (the JSON's prefilter_ms), then one look-up per lobe and pixel, so n means nothing.
    Method("split-sum", "split-sum prefiltered cube map (game engines, glTF viewers)", "split-sum", ignores_n=True),
)}
DEFAULT_METHODS = ("patterns", "patterns-auto", "patterns-thesis", "patterns-eq4.24", "filtered-is", "qmc", "split-sum")


# -- options ----------------------------------------------------------------------------------------
def parse_list(text: str, option: str, *, lo: int, hi: int) -> list[int]:
    parts = [s for s in _LIST.split(text or "") if s]
    if not parts:
        raise GlintError(f"bad {option} '{text}': expected whole numbers separated by commas, e.g. 3,7,19")
    values = []
    for s in parts:
        try:
            v = int(s)
        except ValueError:
            raise GlintError(f"bad {option} '{text}': '{s}' is not a whole number") from None
        if not lo <= v <= hi:
            raise GlintError(f"bad {option} '{text}': {v} is not from {lo} to {hi}")
        values.append(v)
    return sorted(set(values))


def parse_methods(text: str) -> list[str]:
    keys = [s for s in _LIST.split(text or "") if s]
    if not keys:
        raise GlintError(f"bad --methods '{text}': name at least one of {', '.join(METHODS)}")
    for k in keys:
        if k not in METHODS:
            raise GlintError(f"unknown method '{k}' in --methods; choose from {', '.join(METHODS)}")
    return list(dict.fromkeys(keys))


def check_arguments(args) -> dict:
    samples = parse_list(args.lobe_samples, "--lobe-samples", lo=1, hi=MAX_SAMPLES)
    parsed = {
        "size": parse_size(args.size),
        "samples": samples,
        "methods": parse_methods(args.methods),
        "reference": number(args.reference_samples, "--reference-samples", whole=True, lo=1,
                             hi=MAX_REFERENCE_SAMPLES),
        "frames": number(args.frames, "--frames", whole=True, lo=1, hi=MAX_FRAMES),
        "warmup": number(args.warmup, "--warmup", whole=True, lo=0, hi=10_000),
        "supersample": number(args.supersample, "--supersample", whole=True, lo=1, hi=8),
        "exposure": number(args.exposure, "--exposure", lo=-100, hi=100),
    }
    if parsed["reference"] < max(samples):
        raise GlintError(f"--reference-samples {parsed['reference']} is fewer than the largest n of --lobe-samples "
                         f"({max(samples)}): the reference must converge further than what it judges")
    out = Path(args.output) if args.output is not None else Path(f"bench-{Path(args.scene).stem}")
    if out.exists() and not out.is_dir():
        raise GlintError(f"-o {out}: exists and is not a directory")
    parent = out if out.exists() else out.parent if str(out.parent) else Path(".")
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not os.access(parent, os.W_OK):
        raise GlintError(f"cannot write into {out}: permission denied")
    parsed["output"] = out
    return parsed


def choose_cameras(manifest: Manifest, names: list[str] | None, aspect: float) -> list:
    cameras = manifest.cameras
    if names:
        chosen = []
        for name in dict.fromkeys(names):
            chosen.append(ViewCamera.from_manifest(find_named(cameras, name)))
        return chosen
    if cameras:
        return [ViewCamera.from_manifest(c) for c in cameras]
    lo, hi = scene_bounds(manifest)
    camera = ViewCamera.framing(lo, hi, aspect)
    camera.name = "overview"
    return [camera]


# -- images and regions -----------------------------------------------------------------------------


def region_masks(renderer, bake) -> dict[str, np.ndarray]:
    """{region: (H, W) bool} of the renderer's last frame, from its G-buffer: "image" (every pixel),
    "view-dependent" (the pixels the specular pass shades, as shaders/specular_work.glsl
    `specular_list` picks them: a material with lobes, not a dark back face, on an object with a
    cube map or on a planar reflector whose plane got a mirror pass this frame, where the surface
    faces that plane) and "material:NAME" for each such material. With supersampling a pixel
    belongs where most of its N x N samples do."""
    g = read_gbuffer(renderer.gbuffer.targets)
    h, w = g["material"].shape
    dark, material, obj, normal, drawn = g["dark"], g["material"], g["object"], g["normal"], g["drawn"]
    manifest = bake.model
    objects = manifest.objects
    lobed = np.array([bool(m.lobes) for m in manifest.materials] + [False])
    cubed = np.array([renderer.scene.cubemaps.has_cubemap(i) for i in range(len(objects))] + [False])
    # Planar reflectors in this frame's mirror passes, and their planes' normals.
    mirrored = {name for p in renderer.stats.get("mirror", {}).get("passes", []) for name in p.get("reflectors", ())}
    plane_normal = np.zeros((len(objects) + 1, 3), np.float32)
    in_pass = np.zeros(len(objects) + 1, bool)
    for i, o in enumerate(objects):
        if o.name in mirrored and o.plane is not None:
            in_pass[i] = True
            plane_normal[i] = o.plane.normal
    material = np.where(drawn, np.minimum(material, len(lobed) - 1), len(lobed) - 1)
    obj = np.where(drawn, np.minimum(obj, len(cubed) - 1), len(cubed) - 1)
    facing = np.einsum("hwc,hwc->hw", normal, plane_normal[obj]) >= MIRROR_PLANE_COS
    specular = drawn & lobed[material] & ~dark & (cubed[obj] | (in_pass[obj] & facing))
    k = renderer.supersample
    out_h, out_w = h // k, w // k

    def pool(mask):  # GL rows (bottom first) -> image rows, majority of the k x k samples
        m = mask.reshape(out_h, k, out_w, k).mean(axis=(1, 3)) > 0.5
        return np.ascontiguousarray(m[::-1])

    regions = {"image": np.ones((out_h, out_w), bool), "view-dependent": pool(specular)}
    for index, m in enumerate(manifest.materials):
        if m.lobes:
            mask = pool(specular & (material == index))
            if mask.sum() >= MIN_REGION_PIXELS:
                regions[f"material:{m.name}"] = mask
    return regions


def psnr_db(test_srgb: np.ndarray, ref_srgb: np.ndarray, mask: np.ndarray) -> float:
    """PSNR of 8-bit images over the masked pixels (all channels); inf where they are equal."""
    d = test_srgb[mask].astype(np.float64) - ref_srgb[mask].astype(np.float64)
    if not d.size:
        return float("nan")
    mse = float(np.mean(d * d))
    return math.inf if mse == 0.0 else 10.0 * math.log10(255.0 ** 2 / mse)


def rel_mse(test: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> float:
    t, r = test[mask].astype(np.float64), ref[mask].astype(np.float64)
    if not t.size:
        return float("nan")
    return float(np.mean((t - r) ** 2 / (r * r + REL_MSE_EPSILON)))


def flip_module():
    """NVIDIA's `flip_evaluator`, or None where it is not installed."""
    try:
        import flip_evaluator  # optional (glint[flip]): looked for only when a run measures FLIP
    except ImportError:
        return None
    return flip_evaluator


def flip_map(flip, test_srgb: np.ndarray, ref_srgb: np.ndarray) -> np.ndarray:
    """(H, W) LDR-FLIP error of two 8-bit sRGB images."""
    ref = np.ascontiguousarray(ref_srgb, np.float32) / 255.0
    test = np.ascontiguousarray(test_srgb, np.float32) / 255.0
    error, _, _ = flip.evaluate(ref, test, "LDR", inputsRGB=True, applyMagma=False, computeMeanError=False,
                                parameters={"ppd": FLIP_PPD})
    return np.asarray(error, np.float64).reshape(ref.shape[:2])


def errors(test: dict, ref: dict, regions: dict, flip=None) -> dict:
    """{region: {pixels, psnr_db, rel_mse, flip}} of a test image against the reference; each image
    a dict with "srgb" (H, W, 3) uint8 and "linear" (H, W, 3) float32."""
    fmap = flip_map(flip, test["srgb"], ref["srgb"]) if flip is not None else None
    out = {}
    for name, mask in regions.items():
        out[name] = {"pixels": int(mask.sum()),
                     "psnr_db": psnr_db(test["srgb"], ref["srgb"], mask),
                     "rel_mse": rel_mse(test["linear"], ref["linear"], mask),
                     "flip": float(fmap[mask].mean()) if fmap is not None and mask.any() else None}
    return out


# -- the command ------------------------------------------------------------------------------------
def reference_batches(total: int) -> tuple[int, int]:
    """(samples per frame, frames) of a reference of `total` samples: the largest batch of at most
    REFERENCE_BATCH that divides it, so the count is exact."""
    batch = max(d for d in range(1, min(total, REFERENCE_BATCH) + 1) if total % d == 0)
    return batch, total // batch


def render_reference(ctx, bake, camera, size, parsed, progress) -> tuple[dict, dict, float]:
    """The converged image of `camera` (--reference-samples QMC samples per lobe and pixel),
    its regions and the seconds it took."""
    batch, frames = reference_batches(parsed["reference"])
    started = time.perf_counter()
    renderer = Renderer(ctx, bake, supersample=parsed["supersample"], exposure=parsed["exposure"],
                        samples_per_frame=batch, max_frames=frames)
    try:
        for _ in range(frames):
            renderer.render(camera, *size, mode="converge")
            progress.update(1)
        image = {"srgb": renderer.read_srgb(), "linear": renderer.read_linear()}
        regions = region_masks(renderer, bake)
    finally:
        renderer.release()
    return image, regions, time.perf_counter() - started


def sweep(ctx, bake, runs: list, camera, size, parsed, progress) -> list[tuple[dict, dict]]:
    """(image, timing) of every (method, n) in `runs` for one camera. All the renderers stay alive
    and the timed frames go round-robin over them, so whatever else the machine does at the
    time slows every method alike; then each one's medians and its last frame's image."""
    renderers = []
    try:
        for method, n in runs:
            progress.set_postfix_str(f"{camera.name}: {method.key} n={n}")
            renderer = method.renderer(ctx, bake, n, parsed["supersample"], parsed["exposure"])
            renderers.append(renderer)
            renderer.check_size(*size)
            for _ in range(parsed["warmup"]):
                method.frame(renderer, camera, *size)
            renderer.timer.reset()
            progress.update(1)
        progress.set_postfix_str(f"{camera.name}: timing")
        for _ in range(parsed["frames"]):
            for (method, _), renderer in zip(runs, renderers):
                method.frame(renderer, camera, *size)
            progress.update(1)
        out = []
        for renderer in renderers:
            stats = renderer.stats
            median = stats["gpu_ms_median"]
            timing = {name: ms for name, ms in median.items() if name != "total"}
            timing["frame"] = median.get("total")
            spec = stats["specular"]
            timing["lookups_per_pixel"] = spec["lookups_per_pixel_with_lobes"]
            timing["pixels_with_lobes"] = spec["pixels_with_lobes"]
            timing["samples_per_lobe"] = [entry["samples"] for entry in spec["samples_per_lobe"]]
            timing["prefilter_ms"] = stats.get("split_sum", {}).get("prefilter_ms")  # one-time, split-sum only
            timing["skipping"] = frame_section(stats)  # viewer/skipping.py
            out.append(({"srgb": renderer.read_srgb(), "linear": renderer.read_linear()}, timing))
        return out
    finally:
        for renderer in renderers:
            renderer.release()


def run_sweep(args) -> int:
    """`glint bench SCENE`: the sweep of the module docstring (glint/bench_command.py chooses it)."""
    parsed = check_arguments(args)
    report = run_bake(args, progress=sys.stderr.isatty(), outputs=[("-o", parsed["output"])])
    bake = Bake(report.bake_dir)
    size = parsed["size"]
    cameras = choose_cameras(bake.model, args.camera, size[0] / size[1])
    out = parsed["output"]
    flip = None if args.no_flip else flip_module()
    methods = [METHODS[k] for k in parsed["methods"]]
    steps = (reference_batches(parsed["reference"])[1] + sum(len(m.samples(parsed["samples"])) for m in methods)
             + parsed["frames"])

    ctx = headless_context()
    results, references, skipping = [], [], {}
    try:
        device, timing_method = describe(ctx), PassTimer(ctx).description
        load = [round(x, 2) for x in os.getloadavg()]  # other work on the machine skews the times
        with tqdm(total=len(cameras) * steps, desc="bench", unit="step",
                  disable=None, leave=False, dynamic_ncols=True) as progress:
            for camera in cameras:
                progress.set_postfix_str(f"{camera.name}: reference")
                ref, regions, seconds = render_reference(ctx, bake, camera, size, parsed, progress)
                references.append({"camera": camera.name, "seconds": round(seconds, 3),
                                   "regions": {k: int(v.sum()) for k, v in regions.items()}})
                out.mkdir(parents=True, exist_ok=True)
                if args.images:
                    write_png(out / "images" / f"{slug(camera.name)}_reference.png", ref["srgb"])
                runs = [(method, n) for method in methods for n in method.samples(parsed["samples"])]
                for (method, n), (image, timing) in zip(runs, sweep(ctx, bake, runs, camera, size, parsed, progress)):
                    # the work skipped in the camera's frame (the same tiles and passes for every method)
                    skipping.setdefault(camera.name, {**timing["skipping"], **bake_section(bake.model, report.status)})
                    results.append({"camera": camera.name, "method": method.key, "n": n,
                                    "gpu_ms": {k: v for k, v in timing.items() if k not in EXTRA_KEYS},
                                    "lookups_per_pixel": timing["lookups_per_pixel"],
                                    "pixels_with_lobes": timing["pixels_with_lobes"],
                                    "samples_per_lobe": timing["samples_per_lobe"],
                                    **({"prefilter_ms": timing["prefilter_ms"]}
                                       if timing["prefilter_ms"] is not None else {}),
                                    "regions": errors(image, ref, regions, flip)})
                    if args.images:
                        write_png(out / "images" / f"{slug(camera.name)}_{method.key}_n{n}.png", image["srgb"])
    finally:
        ctx.release()

    setup = {
        "scene": args.scene, "bake_dir": str(report.bake_dir), "device": device, "timing": timing_method,
        "cpus": os.cpu_count(), "load_average_before": load, "load_average_after": [round(x, 2) for x in os.getloadavg()],
        "size": list(size), "supersample": parsed["supersample"], "exposure": parsed["exposure"],
        "samples": parsed["samples"], "frames_timed": parsed["frames"], "warmup_frames": parsed["warmup"],
        "methods": {m.key: m.label for m in methods},
        "reference": {"samples_per_lobe_and_pixel": parsed["reference"],
                      "estimator": "still-camera QMC: R2 sequence with a per-pixel Cranley-Patterson rotation, "
                                   "Eq. 4.4 weights, unfiltered cube-map look-ups",
                      "per_camera": references},
        "skipping": skipping,
        "metrics": {"psnr_db": "10 log10(255^2 / MSE) of the displayed 8-bit sRGB images; null: identical (inf)",
                    "rel_mse": f"mean of (x - r)^2 / (r^2 + {REL_MSE_EPSILON}) on linear radiance",
                    "flip": (f"mean LDR-FLIP ({flip.__name__}, {FLIP_PPD:g} ppd) over the region"
                             if flip is not None else "not measured (pip install flip-evaluator)"),
                    "gpu_ms": "median per pass over the timed frames; frame = the sum of the passes that ran"},
    }
    write_results(out, setup, results)
    plot(out / "bench.png", setup, results)
    print(f"wrote {out / 'bench.csv'}, {out / 'bench.json'}, {out / 'bench.md'}, {out / 'bench.png'} "
          f"({len(cameras)} camera(s) x {len(methods)} method(s) x {len(parsed['samples'])} sample count(s))")
    return 0


# -- output -----------------------------------------------------------------------------------------
CSV_COLUMNS = ("scene", "camera", "method", "n", "region", "pixels", "psnr_db", "rel_mse", "flip",
               "ms_specular", "ms_frame", *(f"ms_{p}" for p in PASSES if p != "specular"), "lookups_per_pixel")


def csv_rows(setup: dict, results: list) -> list[dict]:
    rows = []
    for r in results:
        for region, e in r["regions"].items():
            ms = r["gpu_ms"]
            row = {"scene": setup["scene"], "camera": r["camera"], "method": r["method"], "n": r["n"],
                   "region": region, "pixels": e["pixels"], "psnr_db": num(e["psnr_db"]),
                   "rel_mse": num(e["rel_mse"]), "flip": num(e["flip"]), "ms_specular": num(ms.get("specular")),
                   "ms_frame": num(ms.get("frame")), "lookups_per_pixel": num(r["lookups_per_pixel"])}
            for p in PASSES:
                if p != "specular":
                    row[f"ms_{p}"] = num(ms.get(p))
            rows.append(row)
    return rows


def markdown(setup: dict, results: list) -> str:
    """The results as Markdown tables: per camera, PSNR (dB) per region and FLIP of the
    view-dependent pixels (methods x n), then the specular pass's and the frame's milliseconds."""
    ns = sorted({*setup["samples"], *(r["n"] for r in results)})  # split-sum's n = 1 may be outside the sweep
    head = "| method | " + " | ".join(f"n = {n}" for n in ns) + " |\n|---|" + "---:|" * len(ns) + "\n"

    def table(camera, cell) -> str:
        rows = []
        for method in setup["methods"]:
            by_n = {r["n"]: r for r in results if r["camera"] == camera and r["method"] == method}
            rows.append(f"| {method} | " + " | ".join(cell(by_n[n]) if n in by_n else "" for n in ns) + " |")
        return head + "\n".join(rows) + "\n"

    def fmt(x, spec):
        return "inf" if x is None and spec == "psnr" else "" if x is None else f"{x:{spec}}"

    w, h = setup["size"]
    out = [f"<!-- glint bench {setup['scene']}: {w}x{h}, reference "
           f"{setup['reference']['samples_per_lobe_and_pixel']} samples; {setup['device']} -->\n"]
    for camera in dict.fromkeys(r["camera"] for r in results):
        regions = list(dict.fromkeys(k for r in results if r["camera"] == camera for k in r["regions"]))
        for region in regions:
            pixels = next(r["regions"][region]["pixels"] for r in results if r["camera"] == camera
                          and region in r["regions"])
            out.append(f"**{camera}, {region}** ({pixels} pixels): PSNR, dB\n\n")
            out.append(table(camera, lambda r: fmt(r["regions"].get(region, {}).get("psnr_db"), ".1f")
                             if region in r["regions"] else "") + "\n")
        if any(r["regions"]["view-dependent"]["flip"] is not None for r in results if r["camera"] == camera):
            out.append(f"**{camera}, view-dependent**: FLIP (mean, lower is better)\n\n")
            out.append(table(camera, lambda r: fmt(r["regions"]["view-dependent"]["flip"], ".3f")) + "\n")
        out.append(f"**{camera}**: specular pass / whole frame, ms (median of {setup['frames_timed']})\n\n")
        out.append(table(camera, lambda r: f"{fmt(r['gpu_ms'].get('specular'), '.1f')} / "
                                           f"{fmt(r['gpu_ms'].get('frame'), '.1f')}") + "\n")
    if setup.get("skipping"):
        out.append("**Skipped work** (per camera: its frame, the same for every method; viewer/skipping.py)\n\n")
        out.append(markdown_table(setup["skipping"]))
    return "".join(out)


def write_results(out: Path, setup: dict, results: list) -> None:
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "bench.json", {**setup, "results": results})
    write_csv(out / "bench.csv", CSV_COLUMNS, csv_rows(setup, results))
    atomic_write_text(out / "bench.md", markdown(json_safe(setup), json_safe(results)))


def plot(path: Path, setup: dict, results: list, columns: int = 3) -> None:
    """PSNR against the specular pass's ms: a panel per camera and region (the view-dependent
    pixels, then each material), a curve per method, points labelled n."""
    plt = pyplot()
    panels = []
    for camera in dict.fromkeys(r["camera"] for r in results):
        regions = dict.fromkeys(k for r in results if r["camera"] == camera for k in r["regions"])
        panels += [(camera, region) for region in regions if region != "image"]
    cols = max(1, min(columns, len(panels)))
    rows = max(1, -(-len(panels) // cols))
    fig, axes = plt.subplots(rows, cols, squeeze=False, figsize=(4.2 * cols, 3.4 * rows + 0.9))
    markers = "osD^vP*X"
    for ax, (camera, region) in zip(axes.ravel(), panels):
        for k, method in enumerate(setup["methods"]):
            pts = [(r["gpu_ms"].get("specular"), r["regions"][region]["psnr_db"], r["n"]) for r in results
                   if r["camera"] == camera and r["method"] == method and region in r["regions"]]
            pts = [(x, y, n) for x, y, n in pts if x is not None and y is not None and math.isfinite(y)]
            if not pts:
                continue
            xs, ys, _ = zip(*pts)
            ax.plot(xs, ys, marker=markers[k % len(markers)], ms=4, lw=1, label=setup["methods"][method])
            for x, y, n in pts:
                ax.annotate(str(n), (x, y), textcoords="offset points", xytext=(3, 3), fontsize=7)
        ax.set_title(f"{camera}: {region.removeprefix('material:')}", fontsize=9)
        ax.set_xlabel("specular pass, ms (median)", fontsize=8)
        ax.set_ylabel("PSNR, dB (displayed sRGB)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(panels):]:
        ax.set_visible(False)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(2, max(len(labels), 1)), fontsize=8, frameon=False)
    w, h = setup["size"]
    fig.suptitle(f"{setup['scene']}, {w}x{h}: PSNR against the reference of "
                 f"{setup['reference']['samples_per_lobe_and_pixel']} QMC samples per lobe and pixel; "
                 f"points: n samples per lobe\n{setup['device']}", fontsize=9)
    fig.tight_layout(rect=(0, 0.9 / (3.4 * rows + 0.9) * 0.9, 1, 1 - 0.45 / (3.4 * rows + 0.9)))
    save_figure(fig, path, dpi=110)
