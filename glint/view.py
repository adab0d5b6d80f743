"""`glint view SCENE`: bake when needed, then walk through the scene in a window.

glint/cli.py gives the sub-command its options with `add_view_options(parser)`.
Without a display the command stops before baking with one line that points to
`glint capture`, which renders the same frames headless.
"""
from __future__ import annotations

import argparse
import os
import shlex
import sys
import textwrap
from pathlib import Path

from glint.bake.edits import format_assignment, material_assignments, parse_assignment, save_sidecar
from glint.bake.material_mapping import GltfPbr, map_pbr
from glint.core.bake_dir import Bake
from glint.core.errors import GlintError, one_line
from glint.core.gltf_brdf import GltfMaterialParams
from glint.core.manifest import Manifest
from glint.scenes import BUILTIN, resolve
from glint.options import SCENE_HELP, add_bake_options, add_edit_option
from glint.services import background_rebake, number, parse_size, run_bake
from glint.viewer.camera import ViewCamera, find_named, scene_bounds
from glint.viewer.controls import KEY_HELP, WalkControls

DEFAULT_SIZE = "1280x720"


def add_view_options(p: argparse.ArgumentParser) -> None:
    """`glint view`'s options, on the parser glint/cli.py made for it."""
    p.description = textwrap.fill("Open a window on a scene and walk through it. The scene is baked first "
                                  "when its bake directory is missing or out of date (the bake options "
                                  "below apply). Needs a display; `glint capture` renders frames without one.", 78)
    p.epilog = "keys and mouse:\n" + KEY_HELP
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.add_argument("scene", metavar="SCENE", help=SCENE_HELP)
    p.add_argument("--size", default=DEFAULT_SIZE, metavar="WxH",
                   help=f"window size in pixels (default {DEFAULT_SIZE})")
    p.add_argument("--camera", metavar="NAME",
                   help="start at this camera of the scene (default: its first camera, else a view of the whole scene)")
    p.add_argument("--exposure", default="0", metavar="EV",
                   help="exposure in stops: radiance x 2^EV before the tone curve (default 0); a bake whose "
                        "scene would look nearly black or washed out says which value to use")
    p.add_argument("--fullscreen", action="store_true", help="start in fullscreen (F toggles it)")
    p.add_argument("--vsync", action=argparse.BooleanOptionalAction, default=True,
                   help="wait for the monitor's refresh (default: on); --no-vsync shows the real frame rate")
    add_bake_options(p, out_flags=("--bake-dir", "-o", "--out"))  # --bake-dir as capture and bench; -o kept
    add_edit_option(p)
    p.set_defaults(run=cmd_view)


def missing_display() -> str | None:
    """Why no window can open here, when that is plain without trying; else None."""
    if sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")) and \
            not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        return "no display (neither DISPLAY nor WAYLAND_DISPLAY is set)"
    return None


def no_window(scene: str, reason: str) -> GlintError:
    return GlintError(f"cannot open a window: {reason}; to render without a display use "
                      f"`glint capture {scene} -o frame.png`")


def home_camera(manifest: Manifest, aspect: float):
    """A view of the whole scene, for scenes without cameras (as `glint capture` frames them)."""
    return ViewCamera.framing(*scene_bounds(manifest), aspect)


def pbr_mapping(params: GltfMaterialParams) -> tuple[list, list]:
    """The material panel's glTF factors -> (kd, lobes as manifest dicts), by the bake's rule
    (bake/material_mapping.py `map_pbr`; the viewer may not import the bake, so it is handed in)."""
    kd, lobes, _ = map_pbr(GltfPbr.from_params(params))
    return [float(c) for c in kd], [lobe.to_dict() for lobe in lobes]


