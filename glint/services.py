"""Services the commands share: open a scene, run or reuse its bake, the common options.

Below the commands (glint/cli.py, capture.py, view.py and the measurement tools in bench/),
above the bake and the viewer: `bake_scene` hands the bake its one GPU stage
(glint/cubemap_stage.py), which is how the bake runs without importing the renderer.
"""
from __future__ import annotations

import math
import os
import re
import sys
from pathlib import Path

import numpy as np

from glint.bake import pipeline
from glint.bake.edits import edited_bake_dir, edited_bake_keys
from glint.bake.gltf_loader import load_scene
from glint.bake.lightmap import INVALID_WARN_SHARE, UNLIT_WARN_SHARE
from glint.bake.pipeline import BakeReport
from glint.bake.settings import BakeSettings, resolve_settings
from glint.core.bake_dir import check_bake_target, default_bake_dir, read_model, remove_dead_temporaries
from glint.core.errors import GlintError, summarised
from glint.core.manifest import Manifest
from glint.core.scene import Scene
from glint.scenes import BUILTIN, resolve
from glint.viewer.camera import find_named

def open_scene(scene_arg: str, edits: list = ()) -> tuple[Scene, str | None]:
    """SCENE argument (and `--set` assignments) -> (Scene, builtin name or None)."""
    return load_scene(resolve(scene_arg), edits), (scene_arg if scene_arg in BUILTIN else None)


def render_cubemaps(*args, **kwargs):
    """glint.cubemap_stage.render_cubemaps, imported when a bake has cube maps to render: the
    renderer and moderngl are no cost to a bake without any (or one that is up to date)."""
    from glint.cubemap_stage import render_cubemaps as render

    return render(*args, **kwargs)


# The module whose tasks render_cubemaps runs: a `local:N` cluster's workers import it before they arrive
# (bake/pipeline.py bake_scene's `worker_modules`). A name, not the module: importing it here would load
# the renderer into every bake; tests/test_architecture.py counts the string as this module's edge.
CUBEMAP_STAGE = "glint.cubemap_stage"


def bake_scene(scene: Scene, settings: BakeSettings, bake_dir: Path, *, force: bool = False,
               progress: bool = True, announce=None, seed: Path | None = None) -> BakeReport:
    """The whole bake of glint.bake.pipeline, with the cube-map stage that renders on the GPU.
    Repeated warnings of the stages (e.g. objects short of texels) are summarised when it ends."""
    with summarised():
        return pipeline.bake_scene(scene, settings, bake_dir, force=force, progress=progress,
                                   render_cubemaps=render_cubemaps, worker_modules=(CUBEMAP_STAGE,),
                                   announce=announce, seed=seed)


def background_rebake(manifest: Manifest, bake_dir: Path, edits=(), scene_path: Path | None = None):
    """The re-bake of the light maps and cube maps after material edits (glint.bake.rebake.Rebaker:
    a worker process, started now so that it has loaded the scene by the first edit); None for a
    bake whose scene file is gone (nothing to re-bake from: edits then change only what kd shows).
    `scene_path`: the scene file as this run found it (default: the manifest's, as typed then).
    `glint view`'s, and bench/edit_screenshots.py's (a tool: it may not import the command)."""
    from glint.bake.rebake import Rebaker
    from glint.cubemap_stage import ProbeRefresher, baked_probe_chains  # the renderer: only where a re-bake runs

    # the scene as the command found it: the manifest keeps the path as typed (information only),
    # relative to wherever the bake was started, which need not be this run's working directory
    source = scene_path if scene_path is not None else manifest.scene.source
    if not source or not Path(source).is_file():
        return None
    # the worker plans the bake's probes (none: nothing to refresh) and renders them after its passes
    return Rebaker(Path(source), bake_dir, edits=edits, probes=ProbeRefresher, baked_probes=baked_probe_chains)


