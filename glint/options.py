"""The options the commands share, as argparse arguments: the bake's (`add_bake_options`), `--set`
(`add_edit_option`) and the SCENE argument's help.

Light to import (the standard library and the bake's settings): the command line builds a command's
parser before it imports the command's code (glint/cli.py), and `glint bake --help` must not pay for
the renderer.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from glint.parallel.executor import check_scheduler_address
from glint.bake.sidecar_schema import BAKE
from glint.bake.settings import PRESETS
from glint.core.errors import GlintError

SCENE_HELP = ("a built-in scene name (see `glint scenes`) or a .glb/.gltf file; "
              "an optional NAME.glint.toml beside the file adds lights, sky, material overrides and bake settings")


def _scheduler(text: str) -> str:
    """argparse type of --scheduler: `local:N` or [SCHEME://]HOST:PORT (glint.parallel.executor
    check_scheduler_address), checked here, before the command reads the scene."""
    try:
        return check_scheduler_address(text)
    except GlintError as err:  # argparse names the option itself: "argument --scheduler: bad 'x': ..."
        raise argparse.ArgumentTypeError(str(err).replace("bad --scheduler ", "bad ", 1)) from None


def _setting(key: str):
    """argparse type of the option of the bake setting `key`: the text read as a number where it is
    one, then checked by the setting's rule (glint.bake.sidecar_schema.BAKE), the sidecar's [bake] key's."""
    def parse(text: str):
        value = text
        for kind in (int, float):
            try:
                value = kind(text)
                break
            except ValueError:
                pass
        try:
            return BAKE[key].check(value, "", "")
        except GlintError as err:
            raise argparse.ArgumentTypeError(str(err)) from None
    return parse


def add_bake_options(p, out_flags: tuple[str, ...] = ("-o", "--out"), *, keeps_existing: bool = True) -> None:
    """The bake's options, for `bake` and for the commands that bake first (`view`, `capture`,
    `bench`); `out_flags` name the bake-directory option (capture's -o is its image);
    `keeps_existing`: an existing bake keeps its settings unless an option is given (run_bake)."""
    presets = "; ".join(f"{k}: {v['samples']} samples, {v['texels_per_metre']:g} texels/m" for k, v in PRESETS.items())
    p.add_argument(*out_flags, dest="out", type=Path, metavar="DIR",
                   help="bake directory (default: NAME.bake beside the scene file; "
                        "built-in scenes bake into ~/.cache/glint or $GLINT_CACHE)")
    p.add_argument("-q", "--quality", choices=list(PRESETS),
                   help=("quality preset (default: an existing bake is used with the settings it was made with; "
                         "a new one gets the sidecar's [bake] quality, else preview)" if keeps_existing else
                         "quality preset (default: the sidecar's [bake] quality, else preview)") + f" — {presets}")
    p.add_argument("--samples", type=_setting("samples"), metavar="N", help="paths per texel (overrides the preset)")
    p.add_argument("--texels-per-metre", type=_setting("texels_per_metre"), metavar="T", dest="texels_per_metre",
                   help="light-map resolution (overrides the preset)")
    p.add_argument("-j", "--jobs", type=_setting("jobs"), metavar="N",
                   help="worker processes (default: the sidecar's [bake] jobs, else 0 = one per CPU this process may use: its affinity, capped by a container's CPU quota)")
    p.add_argument("--scheduler", type=_scheduler, metavar="ADDRESS",
                   help="bake on a Dask cluster: the light-map tiles and cube maps become tasks on its workers. "
                        "ADDRESS is tcp://HOST:PORT of a running `dask scheduler` (workers started with `dask worker "
                        "tcp://HOST:PORT --nthreads 1`, each with this glint version and, for the cube maps, EGL: "
                        "a GPU driver or Mesa's llvmpipe), or local:N for a cluster of N worker processes on this "
                        "machine (--jobs is then unused). The bake is the same bytes as without it; needs "
                        "pip install 'glint[cluster]' "
                        "(docs/BAKE.md \"On a cluster (Dask)\")")
    p.add_argument("--no-denoise", action="store_true", help="keep the path-traced noise (no Open Image Denoise)")
    p.add_argument("--force", action="store_true", help="bake everything again even if up to date")


def add_edit_option(p) -> None:
    """`--set KEY=VALUE` (repeatable), for `bake`, `capture` and `view` (bake/edits.py)."""
    p.add_argument("--set", dest="edits", action="append", default=[], metavar="KEY=VALUE",
                   help="change one sidecar key for this run, on top of NAME.glint.toml (repeatable): KEY a "
                        "TOML key path, VALUE a TOML value, checked as the sidecar is, e.g. "
                        "--set 'materials.\"Floor\".kd=[0.3, 0.2, 0.1]' --set 'bake.quality=\"draft\"'. "
                        "The edited scene bakes into NAME.edit-<hash>.bake beside the bake directory, "
                        "starting from the unedited bake, which stays as it is (docs/SCENES.md)")
