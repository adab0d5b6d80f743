"""`glint bench`: its options and which measurement a run makes.

    glint bench SCENE              the integration methods' time against error (bench/bench.py)
    glint bench SCENE --mitsuba    the viewer's images against Mitsuba 3 (bench/mitsuba.py)
    glint bench --stress           the numerical stress suite on its own scenes (bench/stress.py)

The one place that knows all three: glint/cli.py has it add the options, and the measurements
themselves import none of each other's commands. A command (glint/, as capture.py and view.py): it
imports the measurements of bench/, never its scripts (the tools), which import no command
(docs/ARCHITECTURE.md, "Layers").
"""
from __future__ import annotations

import argparse
from pathlib import Path

from glint.bench.bench import (
    DEFAULT_FRAMES,
    DEFAULT_METHODS,
    DEFAULT_REFERENCE_SAMPLES,
    DEFAULT_SAMPLES,
    DEFAULT_SIZE,
    DEFAULT_WARMUP,
    MAX_FRAMES,
    METHODS,
    run_sweep,
)
from glint.bench.mitsuba import add_mitsuba_options, cmd_bench_mitsuba
from glint.bench.stress import add_stress_options, run_stress
from glint.core.errors import GlintError
from glint.options import SCENE_HELP, add_bake_options


def add_bench_options(p: argparse.ArgumentParser) -> None:
    """`glint bench`'s options, on the parser glint/cli.py made for it."""
    methods = "; ".join(f"{m.key}: {m.label}" for m in METHODS.values())
    p.description = ("For each camera, method and sample count: GPU milliseconds per pass and the error "
                     "against the converged reference (PSNR of the displayed images, relative MSE of the "
                     "radiance, FLIP when installed), over the whole image, the pixels with view-dependent "
                     "materials and each such material. Writes bench.csv, bench.json, bench.md and bench.png into "
                     "the output directory. Bakes first when the bake is missing or stale.")
    p.epilog = f"Methods: {methods}. The errors are deterministic; the times are not."
    p.add_argument("scene", metavar="SCENE", nargs="?", help=SCENE_HELP + " (not with --stress)")
    p.add_argument("-o", "--output", type=Path, metavar="DIR",
                   help="directory for bench.csv, bench.json, bench.md, bench.png (made if missing; default: "
                        "bench-NAME in the current directory)")
    p.add_argument("--camera", action="append", metavar="NAME",
                   help="a camera of the scene; repeat for several (default: all of them)")
    p.add_argument("--size", default=DEFAULT_SIZE, metavar="WxH", help=f"image size (default {DEFAULT_SIZE})")
    p.add_argument("--lobe-samples", default=",".join(map(str, DEFAULT_SAMPLES)), metavar="N,N,...",
                   help=f"samples per lobe and pixel to sweep, n (default {','.join(map(str, DEFAULT_SAMPLES))}; "
                        "--samples is the bake's paths per texel, as everywhere)")
    p.add_argument("--methods", default=",".join(DEFAULT_METHODS), metavar="M,M,...",
                   help=f"methods to sweep (default: {','.join(DEFAULT_METHODS)}; also: "
                        f"{','.join(k for k in METHODS if k not in DEFAULT_METHODS)})")
    p.add_argument("--reference-samples", default=str(DEFAULT_REFERENCE_SAMPLES), metavar="N",
                   help=f"quasi-random samples per lobe and pixel of the converged reference "
                        f"(default {DEFAULT_REFERENCE_SAMPLES})")
    p.add_argument("--frames", default=str(DEFAULT_FRAMES), metavar="N",
                   help=f"timed frames per method and n, at most {MAX_FRAMES}; the medians are reported "
                        f"(default {DEFAULT_FRAMES})")
    p.add_argument("--warmup", default=str(DEFAULT_WARMUP), metavar="N",
                   help=f"untimed frames first (default {DEFAULT_WARMUP})")
    p.add_argument("--supersample", default="1", metavar="N",
                   help="N x N samples per pixel, box-filtered (default 1: the error is the lobe "
                        "integration's alone)")
    p.add_argument("--exposure", default="0", metavar="EV", help="exposure of the displayed images (default 0)")
    p.add_argument("--images", action="store_true",
                   help="also write the reference and every method's image as PNG into DIR/images")
    p.add_argument("--no-flip", action="store_true", help="skip FLIP even when flip-evaluator is installed")
    add_bake_options(p.add_argument_group("bake (done first when missing or stale)"), out_flags=("--bake-dir",))
    add_stress_options(p)
    p.add_argument("--mitsuba", action="store_true",
                   help="instead of the method sweep: the walkthrough and converged images against Mitsuba 3 "
                        "rendering the same scene, with Mitsuba's error at 1, 2, 4, ... spp and its seconds: "
                        "mitsuba.csv, mitsuba.json, mitsuba.png (bench/mitsuba.py)")
    add_mitsuba_options(p)
    p.set_defaults(run=run_bench)


def run_bench(args) -> int:
    """`glint bench`: the stress suite, the comparison with Mitsuba or the method sweep."""
    if args.stress:
        if args.scene is not None:
            raise GlintError("--stress runs its own scenes (scenes/stress.py): give no SCENE with it")
        return run_stress(args)
    if args.scene is None:
        raise GlintError("glint bench needs a SCENE (a built-in name or a .glb/.gltf file), or --stress")
    if args.mitsuba:
        return cmd_bench_mitsuba(args)
    return run_sweep(args)
