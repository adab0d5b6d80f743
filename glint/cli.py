"""The `glint` command: `glint scenes`, `glint bake SCENE`, ...

Every user-facing failure is a GlintError, printed as one line (`glint: ...`)
with a non-zero exit; `--debug` shows the traceback as well.
"""
from __future__ import annotations

import argparse
import sys
import traceback
from pathlib import Path

from glint import __version__
from glint.errors import GlintError

EXIT_ERROR = 2
EXIT_INTERNAL = 1
EXIT_INTERRUPTED = 130

SCENE_HELP = ("a built-in scene name (see `glint scenes`) or a .glb/.gltf file; "
              "an optional NAME.glint.toml beside the file adds lights, sky, material overrides and bake settings")


def _whole(minimum: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a whole number: '{text}'")
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}: '{text}'")
        return value
    return parse


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: '{text}'")
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive: '{text}'")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="glint",
        description="glint: real-time walkthroughs of light-mapped glTF scenes with glossy, "
                    "anisotropic and translucent materials.",
        epilog="Run `glint COMMAND --help` for the options of a command.")
    parser.add_argument("--version", action="version", version=f"glint {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks for errors")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show tracebacks for errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("scenes", parents=[common], help="list the built-in scenes",
                       description="List the built-in scenes, which any SCENE argument accepts by name.")
    p.set_defaults(run=cmd_scenes)

    p = sub.add_parser("bake", parents=[common], help="bake light maps (global illumination) for a scene",
                       description="Bake a scene's light maps into a bake directory. Only stages whose inputs "
                                   "changed are redone; with nothing changed it says so and does no work. "
                                   "The result is written to a temporary directory and moved into place, "
                                   "so an interrupted bake leaves the previous one intact.")
    p.add_argument("scene", metavar="SCENE", help=SCENE_HELP)
    add_bake_options(p)
    p.set_defaults(run=cmd_bake)
    from viewer.view_command import add_view_parser
    add_view_parser(sub, common)
    from viewer.capture import add_capture_parser
    add_capture_parser(sub, common)
    from viewer.bench import add_bench_parser
    add_bench_parser(sub, common)
    return parser


def add_bake_options(p, out_flags: tuple[str, ...] = ("-o", "--out")) -> None:
    """The bake's options, for `bake` and for the commands that bake first (`view`, `capture`);
    `out_flags` name the bake-directory option (capture's -o is its image)."""
    from bake.settings import PRESETS

    presets = "; ".join(f"{k}: {v['samples']} samples, {v['texels_per_metre']:g} texels/m" for k, v in PRESETS.items())
    p.add_argument(*out_flags, dest="out", type=Path, metavar="DIR",
                   help="bake directory (default: NAME.bake beside the scene file; "
                        "built-in scenes bake into ~/.cache/glint or $GLINT_CACHE)")
    p.add_argument("-q", "--quality", choices=list(PRESETS),
                   help=f"quality preset (default: the sidecar's [bake] quality, else preview) — {presets}")
    p.add_argument("--samples", type=_whole(1), metavar="N", help="paths per texel (overrides the preset)")
    p.add_argument("--texels-per-metre", type=_positive_float, metavar="T", dest="texels_per_metre",
                   help="light-map resolution (overrides the preset)")
    p.add_argument("-j", "--jobs", type=_whole(0), metavar="N",
                   help="worker processes (default: the sidecar's [bake] jobs, else 0 = one per core)")
    p.add_argument("--no-denoise", action="store_true", help="keep the path-traced noise (no Open Image Denoise)")
    p.add_argument("--force", action="store_true", help="bake everything again even if up to date")


def cmd_scenes(args) -> int:
    from scenes import BUILTIN

    width = max(map(len, BUILTIN))
    for name, (_, about) in BUILTIN.items():
        print(f"{name:<{width}}  {about}")
    return 0


def open_scene(scene_arg: str):
    """SCENE argument -> (Scene, builtin name or None)."""
    from scenes import BUILTIN, resolve

    path = resolve(scene_arg)
    from bake.gltf_loader import load_scene

    return load_scene(path), (scene_arg if scene_arg in BUILTIN else None)


def run_bake(args, *, progress: bool = True):
    from bake.bake_dir import default_bake_dir
    from bake.pipeline import bake_scene
    from bake.settings import resolve_settings

    scene, builtin = open_scene(args.scene)
    settings = resolve_settings(scene.bake_settings, quality=args.quality, samples=args.samples,
                                texels_per_metre=args.texels_per_metre, jobs=args.jobs,
                                denoise=False if args.no_denoise else None)
    bake_dir = args.out or default_bake_dir(scene.source, builtin)
    return bake_scene(scene, settings, bake_dir, force=args.force, progress=progress)


def cmd_bake(args) -> int:
    from bake.skipped import summary_line

    report = run_bake(args, progress=sys.stderr.isatty())
    print(report.summary)
    skipped = summary_line(report.manifest, report.status)
    if skipped:
        print(skipped)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "run", None):
        parser.print_help()
        return EXIT_ERROR
    try:
        return args.run(args)
    except GlintError as e:
        if args.debug:
            traceback.print_exc()
        print(f"glint: {e}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print("glint: interrupted; nothing was half-written", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as e:  # a bug: still one line unless --debug
        if args.debug:
            traceback.print_exc()
        print(f"glint: internal error: {type(e).__name__}: {e} (run with --debug for the traceback)",
              file=sys.stderr)
        return EXIT_INTERNAL