def sidecar_saver(scene_arg: str, scene_path: Path, original: list[dict], edits=()):
    """The panel's Save: the run's `--set` edits and every material the panel changed (against the
    bake's `original` entries), as assignments (bake/edits.py `material_assignments`) written into
    the scene's NAME.glint.toml (`save_sidecar`: comments kept, checked, atomic), so `glint bake`
    and `glint capture` reproduce the window. A built-in scene's file is part of glint, not the
    user's: there Save refuses, and prints the `--set` options that reproduce the edits."""
    def save(materials: list[dict]) -> None:
        changed = [(m, o) for m, o in zip(materials, original) if m != o]
        # only the keys the panel changed (material_assignments against the bake's entry)
        assignments = list(edits) + [a for m, o in changed for a in material_assignments(m["name"], m, o)]
        if scene_arg in BUILTIN:
            texts = (format_assignment(*(parse_assignment(a) if isinstance(a, str) else a)) for a in assignments)
            options = " ".join(f"--set {shlex.quote(t)}" for t in texts)
            print(f"glint: {scene_arg} is a built-in scene; its edits as options: {options}", flush=True)
            raise GlintError(f"{scene_arg} is built in and not saved; the --set options are printed in the terminal")
        path = save_sidecar(scene_path, assignments)
        print(f"glint: saved {len(changed)} edited materials to {path}", flush=True)
    return save


def _bake_child(args, progress: bool, results) -> None:
    """`bake_apart`'s child process: run_bake, its warnings summarised, the report or the one line."""
    from glint.core.errors import summarised

    try:
        with summarised():
            results.put(("report", run_bake(args, progress=progress)))
    except GlintError as e:
        results.put(("error", str(e)))
    except KeyboardInterrupt:
        results.put(("interrupted", None))


def bake_apart(args):
    """run_bake in a spawned process, so that nothing of the bake's GL lives in the window's process.
    The bake renders its cube maps with a headless EGL context; in the same process, a window opened
    after it showed only black (Mesa llvmpipe under Xvfb: the renderer drew and flipped every frame,
    F12 saved a right image, X showed nothing) while a window opened on a bake already done was
    right. A spawned child costs its start (about a second) and no GL state crosses to the window."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    results = ctx.SimpleQueue()
    child = ctx.Process(target=_bake_child, args=(args, sys.stderr.isatty(), results), name="glint-bake")
    child.start()
    try:
        child.join()
    except KeyboardInterrupt:  # the child has its own Ctrl-C (the same process group): let it clean up
        child.join()
        raise
    if results.empty():
        raise GlintError(f"the bake's process ended without a result (exit status {child.exitcode})")
    kind, value = results.get()
    if kind == "interrupted":
        raise KeyboardInterrupt
    if kind == "error":
        raise GlintError(value)
    return value


def cmd_view(args) -> int:
    width, height = parse_size(args.size)
    exposure = number(args.exposure, "--exposure", lo=-100, hi=100)
    reason = missing_display()
    if reason:  # before baking: the bake would be wasted on a machine that cannot show it
        raise no_window(args.scene, reason)

    report = bake_apart(args)
    if report.status != "up-to-date":
        print(report.summary, flush=True)

    bake = Bake(report.bake_dir)
    manifest = bake.model
    if args.camera is not None:
        find_named(manifest.cameras, args.camera)  # a one-line error before the window opens
    controls = WalkControls(manifest.cameras, manifest.camera_paths, home_camera(manifest, width / height),
                            start=args.camera)

    # here, not at the top: moderngl_window would slow every glint command's start-up (docs/VIEWER.md, "Start-up times")
    from glint.viewer.window import ViewerWindow, create_window, run

    name = manifest.scene.name
    try:
        window = create_window(size=(width, height), title=f"glint — {name}", vsync=args.vsync,
                               fullscreen=args.fullscreen)
    except Exception as e:  # pyglet/GLFW raise many kinds (no display, no GL 4.3 config, ...)
        raise no_window(args.scene, f"{type(e).__name__}: {one_line(e)}") from e
    save = sidecar_saver(args.scene, resolve(args.scene), [m.to_json() for m in manifest.materials], args.edits)
    # the worker loads the scene as edited, from where this run found it
    rebaker = background_rebake(bake.model, report.bake_dir, args.edits, scene_path=resolve(args.scene))
    try:
        viewer = ViewerWindow(ctx=window.ctx, wnd=window, bake=bake, controls=controls, name=name,
                              pbr_mapping=pbr_mapping, on_save=save, lightmap_source=rebaker, exposure=exposure,
                              on_edit=None if rebaker is None else rebaker.edit)
        run(viewer)
    finally:
        if rebaker is not None:
            rebaker.close()
    return 0

