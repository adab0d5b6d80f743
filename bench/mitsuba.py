"""`glint bench SCENE --mitsuba`: the viewer's images against Mitsuba 3 rendering the same scene.

    glint bench living-room --mitsuba --size 320x180 --supersample 2
    glint bench cornell-box --mitsuba --mitsuba-reference-spp 1024 --mitsuba-max-spp 64 -o out/

For each camera: a high-sample Mitsuba reference (--mitsuba-reference-spp), Mitsuba at 1, 2, 4,
... samples per pixel up to --mitsuba-max-spp with the wall-clock seconds of each render, the
viewer's walkthrough frame (median frame time over --frames after --warmup, as `glint bench`
times frames) and its converged still-camera image (--reference-samples samples per lobe and
pixel, its total wall-clock seconds). Each image's error against the Mitsuba reference: rel MSE
and PSNR as bench/bench.py defines them (its functions), FLIP when installed, over the whole
image and over the viewer's view-dependent pixels and materials (bench/bench.py
`region_masks`). Results: mitsuba.csv, mitsuba.json and mitsuba.png (log-log: rel MSE against
seconds, Mitsuba's curve and the viewer's two points) in the output directory; with --images
also every image as PNG in DIR/images.

Same scene: bench/mitsuba_scene.py converts the Scene that the bake loaded (bake/gltf_loader.py
with the sidecar: the same materials), with the section 3.3 BSDF as a Mitsuba plugin
(bench/mitsuba_bsdf.py). The viewer's error against it is everything the viewer approximates:
light maps (irradiance: no view-dependent light at a texel; lobes widened to m >= 0.02 in the bake's
paths, bake/scatter.py), cube maps and mirror buffers in place
of the scene, the lobe integration.

Pixels: both sides integrate over the pixel's area (Mitsuba: box filter; the viewer:
--supersample N x N, box-filtered). Displayed images: Mitsuba's linear radiance goes through the
viewer's own tone map (shaders/colour.glsl, exposure, ACES fit, sRGB, run by bench/glsl_eval.py),
so PSNR compares like with like.

Mitsuba variant (--mitsuba-variant, default auto): the fastest that works here, cuda_ad_rgb >
llvm_ad_rgb > scalar_rgb, each probed in a child process (a failing LLVM back end aborts the
process). The llvm variants need an LLVM that drjit can use: DRJIT_LIBLLVM_PATH when set, else the
newest libLLVM of version >= 16 found in the system library directories (on Debian 12:
`apt-get install libllvm19`; drjit's own search finds libLLVM-15 there, which aborts in code
generation). scalar_rgb always works but calls the Python BSDF once per path vertex, hundreds of
times slower than llvm_ad_rgb (docs/BENCHMARKS.md, "End to end against Mitsuba 3"). The JSON
records the variant and the library.
"""
from __future__ import annotations

import argparse
import glob
import math
import os
import re
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from glint.bench import glsl_eval, mitsuba_scene
from glint.bench.bench import check_arguments, choose_cameras, errors, flip_module, reference_batches, region_masks
from glint.bench.report import num, pyplot, save_figure, slug, write_csv, write_json, write_png
from glint.core.bake_dir import Bake
from glint.core.errors import GlintError
from glint.services import number, open_scene, run_bake
from glint.viewer.context import headless_context
from glint.viewer.gl import describe
from glint.viewer.renderer import Renderer

# Mitsuba is optional (glint[bench], and part of glint[test]): imported by the functions that need it, so the rest works without.

