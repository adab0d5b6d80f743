"""The `glint` command: `glint scenes`, `glint bake SCENE`, ...

Every user-facing failure is a GlintError, printed as one line (`glint: ...`)
with a non-zero exit; `--debug` shows the traceback as well. A mistake on the
command line is one line too (`glint: bake: argument --samples: ...`), exit 2.

Start-up: this module imports the standard library and glint.core.errors only. Each
sub-command's options and code are imported when that command is run (`COMMANDS`), so
`glint --help` and `glint --version` import nothing heavy, and `glint bake` neither the
renderer nor the measurement tools (tests/test_startup.py).
"""
from __future__ import annotations

import argparse
import sys
import traceback
from dataclasses import dataclass
from typing import Callable

from glint import __version__
from glint.core.errors import GlintError, summarised
from glint.core.signals import exit_status, handle_termination

EXIT_ERROR = 2
EXIT_INTERNAL = 1
EXIT_INTERRUPTED = 130
VERBOSE_HELP = ("list every warning on its own line (by default warnings that repeat per object or "
                "material are summarised in one line each, with a count and the first names)")


class ArgumentParser(argparse.ArgumentParser):
    """argparse, but a mistake is one line on stderr (`glint: bake: argument -j/--jobs: ...`) and
    exit 2, not the usage block: the same shape as every other error of glint."""

    def error(self, message: str):
        where = self.prog.removeprefix("glint").strip()
        hint = f"`{self.prog} --help` lists the {'options' if where else 'commands and options'}"
        print(f"glint: {where + ': ' if where else ''}{message} ({hint})", file=sys.stderr)
        raise SystemExit(EXIT_ERROR)


# -- the sub-commands: each one's parser is filled in only when it is the one run ------------------

def _scenes_options(p: argparse.ArgumentParser) -> None:
    p.description = "List the built-in scenes, which any SCENE argument accepts by name."
    p.set_defaults(run=cmd_scenes)


def _bake_options(p: argparse.ArgumentParser) -> None:
    from glint.options import SCENE_HELP, add_bake_options, add_edit_option

    p.description = ("Bake a scene's light maps into a bake directory. Only stages whose inputs "
                     "changed are redone; with nothing changed it says so and does no work. "
                     "The result is written to a temporary directory and moved into place, "
                     "so an interrupted bake leaves the previous one intact.")
    p.add_argument("scene", metavar="SCENE", help=SCENE_HELP)
    add_bake_options(p, keeps_existing=False)
    add_edit_option(p)
    p.set_defaults(run=cmd_bake)


def _view_options(p: argparse.ArgumentParser) -> None:
    from glint.view import add_view_options

    add_view_options(p)


def _capture_options(p: argparse.ArgumentParser) -> None:
    from glint.capture import add_capture_options

    add_capture_options(p)


def _bench_options(p: argparse.ArgumentParser) -> None:
    from glint.bench_command import add_bench_options

    add_bench_options(p)


def _fit_options(p: argparse.ArgumentParser) -> None:
    from glint.fit import add_fit_options

    add_fit_options(p)


@dataclass(frozen=True)
class Command:
    help: str
    options: Callable[[argparse.ArgumentParser], None]  # adds the command's options and `run`


COMMANDS = {
    "scenes": Command("list the built-in scenes", _scenes_options),
    "bake": Command("bake light maps (global illumination) for a scene", _bake_options),
    "view": Command("walk through a scene in a window (bakes first if needed)", _view_options),
    "capture": Command("render images headless (PNG or EXR), no window needed", _capture_options),
    "bench": Command("run time against error of the specular integration methods", _bench_options),
    "fit": Command("fit the material model to a measured BRDF (MERL .binary or .csv) into a sidecar", _fit_options),
}


def command_of(argv: list[str]) -> str | None:
    """The sub-command named on a command line (the first word that is not an option: the global
    options take no values), or None."""
    return next((word for word in argv if not word.startswith("-")), None)


def build_parser(argv: list[str] | None = None) -> ArgumentParser:
    """The command line's parser. Only the command that `argv` names gets its options (and imports
    their module); the others are listed by name and help, which is all `glint --help` shows.
    `argv` None: every command gets its options (for tests and documentation)."""
    parser = ArgumentParser(
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
    chosen = None if argv is None else command_of(argv)
    parser.chosen = parser  # the parser that reports words nobody took: the command's, when one is named
    for name, command in COMMANDS.items():
        p = sub.add_parser(name, parents=[common], help=command.help, description=command.help)
        if argv is None or name == chosen:
            command.options(p)
        if name == chosen:
            parser.chosen = p
    return parser


def cmd_scenes(args) -> int:
    from glint.scenes import BUILTIN

    width = max(map(len, BUILTIN))
    for name, (_, about) in BUILTIN.items():
        print(f"{name:<{width}}  {about}")
    return 0


def cmd_bake(args) -> int:
    from glint.core.skipped import summary_line
    from glint.services import fidelity_line, run_bake

    report = run_bake(args, progress=sys.stderr.isatty(), reuse=False, explain=False)
    print(report.summary)
    skipped = summary_line(report.model, report.status)
    if skipped:
        print(skipped)
    # Last, so it is what a person reads first: what the bake could not do right.
    line = fidelity_line(report.model)
    if line:
        sys.stdout.flush()
        print(f"glint: {line}", file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    handle_termination()  # SIGTERM and SIGHUP: as Ctrl-C (core/signals.py)
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv)
    try:
        args, unknown = parser.parse_known_args(argv)
        if unknown:
            parser.chosen.error(f"unrecognized arguments: {' '.join(unknown)}")
    except SystemExit as e:  # --help, --version (0) and ArgumentParser.error (2): already printed
        return int(e.code or 0)
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
