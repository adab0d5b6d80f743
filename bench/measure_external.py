"""A scene someone else made, against its path-traced reference: how much of glint's image is right.

    python3 -m glint.bench.measure_external SCENE.glb REFERENCE.exr --camera NAME [--size 180x320]
        [--quality preview] [--converge 64] [--out DIR] [--bake-dir DIR]

Bakes SCENE (or reuses --bake-dir), captures the converged image (`glint capture --converge N`)
at the glTF camera NAME, box-downsamples the reference (linear radiance) to the capture's size
and reports, on Rec. 709 luminance:

- blocks within half a stop: the share of 8 x 8-pixel blocks whose mean luminance is within a
  factor sqrt(2) of the reference's block mean (blocks where both are below 1e-4 count as equal);
- black where lit: the share of pixels whose luminance is below 0.005 where the reference's is
  above 0.02;
- the mean luminance ratio, glint over reference.

Writes DIR/external.json, DIR/external.md and DIR/side_by_side.png (reference | glint | the
per-block ratio in stops, blue darker, red brighter), and the bake's and capture's timings as
their commands report them. Used for the Wooden Staircase (docs/BAKE.md, "Two sides on an external scene").
"""
from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from glint.bench.report import write_json, write_png
from glint.core.atomic import atomic_write_text
from glint.core.bake_dir import read_model
from glint.core.image_io import read_image

LUMA = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709
BLOCK = 8
HALF_STOP = math.sqrt(2.0)
DARK, LIT = 0.005, 0.02
FLOOR = 1e-4  # blocks darker than this in both images are equal


def downsample(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Box filter an (H, W, C) image to (h, w, C) = size[::-1]; H, W must be multiples of h, w."""
    w, h = size
    H, W = image.shape[:2]
    if H % h or W % w:
        raise SystemExit(f"reference {W}x{H} is not a whole multiple of {w}x{h}")
    return image.reshape(h, H // h, w, W // w, -1).mean(axis=(1, 3))


def luminance(image: np.ndarray) -> np.ndarray:
    return np.nan_to_num(image[..., :3], nan=0.0, posinf=0.0, neginf=0.0) @ LUMA


def block_means(lum: np.ndarray) -> np.ndarray:
    h, w = (lum.shape[0] // BLOCK) * BLOCK, (lum.shape[1] // BLOCK) * BLOCK
    return lum[:h, :w].reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK).mean(axis=(1, 3))


def block_ratios(ours: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per 8 x 8 block: (within half a stop, the ratio of the block means' luminance); blocks dark in
    both count as within."""
    bo, br = block_means(luminance(ours)), block_means(luminance(reference))
    ratio = np.maximum(bo, FLOOR) / np.maximum(br, FLOOR)
    return ((bo < FLOOR) & (br < FLOOR)) | ((ratio <= HALF_STOP) & (ratio >= 1 / HALF_STOP)), ratio


def add_scene_arguments(p: argparse.ArgumentParser) -> None:
    """SCENE, REFERENCE, --camera and --size: what bench/mitsuba_external.py shares."""
    p.add_argument("scene", type=Path)
    p.add_argument("reference", type=Path, help="linear-radiance EXR at the camera, a whole multiple of --size")
    p.add_argument("--camera", required=True)
    p.add_argument("--size", default="180x320")


def metrics(ours: np.ndarray, reference: np.ndarray) -> dict:
    """The figures of the module docstring, for two linear-radiance images of one size."""
    lo, lr = luminance(ours), luminance(reference)
    within, ratio = block_ratios(ours, reference)
    lit = lr > LIT
    return {"blocks": int(within.size), "blocks_within_half_stop": float(within.mean()),
            "black_where_lit": float(((lo < DARK) & lit).sum() / max(lit.sum(), 1)),
            "black_where_lit_pixels": int(((lo < DARK) & lit).sum()), "lit_pixels": int(lit.sum()),
            "mean_luminance_ratio": float(lo.mean() / max(lr.mean(), 1e-12)),
            "stops_per_block": np.log2(ratio)}


def to_srgb(linear: np.ndarray, exposure: float) -> np.ndarray:
    x = np.clip(linear[..., :3] * exposure, 0.0, None)
    x = x / (1.0 + x)  # Reinhard: enough for looking; both images get the same curve
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def side_by_side(ours: np.ndarray, reference: np.ndarray, stops: np.ndarray) -> np.ndarray:
    exposure = 0.5 / max(float(np.percentile(luminance(reference), 50)), 1e-6)
    h, w = ours.shape[:2]
    s = np.clip(np.kron(stops, np.ones((BLOCK, BLOCK))), -2, 2) / 2  # -1 .. 1 for -2 .. +2 stops
    diff = np.ones((h, w, 3))
    hs, ws = s.shape
    diff[:hs, :ws, 0] = 1 - np.clip(-s, 0, 1)
    diff[:hs, :ws, 1] = 1 - np.abs(s)
    diff[:hs, :ws, 2] = 1 - np.clip(s, 0, 1)
    gap = np.ones((h, 4, 3))
    return np.concatenate([to_srgb(reference, exposure), gap, to_srgb(ours, exposure), gap, diff], axis=1)


def glint(*args) -> float:
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "glint", *map(str, args)], check=True)
    return time.perf_counter() - t


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_scene_arguments(p)
    p.add_argument("--quality", default="preview")
    p.add_argument("--converge", type=int, default=64)
    p.add_argument("--out", type=Path, default=Path("external"))
    p.add_argument("--bake-dir", type=Path, help="default: OUT/NAME.bake")
    args = p.parse_args(argv)
    w, h = (int(x) for x in args.size.lower().split("x"))
    args.out.mkdir(parents=True, exist_ok=True)
    bake_dir = args.bake_dir or args.out / f"{args.scene.stem}.bake"
    bake_s = glint("bake", args.scene, "-o", bake_dir, "-q", args.quality)
    capture = args.out / "glint.exr"
    stats = args.out / "capture_stats.json"
    capture_s = glint("capture", args.scene, "--bake-dir", bake_dir, "--camera", args.camera, "--size", args.size,
                      "--converge", args.converge, "-o", capture, "--stats", stats)
    ours = read_image(capture)[..., :3]
    reference = downsample(read_image(args.reference)[..., :3], (w, h))
    m = metrics(ours, reference)
    write_png(args.out / "side_by_side.png", side_by_side(ours, reference, m.pop("stops_per_block")))
    result = {"scene": str(args.scene), "camera": args.camera, "size": [w, h], "quality": args.quality,
              "converge": args.converge, **m, "bake_command_seconds": round(bake_s, 1),
              "capture_command_seconds": round(capture_s, 1), "bake_statistics": read_model(bake_dir).statistics.data}
    write_json(args.out / "external.json", result)
    atomic_write_text(args.out / "external.md", (
        f"| scene | blocks within half a stop | black where lit | mean luminance ratio |\n|---|---|---|---|\n"
        f"| {args.scene.name} ({args.camera}, {w}x{h}, {args.quality}, converge {args.converge}) "
        f"| {m['blocks_within_half_stop']:.1%} | {m['black_where_lit']:.2%} | {m['mean_luminance_ratio']:.3f} |\n"))
    print(json.dumps({k: v for k, v in result.items() if k != "bake_statistics"}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
