"""End-to-end error of the glossy-floor rooms against Mitsuba 3: docs/BENCHMARKS.md, "Glossy floors".

    python3 -m glint.bench.measure_glossy_floors [--size 160x90] [--spp 1024] [--seed 0] [--converge 64]
        [--quality preview] [--scenes metal-floor-room glossy-floor-room metal-0.05 ...] [--reference gltf]
        [--out DIR]

For metal-floor-room and glossy-floor-room (scenes/generate.py `glossy_floor_room`), from their
camera, and for issue 24's rooms (ISSUE_24: the same room with a glTF metal floor of roughness 0.05
or 0.3, or a dielectric one of roughness 0.2 or 0.4, seen from 1.6 m, written to DIR): glint's
walkthrough image and its converged still-camera image (`--converge` frames), both with supersample
2, against Mitsuba 3 (bench/mitsuba_scene.py: the path tracer, unlimited depth) at `--spp` samples
per pixel. `--reference gltf` (the default) renders every material mapped from glTF factors by the
glTF specification's BRDF (bench/mitsuba_gltf_bsdf.py, written without glint's mapping: the
reference of issue 24); `--reference model` by glint's own section 3.3 BSDF with the lobes glint's
mapping chose (which can only see the renderer's error, never the mapping's). Printed and written to
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
from glint.scenes.generate import GF_CAMERA, GF_X, GF_Z, glossy_floor_room

SCENES = ("metal-floor-room", "glossy-floor-room")
EYE_HEIGHT = 1.6  # metres: issue 24's rooms are seen from standing eye height
ISSUE_24 = {  # name: the floor's glTF factors
    "metal-0.05": dict(base_color=(0.9, 0.9, 0.9, 1), metallic=1.0, roughness=0.05),
    "metal-0.3": dict(base_color=(0.9, 0.9, 0.9, 1), metallic=1.0, roughness=0.3),
    "dielectric-0.2": dict(base_color=(0.4, 0.4, 0.4, 1), metallic=0.0, roughness=0.2),
    "dielectric-0.4": dict(base_color=(0.4, 0.4, 0.4, 1), metallic=0.0, roughness=0.4),
}


def scene_path(name: str, out: Path) -> Path:
    """A built-in scene's file, or issue 24's room `name` written to `out`."""
    if name in SCENES:
        return builtin_path(name)
    _, eye, target, fov = GF_CAMERA
    camera = ("Camera", (eye[0], EYE_HEIGHT, eye[2]), target, fov)
    path = out / f"{name}.glb"
    glossy_floor_room(ISSUE_24[name], camera).write(path)
    return path
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
    p.add_argument("--scenes", nargs="+", choices=SCENES + tuple(ISSUE_24), default=list(SCENES + tuple(ISSUE_24)))
    p.add_argument("--reference", choices=("gltf", "model"), default="gltf",
                   help="what Mitsuba renders glTF materials with (the module docstring)")
    p.add_argument("--reference-cache", type=Path, default=None,
                   help="keep Mitsuba's images here and reuse them (a `gltf` reference does not depend on "
                        "glint's mapping, so two commits can be measured against one rendering)")
    p.add_argument("--out", type=Path, default=Path("glossy-floors"))
    args = p.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))
    args.out.mkdir(parents=True, exist_ok=True)
    import mitsuba as mi

    variant = choose_variant("auto")["variant"]
    results = {"size": args.size, "spp": args.spp, "seed": args.seed, "converge": args.converge,
               "quality": args.quality, "reference": args.reference,
               "mitsuba_variant": variant, "scenes": {}}
    for name in args.scenes:
        path = scene_path(name, args.out)
        scene = load_scene(path)
        camera = scene.cameras[0]
        started = time.perf_counter()
        scene_dict, notes = convert(scene, [sensor_dict(camera, width, height, spp=args.spp, seed=args.seed)],
                                    gltf=args.reference == "gltf")
        for note in notes:
            print(f"{name}: {note}")
        cached = None if args.reference_cache is None else (
            args.reference_cache / f"{name}-{args.reference}-{args.size}-{args.spp}spp-{args.seed}.exr")
        if cached is not None and cached.exists():
            reference = read_image(cached)[..., :3].astype(np.float64)
        else:
            reference = render(mi.load_dict(scene_dict), spp=args.spp, seed=args.seed).astype(np.float64)
            if cached is not None:
                cached.parent.mkdir(parents=True, exist_ok=True)
                write_image(cached, reference.astype(np.float32), half=False)
        mitsuba_s = time.perf_counter() - started
        write_image(args.out / f"{name}-mitsuba.exr", reference.astype(np.float32), half=False)
        images = {}
        for mode, extra in (("walkthrough", []), ("converged", ["--converge", str(args.converge)])):
            out = args.out / f"{name}-{mode}.exr"
            # the command in its own process: a tool does not import the commands (docs/ARCHITECTURE.md)
            subprocess.run([sys.executable, "-m", "glint", "capture", str(path), "-o", str(out), "--size", args.size,
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
