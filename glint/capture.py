"""`glint capture SCENE -o FILE`: render headless (EGL) into PNG or EXR files.

    glint capture living-room -o hall.png                        # the scene's first camera
    glint capture cornell-box -o cb.exr --size 256x256            # linear radiance, float32
    glint capture living-room -o v.png --eye 1.6,1.6,1.6 --target -1,1,-0.8 --fov 55
    glint capture living-room -o tour.png --path tour --frames 120   # tour_0000.png ...
    glint capture living-room -o still.png --converge 64             # the still camera's image
    glint capture room.glb -o red.png --set 'materials."Floor".kd=[0.6,0.1,0.1]'   # an edited material

Without --converge a frame is what the walkthrough shows (regular lobe patterns,
section 4.4.3); with --converge N it is the mean of N still-camera frames of
quasi-random samples (section 4.4.2), which converges to the exact integral of the
cube maps' light.

The scene is baked first when its bake is missing or stale (the `glint bake`
options apply; the bake directory is --bake-dir, as -o names the image here).
The same command gives byte-identical images: nothing random, no timestamps.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import re
import sys
import time
from pathlib import Path

import numpy as np

from glint.core.atomic import atomic_write_text
from glint.core.bake_dir import Bake
from glint.core.errors import GlintError
from glint.core.image_io import write_image
from glint.core.manifest import Manifest
from glint.options import SCENE_HELP, add_bake_options, add_edit_option
from glint.services import (
    check_outputs,
    check_writable,
    number,
    parse_size,
    parse_vector,
    run_bake,
)
from glint.viewer.camera import (
    DEFAULT_YFOV,
    ViewCamera,
    camera_path_at,
    clip_range,
    find_named,
    path_span,
    scene_bounds,
)
from glint.viewer.context import headless_context
from glint.viewer.progressive import DEFAULT_SAMPLES_PER_FRAME
from glint.viewer.reflectors import DEFAULT_BUDGET
from glint.viewer.renderer import GBUFFER_WAYS, Renderer
from glint.viewer.skipping import frame_section, skipping_section

EXTENSIONS = {".png": "tone-mapped sRGB, 8 bits", ".exr": "linear radiance, float32"}
DEFAULT_SIZE = "1280x720"
DEFAULT_SUPERSAMPLE = 2
DEFAULT_FRAMES = 30
STATS_REPEATS = 5  # a single capture with --stats is timed over this many renders (medians)
MAX_CONVERGE = 100_000
MAX_LOBE_SAMPLES = 256
MAX_MIRROR_BUDGET = 64
_VECTOR_ARG = re.compile(r"^-[\d.]")  # "-1,2,3" is a value, not an option


def add_capture_options(p: argparse.ArgumentParser) -> None:
    """`glint capture`'s options, on the parser glint/cli.py made for it."""
    p.description = ("Render a scene without a window or display (EGL; Mesa's llvmpipe where there is no "
                     "GPU) into a PNG (tone-mapped sRGB) or an OpenEXR file (linear radiance, float32, "
                     "before exposure and tone mapping). Bakes first when the bake is missing or stale. "
                     "The same command gives byte-identical files.")
    p.epilog = ("Vectors are X,Y,Z in metres, world space, Y up; a negative first value works as is "
                "(--eye -1,1.5,2).")
    # argparse would read "-1,2,3" as an unknown option; vectors may start with a minus sign.
    p._negative_number_matcher = _VECTOR_ARG
    p.add_argument("scene", metavar="SCENE", help=SCENE_HELP)
    p.add_argument("-o", "--output", required=True, type=Path, metavar="FILE",
                   help="image to write: .png (tone-mapped sRGB) or .exr (linear radiance, float32); "
                        "with --path, FILE gets a frame number before its extension (out_0000.png, ...)")
    p.add_argument("--size", default=DEFAULT_SIZE, metavar="WxH", help=f"image size in pixels (default {DEFAULT_SIZE})")
    view = p.add_argument_group("view (default: the scene's first camera, else a view of the whole scene)")
    view.add_argument("--camera", metavar="NAME", help="a camera of the scene (glTF or sidecar)")
    view.add_argument("--eye", metavar="X,Y,Z", help="eye position (needs --target)")
    view.add_argument("--target", metavar="X,Y,Z", help="point the eye looks at")
    view.add_argument("--up", metavar="X,Y,Z", help="up direction with --eye (default 0,1,0)")
    view.add_argument("--fov", metavar="DEG", help="vertical field of view in degrees (default: the "
                                                   "camera's; 50 with --eye or --path keys without one)")
    view.add_argument("--path", metavar="NAME", help="a camera path of the scene (sidecar [camera_paths])")
    view.add_argument("--frames", metavar="N", help=f"frames along --path, first to last key, evenly spaced "
                                                    f"in time (default {DEFAULT_FRAMES})")
    image = p.add_argument_group("image")
    image.add_argument("--exposure", default="0", metavar="EV",
                       help="exposure in stops for the PNG: radiance x 2^EV before the tone curve "
                            "(default 0; the EXR is never scaled)")
    image.add_argument("--supersample", default=str(DEFAULT_SUPERSAMPLE), metavar="N",
                       help=f"render N x N samples per pixel and average them (box filter, as a path "
                            f"tracer's pixel integral; 1 to 8, default {DEFAULT_SUPERSAMPLE})")
    specular = p.add_argument_group("view-dependent materials (section 4.4)")
    specular.add_argument("--converge", default="0", metavar="N",
                          help="render N still-camera frames of quasi-random samples per view and write their "
                               f"mean (the converged image; {DEFAULT_SAMPLES_PER_FRAME} samples per lobe and pixel "
                               "per frame); 0: the walkthrough image (default)")
    specular.add_argument("--lobe-samples", metavar="N",
                          help="samples per lobe of the walkthrough's regular patterns (default: chosen per lobe "
                               "from its width)")
    specular.add_argument("--weights", choices=("albedo", "eq4.25", "eq4.24"), default="albedo",
                          help="the walkthrough's normalised estimator: the lobe's albedo times the pattern's mean "
                               "radiance (default), or, for comparisons, the thesis' Eq. 4.25 or Eq. 4.24")
    specular.add_argument("--walkthrough-method", choices=("patterns", "filtered-importance", "split-sum"),
                          default="patterns",
                          help="regular patterns (default), or, for comparisons, Colbert-Krivanek filtered importance "
                               "sampling with as many samples, or game engines' split-sum prefiltered cube maps")
    specular.add_argument("--mirror-budget", metavar="N",
                          help=f"mirror passes per frame at most, for planar reflectors (section 4.5; default "
                               f"{DEFAULT_BUDGET}; 0: none, planar objects show their diffuse part)")
    image.add_argument("--gbuffer", choices=tuple(GBUFFER_WAYS), default="auto",
                       help="how the G-buffer is made: rasterised with every surface value per fragment, or a "
                            "visibility buffer (ids per pixel, the surface worked out once per pixel in compute); "
                            "auto (default): the visibility buffer on a GPU, the raster pass on a software "
                            "renderer, where it is faster (docs/VIEWER.md); the same image either way")
    image.add_argument("--stats", type=Path, metavar="FILE.json",
                       help="write time per pass and what was drawn and skipped as JSON")
    add_bake_options(p.add_argument_group("bake (done first when missing or stale)"), out_flags=("--bake-dir",))
    add_edit_option(p.add_argument_group("edits (the sidecar's keys, docs/SCENES.md)"))
    p.set_defaults(run=cmd_capture)


