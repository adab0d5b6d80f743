"""End-to-end error of the glossy-floor rooms against Mitsuba 3: docs/BENCHMARKS.md, "Glossy floors".

    python3 -m glint.bench.measure_glossy_floors [--size 160x90] [--spp 1024] [--seed 0] [--converge 64]
        [--quality preview] [--scenes metal-floor-room glossy-floor-room] [--out DIR]

For metal-floor-room and glossy-floor-room (scenes/generate.py `glossy_floor_room`), from their
camera: glint's walkthrough image and its converged still-camera image (`--converge` frames),
both with supersample 2, against Mitsuba 3 (bench/mitsuba_scene.py: the path tracer, unlimited
depth, the section 3.3 BSDF plugin) at `--spp` samples per pixel. Printed and written to
DIR/glossy_floors.json: the relative MAE of 4 x 4-pixel block means, sum |a - b| / sum b over the
blocks, of the whole image and of the floor's blocks alone (the blocks whose every pixel's
centre ray meets the floor first: the plane y = 0 inside the room, not behind the pedestal or
the ball), and the signed bias of each.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from glint.bake.gltf_loader import load_scene
from glint.core.atomic import atomic_write_text
from glint.core.image_io import read_image, write_image
from glint.scenes import builtin_path
from glint.scenes.generate import GF_X, GF_Z

SCENES = ("metal-floor-room", "glossy-floor-room")
BLOCK = 4
PEDESTAL = (np.array([-0.2, 0.0, -0.9]), np.array([0.2, 0.8, -0.5]))  # generate.glossy_floor_room
BALL = (np.array([0.0, 1.0, -0.7]), 0.2)


def floor_mask(camera, width: int, height: int) -> np.ndarray:
    """(height, width): the pixels whose centre ray meets the floor before the pedestal and the ball."""
    eye, f, up = (np.asarray(a, np.float64) for a in (camera.eye, camera.forward, camera.up))
    right = np.cross(f, up)
    t = np.tan(camera.yfov / 2)
    aspect = width / height
    x = ((np.arange(width) + 0.5) / width * 2 - 1) * t * aspect
    y = -((np.arange(height) + 0.5) / height * 2 - 1) * t
    d = f + x[None, :, None] * right + y[:, None, None] * up
    with np.errstate(divide="ignore", invalid="ignore"):
        t_floor = np.where(d[..., 1] < 0, -eye[1] / d[..., 1], np.inf)
        hit = eye + t_floor[..., None] * d
        floor = np.isfinite(t_floor) & (np.abs(hit[..., 0]) <= GF_X) & (np.abs(hit[..., 2]) <= GF_Z)
        lo, hi = PEDESTAL  # slab test
        t0, t1 = (lo - eye) / d, (hi - eye) / d
        near = np.minimum(t0, t1).max(axis=-1)
        far = np.maximum(t0, t1).min(axis=-1)
        box = (near <= far) & (far > 0) & (near < t_floor)
        centre, radius = BALL
        oc = eye - centre
        b = d @ oc
        disc = b * b - (d * d).sum(-1) * (oc @ oc - radius ** 2)
        ball = (disc >= 0) & ((-b - np.sqrt(np.maximum(disc, 0))) / (d * d).sum(-1) < t_floor)
    return floor & ~box & ~ball


def block_figures(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> dict:
    """Relative MAE and signed bias of the BLOCK x BLOCK block means (over the blocks wholly in `mask`)."""
    h, w = (reference.shape[0] // BLOCK) * BLOCK, (reference.shape[1] // BLOCK) * BLOCK

    def blocks(a):
        return a[:h, :w].reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK, -1).mean(axis=(1, 3))

    a, b = blocks(image), blocks(reference)
    if mask is not None:
        inside = mask[:h, :w].reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK).all(axis=(1, 3))
        a, b = a[inside], b[inside]
    return {"relative_mae": float(np.abs(a - b).sum() / b.sum()), "bias": float((a - b).sum() / b.sum()),
            "blocks": int(a.shape[0] if mask is not None else a.shape[0] * a.shape[1])}


def main(argv=None) -> int:
    from glint.bench.mitsuba import choose_variant
    from glint.bench.mitsuba_scene import convert, render, sensor_dict

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", default="160x90")
    p.add_argument("--spp", type=int, default=1024)
    p.add_argument("--seed", type=int, default=0, help="Mitsuba's sampler seed")
    p.add_argument("--converge", type=int, default=64)
    p.add_argument("--quality", default="preview")
    p.add_argument("--scenes", nargs="+", choices=SCENES, default=list(SCENES))
    p.add_argument("--out", type=Path, default=Path("glossy-floors"))
    args = p.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))
    args.out.mkdir(parents=True, exist_ok=True)
    import mitsuba as mi

    variant = choose_variant("auto")["variant"]
    results = {"size": args.size, "spp": args.spp, "seed": args.seed, "converge": args.converge,
               "quality": args.quality,
               "mitsuba_variant": variant, "scenes": {}}
    for name in args.scenes:
        scene = load_scene(builtin_path(name))
        camera = scene.cameras[0]
        started = time.perf_counter()
        scene_dict, _ = convert(scene, [sensor_dict(camera, width, height, spp=args.spp, seed=args.seed)])
        reference = render(mi.load_dict(scene_dict), spp=args.spp, seed=args.seed).astype(np.float64)
        mitsuba_s = time.perf_counter() - started
        write_image(args.out / f"{name}-mitsuba.exr", reference.astype(np.float32), half=False)
        images = {}
        for mode, extra in (("walkthrough", []), ("converged", ["--converge", str(args.converge)])):
            out = args.out / f"{name}-{mode}.exr"
            # the command in its own process: a tool does not import the commands (docs/ARCHITECTURE.md)
            subprocess.run([sys.executable, "-m", "glint", "capture", name, "-o", str(out), "--size", args.size,
                            "--supersample", "2", "-q", args.quality, "--bake-dir", str(args.out / f"{name}.bake"),
                            *extra], check=True)
            images[mode] = read_image(out)[..., :3].astype(np.float64)
        floor = floor_mask(camera, width, height)
        entry = {"mitsuba_seconds": round(mitsuba_s, 1), "floor_pixels": int(floor.sum())}
        for mode, image in images.items():
            entry[mode] = {"whole": block_figures(image, reference), "floor": block_figures(image, reference, floor)}
            print(f"{name} {mode:11s} whole image: MAE {entry[mode]['whole']['relative_mae']:.3f} "
                  f"bias {entry[mode]['whole']['bias']:+.3f}; floor: MAE {entry[mode]['floor']['relative_mae']:.3f} "
                  f"bias {entry[mode]['floor']['bias']:+.3f}")
        results["scenes"][name] = entry
    atomic_write_text(args.out / "glossy_floors.json", json.dumps(results, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