def fidelity_line(manifest: Manifest) -> str | None:
    """One line of what the scene will look like wrong, from a bake's statistics: the share of
    light-map texels inside geometry (invalid: lit by dilation from their neighbours, not path
    traced) and the glTF features the loader ignored, e.g. "the scene will look wrong where:
    31.2 % of light-map texels lie inside geometry (filled from their neighbours); 12.0 % of
    the surface gets no light (black where seen); ignored: clearcoatTexture (12),
    EXT_texture_webp (3)". None when there is nothing to say (or nothing recorded)."""
    stats = manifest.statistics
    parts = []
    lightmaps = stats.lightmaps
    texels = lightmaps.get("texels") or 0
    surface = texels - (lightmaps.get("back_texels") or 0)
    # Only past the bake's warning shares: well-made scenes have some of both (contacts, chart
    # borders, backs of furniture; glint.bake.lightmap INVALID_WARN_SHARE).
    for key, of, limit, what in (
            ("invalid_texels", texels, INVALID_WARN_SHARE, "light-map texels lie inside geometry (filled from their neighbours)"),
            ("unlit_texels", surface, UNLIT_WARN_SHARE, "the surface gets no light (black where seen)")):
        count = lightmaps.get(key) or 0
        if of > 0 and count > limit * of:
            parts.append(f"{100.0 * count / of:.1f} % of {what}")
    ignored = stats.ignored_features
    if ignored:
        parts.append("ignored: " + ", ".join(f"{name} ({count})" for name, count in ignored.items()))
    return "the scene will look wrong where: " + "; ".join(parts) if parts else None


def _command_line_settings(args) -> dict:
    return {"quality": args.quality, "samples": args.samples, "texels_per_metre": args.texels_per_metre,
            "jobs": args.jobs, "scheduler": args.scheduler, "denoise": False if args.no_denoise else None}


def settings_for(scene: Scene, args, existing: Manifest | None) -> BakeSettings:
    """The settings to bake `scene` with for a command's arguments (add_bake_options).

    Without an existing bake (or for `glint bake` itself): the quality preset, the sidecar's
    [bake] table, then the command line (glint.bake.settings.resolve_settings). With one
    (`existing`, its manifest), the bake the user made is used as it is: its own settings,
    whatever preset it was made with; only what the command line gives explicitly changes
    them, and when the scene file or sidecar changed since, the sidecar's [bake] keys apply too
    (the sidecar is part of the scene). The pipeline then redoes only the stages whose inputs
    differ, usually none.
    """
    cli = _command_line_settings(args)
    if existing is None or args.quality is not None:
        return resolve_settings(scene.bake_settings, **cli)
    made_with = {k: v for k, v in existing.settings.items() if k in BakeSettings.__dataclass_fields__}
    sidecar = {k: v for k, v in (scene.bake_settings or {}).items() if k != "quality"}
    # The files unchanged (an edited scene's bake starts from the unedited one's manifest): only
    # the [bake] keys that `--set` gives apply; jobs never changes a result.
    unchanged = {pipeline.source_hash(scene)} | ({pipeline.source_hash(scene, edits=False)} if scene.edits else set())
    if existing.scene.hash in unchanged:  # without edits both hashes are one: the scene's files read once
        sidecar = {k: v for k, v in sidecar.items() if k == "jobs" or k in edited_bake_keys(scene.edits)}
    return resolve_settings({**made_with, **sidecar}, **cli)


def check_view_names(scene: Scene, args) -> None:
    """A one-line GlintError for a --camera or --path the scene does not have (capture, view and
    bench take them; bench's --camera repeats)."""
    wanted = getattr(args, "camera", None)
    for name in wanted if isinstance(wanted, list) else [wanted] if wanted else []:
        find_named(scene.cameras, name)
    if getattr(args, "path", None):
        find_named(scene.camera_paths, args.path, "camera path",
                   "the scene has none (sidecar [camera_paths])")


def run_bake(args, *, progress: bool = True, reuse: bool = True, explain: bool = True,
             outputs: list[tuple[str, Path]] = ()) -> BakeReport:
    """Bake, or find up to date, the scene of a command's arguments (add_bake_options).

    `reuse`: an existing bake keeps its settings (settings_for); `glint bake` passes False, so
    its presets and sidecar apply as given. When an existing bake must be redone, one line on
    stderr says why before the work starts. `explain`: after a bake that did work, one line on
    stderr says what the scene will look like wrong (fidelity_line); `glint bake` passes False
    and prints it last itself. `outputs`: the command's output files as (option, path), refused
    where they are or lie inside the bake directory. The bake directory must be absent, empty or a
    glint bake (check_bake_target): checked before the scene is loaded."""
    option = "-o" if getattr(args, "command", None) == "bake" else "--bake-dir"
    edits = getattr(args, "edits", None) or ()
    builtin = args.scene if args.scene in BUILTIN else None
    seed = args.out or default_bake_dir(resolve(args.scene), builtin)
    if not edits:  # with edits the seed is only read; the edited scene's directory is checked below
        check_bake_dir(seed, option, outputs)
    scene, builtin = open_scene(args.scene, edits)
    check_view_names(scene, args)  # before the bake: a typo costs nothing
    bake_dir = seed
    if scene.edits:  # never the unedited scene's directory: it stays valid (bake/edits.py)
        bake_dir = edited_bake_dir(seed, scene.edits)
        check_bake_dir(bake_dir, option, outputs)
    existing = (read_model(bake_dir) or (read_model(seed) if scene.edits else None)
                if reuse and not args.force else None)
    seeded = scene.edits and read_model(bake_dir) is None and read_model(seed) is not None
    settings = settings_for(scene, args, existing)

    def announce(why: str) -> None:
        if seeded:
            print(f"glint: baking the edited scene into {bake_dir}, starting from {seed} ({why})", file=sys.stderr)
        else:
            print(f"glint: {bake_dir} is stale ({why}): re-baking what changed", file=sys.stderr)

    report = bake_scene(scene, settings, bake_dir, force=args.force, progress=progress, announce=announce,
                        seed=seed if scene.edits else None)
    line = fidelity_line(report.model) if explain and report.status != "up-to-date" else None
    if line:
        print(f"glint: {line}", file=sys.stderr)
    return report