VARIANTS = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")  # fastest first
DEFAULT_REFERENCE_SPP = 4096
DEFAULT_MAX_SPP = 256
MAX_SPP = 1 << 20
LANES_PER_RENDER = 1 << 24  # pixels x spp of one mi.render (memory of a wavefront variant)
SHORT_RENDER = 1.0  # seconds: shorter Mitsuba renders are timed three times
MIN_LLVM = 16
PROBE_TIMEOUT = 180
SEED_CURVE = 1 << 20  # the curve's seeds, apart from the reference's 0, 1, 2, ...
INSTALL_HINT = "pip install 'glint[bench]'"
_PROBE = ("import sys, mitsuba as mi; mi.set_variant(sys.argv[1]); "
          "s = mi.cornell_box(); s['sensor']['film']['width'] = s['sensor']['film']['height'] = 8; "
          "import numpy as np; print(float(np.array(mi.render(mi.load_dict(s), spp=2)).mean()))")


def add_mitsuba_options(p) -> None:
    """The options of --mitsuba (the flag itself is glint/bench_command.py's)."""
    g = p.add_argument_group("--mitsuba: against Mitsuba 3")
    g.add_argument("--mitsuba-reference-spp", default=str(DEFAULT_REFERENCE_SPP), metavar="N",
                   help=f"samples per pixel of Mitsuba's reference (default {DEFAULT_REFERENCE_SPP})")
    g.add_argument("--mitsuba-max-spp", default=str(DEFAULT_MAX_SPP), metavar="N",
                   help=f"Mitsuba's time-error curve: 1, 2, 4, ... up to N samples per pixel (default {DEFAULT_MAX_SPP})")
    g.add_argument("--mitsuba-variant", default="auto", choices=("auto",) + VARIANTS,
                   help="Mitsuba variant (default auto: the fastest that works here, "
                        f"{' > '.join(VARIANTS)})")