# -- argument checks (all before the bake, so mistakes cost nothing) ------------------------------


def check_arguments(args) -> dict:
    """Everything that can be checked before baking; returns the parsed values."""
    out = Path(args.output)
    ext = out.suffix.lower()
    if ext not in EXTENSIONS:
        kinds = ", ".join(f"{e} ({what})" for e, what in EXTENSIONS.items())
        raise GlintError(f"{out}: unsupported image type '{out.suffix or '(none)'}'; use {kinds}")
    width, height = parse_size(args.size)
    if args.camera is not None and args.eye is not None:
        raise GlintError("--camera and --eye both choose the view; give one of them")
    if args.path is not None and (args.camera is not None or args.eye is not None):
        raise GlintError("--path moves the camera itself; it cannot be combined with "
                         f"{'--camera' if args.camera is not None else '--eye'}")
    if args.eye is not None and args.target is None:
        raise GlintError("--eye needs --target (the point to look at)")
    for option in ("target", "up"):
        if getattr(args, option) is not None and args.eye is None:
            raise GlintError(f"--{option} only goes with --eye")
    if args.frames is not None and args.path is None:
        raise GlintError("--frames only goes with --path")
    parsed = {
        "size": (width, height),
        "fov": None if args.fov is None else math.radians(number(args.fov, "--fov", lo=0, hi=179, open_lo=True)),
        "frames": number(args.frames, "--frames", whole=True, lo=1) if args.frames is not None else DEFAULT_FRAMES,
        "exposure": number(args.exposure, "--exposure", lo=-100, hi=100),
        "supersample": number(args.supersample, "--supersample", whole=True, lo=1, hi=8),
        "converge": number(args.converge, "--converge", whole=True, lo=0, hi=MAX_CONVERGE),
        "lobe_samples": (number(args.lobe_samples, "--lobe-samples", whole=True, lo=1, hi=MAX_LOBE_SAMPLES)
                         if args.lobe_samples is not None else None),
        "mirror_budget": (number(args.mirror_budget, "--mirror-budget", whole=True, lo=0, hi=MAX_MIRROR_BUDGET)
                          if getattr(args, "mirror_budget", None) is not None else None),
    }
    if args.eye is not None:
        parsed["eye"] = parse_vector(args.eye, "--eye")
        parsed["target"] = parse_vector(args.target, "--target")
        parsed["up"] = parse_vector(args.up, "--up") if args.up is not None else np.array([0.0, 1.0, 0.0])
        if np.linalg.norm(parsed["target"] - parsed["eye"]) < 1e-9:
            raise GlintError("--eye and --target are the same point")
        if np.linalg.norm(parsed["up"]) < 1e-12:
            raise GlintError("--up must not be zero")
    check_writable(out, "-o")
    outputs = [("-o", f) for f in (frame_paths(out, parsed["frames"]) if args.path is not None else [out])]
    if args.stats is not None:
        check_writable(Path(args.stats), "--stats")
        outputs.append(("--stats", Path(args.stats)))
    check_outputs(outputs)
    parsed["outputs"] = outputs
    return parsed


