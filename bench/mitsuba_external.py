"""A scene someone else made, rendered by Mitsuba 3 with its materials as their glTF authors defined them.

    python3 -m glint.bench.mitsuba_external SCENE.glb REFERENCE.exr --camera NAME [--size 180x320]
        [--spp 16] [--seeds 0 1 2 ...] [--out DIR] [--glint IMAGE.exr ...]

Two questions bench/measure_external.py cannot answer alone: how close a renderer that reads the
.glb by the glTF specification gets to the scene's own path-traced reference (made from the
original scene, whose materials the .glb only approximates), and how close glint's image is to that
renderer's, a reference that shares nothing with glint's material mapping or renderer.

Renders one image per seed with Mitsuba 3 (`scalar_rgb`, its path tracer, unlimited depth) of the
scene converted by bench/mitsuba_scene.py `convert(gltf=True)`: every material the loader read from
glTF factors (base-colour textures included) by the glTF plugin bench/mitsuba_gltf_bsdf.py; the
others by glint's own BSDF, each printed. Images already in DIR (mitsuba-WxH-SPPspp-sSEED.exr) are
reused; the seeds' mean is the Mitsuba image. Printed, with bench/measure_external.py's metric
(8 x 8-pixel blocks within half a stop, black where lit, mean luminance ratio; the reference
box-downsampled to --size): the Mitsuba image against REFERENCE, each --glint image against REFERENCE
and against the Mitsuba image, and the blocks that one of the two misses against REFERENCE and the
other does not. Written: DIR/mitsuba_external.json.

Scalar Mitsuba with a Python BSDF is slow: the Wooden Staircase takes about 25 s per sample per pixel
at 180 x 320 on one core of the shared 2-core machine.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from glint.bench.measure_external import add_scene_arguments, block_ratios, downsample, metrics
from glint.bench.report import write_json
from glint.core.image_io import read_image, write_image


def render_seed(scene_path: Path, camera: str, size: tuple[int, int], spp: int, seed: int, out: Path) -> float:
    """Render one seed to `out` (EXR, linear radiance); the seconds it took."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    from glint.bake.gltf_loader import load_scene
    from glint.bench import mitsuba_scene
    from glint.viewer.camera import find_named

    scene = load_scene(scene_path)
    cam = find_named(scene.cameras, camera)
    started = time.perf_counter()
    d, warnings = mitsuba_scene.convert(scene, [mitsuba_scene.sensor_dict(cam, *size, spp=spp, seed=seed)], gltf=True)
    for w in warnings:
        print(f"mitsuba_external: {w}", flush=True)
    image = mitsuba_scene.render(mi.load_dict(d), 0, spp=spp, seed=seed)
    write_image(out, np.asarray(image, np.float32), half=False)
    return time.perf_counter() - started


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_scene_arguments(p)
    p.add_argument("--spp", type=int, default=16, help="samples per pixel per seed")
    p.add_argument("--seeds", type=int, nargs="+", default=[0])
    p.add_argument("--out", type=Path, default=Path("mitsuba-external"))
    p.add_argument("--glint", type=Path, nargs="*", default=[], help="glint images (EXR, --size) to compare")
    args = p.parse_args(argv)
    size = tuple(int(x) for x in args.size.lower().split("x"))
    args.out.mkdir(parents=True, exist_ok=True)
    images = []
    for seed in args.seeds:
        path = args.out / f"mitsuba-{size[0]}x{size[1]}-{args.spp}spp-s{seed}.exr"
        if not path.exists():
            seconds = render_seed(args.scene, args.camera, size, args.spp, seed, path)
            print(f"mitsuba_external: seed {seed}, {args.spp} spp in {seconds:.0f} s -> {path}", flush=True)
        images.append(read_image(path)[..., :3].astype(np.float64))
    ours = sum(images) / len(images)
    reference = downsample(read_image(args.reference)[..., :3].astype(np.float64), size)

    def summary(m: dict) -> dict:
        return {k: m[k] for k in ("blocks", "blocks_within_half_stop", "black_where_lit", "mean_luminance_ratio")}

    result = {"scene": str(args.scene), "camera": args.camera, "size": list(size),
              "samples_per_pixel": args.spp * len(args.seeds), "seeds": args.seeds,
              "mitsuba_vs_reference": summary(metrics(ours, reference)), "glint": {}}
    print(f"Mitsuba ({result['samples_per_pixel']} spp) against the reference: {result['mitsuba_vs_reference']}")
    hit_m = block_ratios(ours, reference)[0]
    for path in args.glint:
        g = read_image(path)[..., :3].astype(np.float64)
        hit_g = block_ratios(g, reference)[0]
        entry = {"vs_reference": summary(metrics(g, reference)), "vs_mitsuba": summary(metrics(g, ours)),
                 "blocks_glint_misses_mitsuba_hits": int((~hit_g & hit_m).sum()),
                 "blocks_mitsuba_misses_glint_hits": int((hit_g & ~hit_m).sum()),
                 "blocks_both_miss": int((~hit_g & ~hit_m).sum())}
        result["glint"][str(path)] = entry
        print(f"{path}: {json.dumps(entry)}")
    write_json(args.out / "mitsuba_external.json", result)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