# -- the Mitsuba variant -------------------------------------------------------------------------
def llvm_library() -> str | None:
    """DRJIT_LIBLLVM_PATH, else the newest system libLLVM of version >= MIN_LLVM, else None."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return os.environ["DRJIT_LIBLLVM_PATH"]
    best = None
    for path in glob.glob("/usr/lib/*/libLLVM*.so*") + glob.glob("/usr/lib/llvm-*/lib/libLLVM*.so*"):
        m = re.search(r"libLLVM(?:-|\.so\.)(\d+)", os.path.basename(path))
        if m and int(m.group(1)) >= MIN_LLVM and (best is None or int(m.group(1)) > best[0]):
            best = (int(m.group(1)), path)
    return best[1] if best else None


def probe(variant: str, llvm: str | None) -> tuple[bool, str]:
    """Whether `variant` renders a tiny scene, in a child process (an LLVM failure aborts it)."""
    env = dict(os.environ)
    if llvm and variant.startswith("llvm"):
        env["DRJIT_LIBLLVM_PATH"] = llvm
    try:
        r = subprocess.run([sys.executable, "-c", _PROBE, variant], env=env, capture_output=True, text=True,
                           timeout=PROBE_TIMEOUT)
    except subprocess.TimeoutExpired:
        return False, "timed out"
    last = (r.stderr.strip().splitlines() or [""])[-1]
    return r.returncode == 0, ("ok" if r.returncode == 0 else f"exit {r.returncode}: {last[:200]}")


def choose_variant(requested: str) -> dict:
    """Set up Mitsuba with the requested variant, or the fastest that works ("auto"); returns what
    was tried, for the JSON. GlintError when Mitsuba is missing or the requested variant fails."""
    try:
        import mitsuba as mi
    except ImportError:
        raise GlintError(f"--mitsuba needs Mitsuba 3: {INSTALL_HINT}") from None
    llvm = llvm_library()
    tried = {}
    candidates = VARIANTS if requested == "auto" else (requested,)
    chosen = None
    for variant in candidates:
        if variant not in mi.variants():
            tried[variant] = "not in this Mitsuba build"
            continue
        if variant == mi.variant():  # already running in this process
            chosen = variant
            tried[variant] = "ok (already set)"
            break
        ok, why = probe(variant, llvm)
        tried[variant] = why
        if ok:
            chosen = variant
            break
    if chosen is None:
        raise GlintError(f"no Mitsuba variant works here ({'; '.join(f'{k}: {v}' for k, v in tried.items())})")
    if chosen.startswith("llvm") and llvm and "DRJIT_LIBLLVM_PATH" not in os.environ:
        os.environ["DRJIT_LIBLLVM_PATH"] = llvm  # read when the LLVM back end starts, in set_variant
    mi.set_variant(chosen)
    return {"variant": chosen, "libllvm": llvm if chosen.startswith("llvm") else None, "tried": tried}


def curve_spps(max_spp: int) -> list[int]:
    out, s = [], 1
    while s <= max_spp:
        out.append(s)
        s *= 2
    return out


# -- displayed images: the viewer's tone map ------------------------------------------------------
def display_srgb(linear: np.ndarray, exposure: float, ctx=None) -> np.ndarray:
    """(H, W, 3) uint8: shaders/colour.glsl's aces_narkowicz and srgb_oetf of radiance x 2^EV, run by
    bench/glsl_eval.py in `ctx` (default: its own), rounded as an rgba8 image store does (what
    Renderer.read_srgb returns)."""
    h, w = linear.shape[:2]
    L = np.nan_to_num(np.asarray(linear, np.float32).reshape(-1, 3), nan=0.0, posinf=0.0, neginf=0.0)
    if ctx is None:
        ctx = glsl_eval.context()
        ctx.__enter__()  # make it current (another context may have been since); no __exit__, which
        # would leave no context current (glcontext's EGL backend), breaking the caller's next draw
    out = glsl_eval.evaluate("colour.glsl", "srgb = srgb_oetf(aces_narkowicz(L * scale));",
                             inputs={"L": L, "scale": np.full(len(L), 2.0 ** exposure, np.float32)},
                             outputs={"srgb": 3}, ctx=ctx)["srgb"]
    return np.clip(np.rint(out * 255.0), 0, 255).astype(np.uint8).reshape(h, w, 3)


# -- the command --------------------------------------------------------------------------------
def check_mitsuba_arguments(args) -> dict:
    ref = number(args.mitsuba_reference_spp, "--mitsuba-reference-spp", whole=True, lo=1, hi=MAX_SPP)
    top = number(args.mitsuba_max_spp, "--mitsuba-max-spp", whole=True, lo=1, hi=MAX_SPP)
    if ref < 2 * top:
        raise GlintError(f"--mitsuba-reference-spp {ref} must be at least twice --mitsuba-max-spp {top}: the "
                         "reference's own noise adds to every error of the curve")
    return {"reference_spp": ref, "max_spp": top}


def render_batches(spp: int, pixels: int) -> list[int]:
    """spp split into renders of at most LANES_PER_RENDER lanes (pixels x spp) each."""
    batch = max(1, min(spp, LANES_PER_RENDER // max(pixels, 1)))
    return [min(batch, spp - done) for done in range(0, spp, batch)]


def render_mitsuba(mi_scene, sensor: int, spp: int, seed: int, pixels: int, progress=None) -> np.ndarray:
    """Mean of `render_batches` renders (seeds seed, seed + 1, ...), a progress step after each."""
    total = 0.0
    for k, n in enumerate(render_batches(spp, pixels)):
        total = total + mitsuba_scene.render(mi_scene, sensor=sensor, spp=n, seed=seed + k).astype(np.float64) * n
        if progress is not None:
            progress.update(1)
    return (total / spp).astype(np.float32)


def reference_noise(one_spp: dict, ref_spp: int) -> dict:
    """{region: estimated rel MSE of the reference's own noise}. Mitsuba's error at s spp against a
    reference of R spp is about v (1/s + 1/R) (independent samples; v the per-sample variance in
    rel MSE units), so the 1-spp row gives v = e1 R / (R + 1) and the reference adds v / R to every
    error measured against it: a floor below which no image can be told apart from it."""
    return {region: e["rel_mse"] / (ref_spp + 1) for region, e in one_spp["regions"].items()}


def timed_render(mi_scene, sensor: int, spp: int, seed: int, pixels: int) -> tuple[np.ndarray, float]:
    """(image, seconds) of render_mitsuba; renders under SHORT_RENDER seconds run three times (the
    median time, the first image), as short times jitter."""
    times, image = [], None
    while not times or (len(times) < 3 and times[0] < SHORT_RENDER):
        started = time.perf_counter()
        result = render_mitsuba(mi_scene, sensor, spp, seed, pixels)
        times.append(time.perf_counter() - started)
        image = result if image is None else image
    return image, float(np.median(times))


def glint_images(ctx, bake, camera, size, parsed, progress) -> tuple[dict, dict, dict, dict]:
    """(walkthrough image, its timing, converged image, its seconds + regions) of one camera.

    Walkthrough: the median frame time after --warmup frames, as `glint bench` times. Converged:
    the wall-clock seconds of its --reference-samples still-camera frames (bench/bench.py
    `reference_batches`), after one untimed frame that compiles and uploads everything (Mitsuba's
    kernels are compiled before its timings too)."""
    batch, frames = reference_batches(parsed["reference"])
    renderer = Renderer(ctx, bake, supersample=parsed["supersample"], exposure=parsed["exposure"],
                        samples_per_frame=batch, max_frames=frames)
    try:
        renderer.check_size(*size)
        renderer.render(camera, *size, mode="converge")
        renderer.progressive.invalidate()  # start over: the timed frames are all of it
        ctx.finish()
        started = time.perf_counter()
        for _ in range(frames):
            renderer.render(camera, *size, mode="converge")
            progress.update(1)
        converged = {"linear": renderer.read_linear()}  # reading waits for the GPU
        seconds = time.perf_counter() - started
        regions = region_masks(renderer, bake)
    finally:
        renderer.release()
    renderer = Renderer(ctx, bake, supersample=parsed["supersample"], exposure=parsed["exposure"])
    try:
        for _ in range(parsed["warmup"]):
            renderer.render(camera, *size)
        renderer.timer.reset()
        for _ in range(parsed["frames"]):
            renderer.render(camera, *size)
            progress.update(1)
        walk = {"linear": renderer.read_linear()}
        stats = renderer.stats
    finally:
        renderer.release()
    ms = stats["gpu_ms_median"].get("total")
    return walk, {"ms": ms, "seconds": None if ms is None else ms / 1000.0, "timing": stats["timing"]}, \
        converged, {"seconds": seconds, "regions": regions}


def cmd_bench_mitsuba(args) -> int:
    # The sweep's --lobe-samples play no part here (the walkthrough uses the default patterns).
    parsed = check_arguments(argparse.Namespace(**{**vars(args), "lobe_samples": "1"}))
    parsed.update(check_mitsuba_arguments(args))
    setup_variant = choose_variant(args.mitsuba_variant)
    import mitsuba as mi  # present: choose_variant checked

    report = run_bake(args, progress=sys.stderr.isatty(), outputs=[("-o", parsed["output"])])
    bake = Bake(report.bake_dir)
    scene, _ = open_scene(args.scene)  # the bake's own loading path: the same materials
    size = parsed["size"]
    w, h = size
    cameras = choose_cameras(bake.model, args.camera, w / h)
    out = parsed["output"]
    flip = None if args.no_flip else flip_module()
    spps = curve_spps(parsed["max_spp"])
    ref_spp = parsed["reference_spp"]
    steps_camera = (reference_batches(parsed["reference"])[1] + parsed["frames"] + len(render_batches(ref_spp, w * h))
                    + len(spps) + 1)

    results, per_camera = [], []
    ctx = headless_context()
    try:
        scene_dict, warnings = mitsuba_scene.convert(scene, [mitsuba_scene.sensor_dict(c, w, h, 1) for c in cameras])
        mi_scene = mi.load_dict(scene_dict)
        device = describe(ctx)
        load = [round(x, 2) for x in os.getloadavg()]
        with tqdm(total=len(cameras) * steps_camera, desc="bench --mitsuba", unit="step", disable=None,
                  leave=False, dynamic_ncols=True) as progress:
            for sensor, camera in enumerate(cameras):
                progress.set_postfix_str(f"{camera.name}: glint")
                walk, walk_time, conv, conv_info = glint_images(ctx, bake, camera, size, parsed, progress)
                regions = conv_info["regions"]
                progress.set_postfix_str(f"{camera.name}: Mitsuba, compiling")
                render_mitsuba(mi_scene, sensor, 1, SEED_CURVE - 1, w * h)  # compiles the kernels: not timed
                progress.update(1)
                progress.set_postfix_str(f"{camera.name}: Mitsuba reference, {ref_spp} spp")
                started = time.perf_counter()
                reference = render_mitsuba(mi_scene, sensor, ref_spp, 0, w * h, progress)
                ref_seconds = time.perf_counter() - started
                ref = {"linear": reference, "srgb": display_srgb(reference, parsed["exposure"], ctx)}

                def row(method, image, seconds, **extra):
                    image["srgb"] = display_srgb(image["linear"], parsed["exposure"], ctx)
                    results.append({"camera": camera.name, "method": method, "seconds": seconds, **extra,
                                    "regions": errors(image, ref, regions, flip)})
                    if args.images:  # --images: the displayed images, as `glint bench --images` writes
                        name = f"{method}_{extra['spp']}spp" if "spp" in extra else method
                        write_png(out / "images" / f"{slug(camera.name)}_{name}.png", image["srgb"])

                if args.images:
                    write_png(out / "images" / f"{slug(camera.name)}_mitsuba_reference.png", ref["srgb"])

                row("glint-walkthrough", walk, walk_time["seconds"], frame_ms=walk_time["ms"])
                row("glint-converged", conv, conv_info["seconds"], samples_per_lobe=parsed["reference"])
                for spp in spps:
                    progress.set_postfix_str(f"{camera.name}: Mitsuba {spp} spp")
                    image, seconds = timed_render(mi_scene, sensor, spp, SEED_CURVE + spp, w * h)
                    row("mitsuba", {"linear": image}, seconds, spp=spp)
                    progress.update(1)
                one = next(r for r in results if r["camera"] == camera.name and r.get("spp") == 1)
                per_camera.append({"camera": camera.name, "mitsuba_reference_seconds": round(ref_seconds, 3),
                                   "reference_noise_rel_mse": reference_noise(one, ref_spp),
                                   "glint_timing": walk_time["timing"],
                                   "regions": {k: int(v.sum()) for k, v in regions.items()}})
    finally:
        ctx.release()

    setup = {
        "scene": args.scene, "bake_dir": str(report.bake_dir), "device": device, "cpus": os.cpu_count(),
        "load_average_before": load, "load_average_after": [round(x, 2) for x in os.getloadavg()],
        "size": [w, h], "supersample": parsed["supersample"], "exposure": parsed["exposure"],
        "mitsuba": {**setup_variant, "version": mi.__version__, "reference_spp": ref_spp, "curve_spp": spps,
                    "integrator": "path, unlimited depth", "pixel_filter": "box", "warnings": warnings,
                    "seconds": "wall clock of mi.render to a numpy image, kernels compiled beforehand"},
        "glint": {"walkthrough": f"median frame time over {parsed['frames']} frames after {parsed['warmup']} "
                                 "(viewer/timing.py), default lobe patterns",
                  "converged": f"still camera, {parsed['reference']} samples per lobe and pixel; wall-clock "
                               "seconds of all its frames"},
        "metrics": {"reference": f"Mitsuba, {ref_spp} spp",
                    "rel_mse": "bench/bench.py rel_mse on linear radiance",
                    "psnr_db": "bench/bench.py psnr_db of the displayed images (the viewer's tone map for both)",
                    "flip": "mean LDR-FLIP" if flip is not None else "not measured (pip install flip-evaluator)"},
        "per_camera": per_camera,
    }
    write_results(out, setup, results)
    plot(out / "mitsuba.png", setup, results)
    print(f"wrote {out / 'mitsuba.csv'}, {out / 'mitsuba.json'}, {out / 'mitsuba.png'} "
          f"({len(cameras)} camera(s); Mitsuba {setup_variant['variant']})")
    return 0


# -- output -------------------------------------------------------------------------------------
CSV_COLUMNS = ("scene", "camera", "method", "spp", "seconds", "region", "pixels", "rel_mse", "psnr_db", "flip")


def write_results(out: Path, setup: dict, results: list) -> None:
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "mitsuba.json", {**setup, "results": results})
    rows = []
    for r in results:
        for region, e in r["regions"].items():
            rows.append({"scene": setup["scene"], "camera": r["camera"], "method": r["method"],
                         "spp": r.get("spp", ""), "seconds": num(r["seconds"]), "region": region,
                         "pixels": e["pixels"], "rel_mse": num(e["rel_mse"]), "psnr_db": num(e["psnr_db"]),
                         "flip": num(e["flip"])})
    write_csv(out / "mitsuba.csv", CSV_COLUMNS, rows)


def plot(path: Path, setup: dict, results: list) -> None:
    """rel MSE against seconds, log-log, a panel per camera and region (image, view-dependent):
    Mitsuba's curve (points labelled spp) and the viewer's walkthrough and converged points."""
    plt = pyplot()
    panels = [(c, region) for c in dict.fromkeys(r["camera"] for r in results)
              for region in ("image", "view-dependent")
              if any(r["camera"] == c and r["regions"].get(region, {}).get("pixels") for r in results)]
    fig, axes = plt.subplots(1, max(len(panels), 1), squeeze=False, figsize=(4.6 * max(len(panels), 1), 4.2))
    styles = {"glint-walkthrough": ("o", "C3", "glint walkthrough frame"),
              "glint-converged": ("s", "C2", "glint converged (still camera)")}
    for ax, (camera, region) in zip(axes[0], panels):
        def points(method):
            return [(r["seconds"], r["regions"][region]["rel_mse"], r.get("spp")) for r in results
                    if r["camera"] == camera and r["method"] == method and r["seconds"]
                    and math.isfinite(r["regions"][region]["rel_mse"]) and r["regions"][region]["rel_mse"] > 0]
        pts = points("mitsuba")
        if pts:
            xs, ys, ns = zip(*pts)
            ax.plot(xs, ys, marker=".", lw=1, color="C0", label=f"Mitsuba {setup['mitsuba']['variant']} (spp)")
            for x, y, n in pts:
                ax.annotate(str(n), (x, y), textcoords="offset points", xytext=(3, 3), fontsize=7)
        for method, (marker, colour, label) in styles.items():
            for x, y, _ in points(method):
                ax.plot([x], [y], marker=marker, color=colour, ls="none", ms=7, label=label)
        floor = next((c["reference_noise_rel_mse"].get(region) for c in setup["per_camera"]
                      if c["camera"] == camera), None)
        if floor:
            ax.axhline(floor, color="0.5", ls="--", lw=1, label="the reference's own noise (estimate)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"{camera}: {region}", fontsize=9)
        ax.set_xlabel("seconds (glint walkthrough: one frame)", fontsize=8)
        ax.set_ylabel("rel MSE against Mitsuba's reference", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    w, h = setup["size"]
    fig.suptitle(f"{setup['scene']}, {w}x{h}: error against Mitsuba ({setup['mitsuba']['reference_spp']} spp) "
                 f"and time\n" + textwrap.shorten(f"glint: {setup['device']}", 60 * max(len(panels), 1)), fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