# -- views ----------------------------------------------------------------------------------------
def choose_views(manifest: Manifest, args, parsed: dict) -> list:
    """The camera of every frame to render, from the bake manifest and the options."""
    cameras, paths = manifest.cameras, manifest.camera_paths
    fov = parsed["fov"]
    w, h = parsed["size"]
    if args.path is not None:
        path = find_named(paths, args.path, "camera path", "the scene has none (sidecar [camera_paths])")
        t0, t1 = path_span(path)
        n = parsed["frames"]
        near, far = clip_range(manifest)
        times = [t0 + (t1 - t0) * (k / (n - 1) if n > 1 else 0.0) for k in range(n)]
        views = [camera_path_at(path, t, znear=near, zfar=far) for t in times]
        return [_with_fov(c, fov) for c in views] if fov is not None else views
    if args.eye is not None:
        near, far = clip_range(manifest, parsed["eye"])
        return [ViewCamera.look_at(parsed["eye"], parsed["target"], parsed["up"],
                                   fov if fov is not None else DEFAULT_YFOV, znear=near, zfar=far, name="--eye")]
    if args.camera is not None:
        camera = ViewCamera.from_manifest(find_named(cameras, args.camera))
    elif cameras:
        camera = ViewCamera.from_manifest(cameras[0])
    else:
        lo, hi = scene_bounds(manifest)
        camera = ViewCamera.framing(lo, hi, w / h, fov if fov is not None else DEFAULT_YFOV)
    return [_with_fov(camera, fov) if fov is not None else camera]


def _with_fov(camera, fov: float):
    return dataclasses.replace(camera, yfov=fov)


# -- the command ----------------------------------------------------------------------------------
def frame_paths(out: Path, count: int) -> list[Path]:
    """FILE itself for one frame of a view; FILE_0000.ext ... for a sequence along a path."""
    digits = max(4, len(str(count - 1)))
    return [out.with_name(f"{out.stem}_{k:0{digits}d}{out.suffix}") for k in range(count)]


