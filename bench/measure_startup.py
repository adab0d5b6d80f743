"""Start-up time of the `glint` command: wall seconds of `python -m glint ARGS` for the commands that
do no work (`--version`, `--help`, `bake --help`, `capture --help`), medians over fresh processes.

    python3 -m glint.bench.measure_startup [--runs 20]

Measured, never asserted (tests/test_startup.py checks what is imported); figures in docs/VIEWER.md,
"Start-up times".
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time

CASES = (["--version"], ["--help"], ["bake", "--help"], ["capture", "--help"])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20, help="fresh processes per command line (default 20)")
    args = parser.parse_args()
    for case in CASES:
        subprocess.run([sys.executable, "-m", "glint", *case], capture_output=True, check=True)  # warm the caches
        seconds = []
        for _ in range(args.runs):
            start = time.perf_counter()
            subprocess.run([sys.executable, "-m", "glint", *case], capture_output=True, check=True)
            seconds.append(time.perf_counter() - start)
        print(json.dumps({"args": " ".join(case), "median_ms": round(1e3 * statistics.median(seconds), 1),
                          "min_ms": round(1e3 * min(seconds), 1), "runs": args.runs}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