def check_bake_dir(bake_dir: Path, option: str, outputs: list[tuple[str, Path]] = ()) -> None:
    """Remove what a killed bake of `bake_dir` left beside it (remove_dead_temporaries); then a one-line
    GlintError, before any work, unless a bake may write `bake_dir` (core/bake_dir.py
    check_bake_target: absent, empty or a glint bake) and none of `outputs` ((option, path) of the
    command's output files) is the bake directory or lies inside it (a bake replaces it whole)."""
    remove_dead_temporaries(bake_dir)  # a killed bake's, also when this one finds the bake up to date
    check_bake_target(bake_dir, option)
    real = Path(os.path.realpath(bake_dir))
    for name, path in outputs:
        out = Path(os.path.realpath(path))
        if out == real or real in out.parents:
            raise GlintError(f"{name} {path} is {'' if out == real else 'inside '}the bake directory {bake_dir}, "
                             f"which a bake replaces as a whole; write it elsewhere")


def check_outputs(outputs: list[tuple[str, Path]]) -> None:
    """A one-line GlintError, before any work, when two of a command's output files ((option, path))
    are one file: the second would be written over the first."""
    seen: dict[str, tuple[str, Path]] = {}
    for name, path in outputs:
        key = os.path.realpath(path)
        if key in seen:
            first, first_path = seen[key]
            raise GlintError(f"{first} {first_path} and {name} {path} are the same file; give them different names")
        seen[key] = (name, path)


# -- argument checks shared by capture, view and bench --------------------------------------------
def parse_size(text: str, example: str = "1280x720") -> tuple[int, int]:
    m = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", text or "")
    if not m:
        raise GlintError(f"bad --size '{text}': expected WIDTHxHEIGHT in pixels, e.g. {example}")
    w, h = int(m.group(1)), int(m.group(2))
    if w < 1 or h < 1:
        raise GlintError(f"bad --size '{text}': width and height must be at least 1 pixel")
    return w, h


def parse_vector(text: str, option: str) -> np.ndarray:
    parts = [s for s in re.split(r"[,\s]+", text.strip()) if s]
    try:
        v = np.array([float(s) for s in parts], np.float64)
    except ValueError:
        v = np.zeros(0)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise GlintError(f"bad {option} '{text}': expected three numbers X,Y,Z")
    return v


def number(text: str, option: str, *, whole: bool = False, lo: float | None = None,
            hi: float | None = None, open_lo: bool = False):
    """`text` as a number for `option` within [lo, hi] (lo excluded with `open_lo`), or a GlintError
    that names the option."""
    try:
        value = int(text) if whole else float(text)
    except (TypeError, ValueError):
        raise GlintError(f"bad {option} '{text}': expected {'a whole number' if whole else 'a number'}") from None
    too_low = lo is not None and (value <= lo if open_lo else value < lo)
    if not math.isfinite(value) or too_low or (hi is not None and value > hi):
        low = None if lo is None else (f"above {lo:g}" if open_lo else f"at least {lo:g}")
        high = None if hi is None else f"at most {hi:g}"
        raise GlintError(f"bad {option} '{text}': must be " + (" and ".join(filter(None, (low, high))) or "finite"))
    return value


def check_writable(path: Path, option: str) -> None:
    """A GlintError now, before any work, if `path` cannot be written."""
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise GlintError(f"{option} {path}: is a directory; give a file name")
    if not parent.is_dir():
        raise GlintError(f"cannot write {path}: directory {parent} does not exist")
    if not os.access(parent, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise GlintError(f"cannot write {path}: permission denied")