def cmd_capture(args) -> int:
    parsed = check_arguments(args)
    out = Path(args.output)
    report = run_bake(args, progress=sys.stderr.isatty(), outputs=parsed["outputs"])

    bake = Bake(report.bake_dir)
    views = choose_views(bake.model, args, parsed)
    files = frame_paths(out, len(views)) if args.path is not None else [out]
    width, height = parsed["size"]
    exr = out.suffix.lower() == ".exr"

    ctx = headless_context()
    try:
        converge = parsed["converge"]
        budget = {} if parsed["mirror_budget"] is None else {"mirror_budget": parsed["mirror_budget"]}
        renderer = Renderer(ctx, bake, supersample=parsed["supersample"], exposure=parsed["exposure"],
                            lobe_samples=parsed["lobe_samples"], weights=args.weights,
                            walkthrough=args.walkthrough_method, max_frames=max(converge, 1),
                            visibility=GBUFFER_WAYS[args.gbuffer], **budget)
        renderer.check_size(width, height)
        mode = "converge" if converge else "walkthrough"
        started = time.perf_counter()
        frames = []
        for camera, path in zip(views, files):
            for _ in range(max(converge, 1)):
                renderer.render(camera, width, height, mode=mode)
            if exr:
                write_image(path, renderer.read_linear(), half=False)
            else:
                write_image(path, renderer.read_srgb())
            if args.stats is not None:
                s = renderer.stats
                frames.append({"file": str(path), "camera": _camera_json(camera), "gpu_ms": s["gpu_ms"],
                               "objects_drawn": s["objects_drawn"], "triangles": s["triangles"],
                               "skipped": s["skipped"], "specular": s["specular"], "mirror": s["mirror"],
                               "skipping": frame_section(s)})
        seconds = time.perf_counter() - started
        if args.stats is not None:
            if len(views) == 1 and not converge:  # time a few more renders of the same view: medians, warm caches
                for _ in range(STATS_REPEATS - 1):
                    renderer.render(views[0], width, height)
            _write_stats(Path(args.stats), args, report, renderer, frames)
        renderer.release()
    finally:
        ctx.release()
    what = f"{files[0]}" if len(files) == 1 else f"{len(files)} frames {files[0].name} .. {files[-1].name}"
    print(f"wrote {what} ({width}x{height}, {EXTENSIONS[out.suffix.lower()]}, {seconds:.2f} s)")
    return 0


def _camera_json(camera) -> dict:
    return {"name": camera.name, "eye": [float(x) for x in camera.eye],
            "forward": [float(x) for x in camera.forward], "up": [float(x) for x in camera.up],
            "yfov_degrees": math.degrees(camera.yfov)}


def _write_stats(path: Path, args, report, renderer, frames: list) -> None:
    s = renderer.stats
    data = {
        "scene": args.scene,
        "bake_dir": str(report.bake_dir),
        "bake": report.status,
        "device": s["device"],
        "timing": s["timing"],
        "gbuffer": s["gbuffer"],
        "size": s["size"],
        "render_size": s["render_size"],
        "supersample": s["supersample"],
        "exposure": s["exposure"],
        "frames": len(frames),
        "gpu_ms_median": s["gpu_ms_median"],
        "frames_timed": s["frames_timed"],
        "objects": s["objects"],
        "triangles_in_scene": s["triangles_in_scene"],
        "lightmap_format": s["lightmap_format"],
        "lightmap_texels": lightmap_texels(renderer.bake.model),
        # of the last frame (per_frame has each frame's specular and mirror parts) and of the bake
        "skipping": skipping_section(s, renderer.bake.model, report.status),
        "per_frame": frames,
    }
    atomic_write_text(path, json.dumps(data, indent=1) + "\n")


def lightmap_texels(manifest: Manifest) -> dict:
    """The bake's light-map texel counts (manifest statistics.lightmaps; bake/lightmap.py): path traced
    (both sides), back sides, invalid (inside geometry), unlit, moved out of geometry
    (bake/sample_points.py) and refined by adaptive sampling (of them, enclosed: in cavities), with the
    objects that have most invalid and unlit. Counts a bake dir made before they were recorded lacks are null."""
    lm = manifest.statistics.lightmaps
    return {key: lm.get(key) for key in ("texels", "back_texels", "invalid_texels", "unlit_texels",
                                         "moved_texels", "refined_texels", "enclosed_texels", "invalid_objects",
                                         "unlit_objects")}
