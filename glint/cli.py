"""The `glint` command: `glint scenes`, `glint bake SCENE`, ...

Every user-facing failure is a GlintError, printed as one line (`glint: ...`)
with a non-zero exit; `--debug` shows the traceback as well.
"""
from __future__ import annotations

import argparse
import sys
import traceback

from glint import __version__
from glint.bench.command import add_bench_parser
from glint.capture import add_capture_parser
from glint.core.errors import GlintError, summarised
from glint.core.signals import exit_status, handle_termination
from glint.core.skipped import summary_line
from glint.scenes import BUILTIN
from glint.services import SCENE_HELP, add_bake_options, add_edit_option, fidelity_line, run_bake
from glint.view import add_view_parser

EXIT_ERROR = 2
EXIT_INTERNAL = 1
EXIT_INTERRUPTED = 130
VERBOSE_HELP = ("list every warning on its own line (by default warnings that repeat per object or "
                "material are summarised in one line each, with a count and the first names)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="glint",
        description="glint: real-time walkthroughs of light-mapped glTF scenes with glossy, "
                    "anisotropic and translucent materials.",
        epilog="Run `glint COMMAND --help` for the options of a command.")
    parser.add_argument("--version", action="version", version=f"glint {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks for errors")
    parser.add_argument("--verbose", action="store_true", help=VERBOSE_HELP)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show tracebacks for errors")
    common.add_argument("--verbose", action="store_true", default=argparse.SUPPRESS, help=VERBOSE_HELP)
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
    add_bake_options(p, keeps_existing=False)
    add_edit_option(p)
    p.set_defaults(run=cmd_bake)
    add_view_parser(sub, common)
    add_capture_parser(sub, common)
    add_bench_parser(sub, common)
    return parser


def cmd_scenes(args) -> int:
    width = max(map(len, BUILTIN))
    for name, (_, about) in BUILTIN.items():
        print(f"{name:<{width}}  {about}")
    return 0


def cmd_bake(args) -> int:
    report = run_bake(args, progress=sys.stderr.isatty(), reuse=False, explain=False)
    print(report.summary)
    skipped = summary_line(report.manifest, report.status)
    if skipped:
        print(skipped)
    # Last, so it is what a person reads first: what the bake could not do right.
    line = fidelity_line(report.manifest)
    if line:
        sys.stdout.flush()
        print(f"glint: {line}", file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    handle_termination()  # SIGTERM and SIGHUP: as Ctrl-C (core/signals.py)
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "run", None):
        parser.print_help()
        return EXIT_ERROR
    try:
        # Warnings collected and not yet summarised are printed however the command ends,
        # before the error line.
        with summarised(verbose=args.verbose):
            return args.run(args)
    except GlintError as e:
        if args.debug:
            traceback.print_exc()
        print(f"glint: {e}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt as e:  # Ctrl-C, or SIGTERM / SIGHUP (core/signals.py Terminated)
        name, status = exit_status(e)
        print(f"glint: {'interrupted' if status == EXIT_INTERRUPTED else f'terminated ({name})'}; "
              "nothing was half-written", file=sys.stderr)
        return status
    except Exception as e:  # a bug: still one line unless --debug
        if args.debug:
            traceback.print_exc()
        print(f"glint: internal error: {type(e).__name__}: {e} (run with --debug for the traceback)",
              file=sys.stderr)
        return EXIT_INTERNAL
