"""The counted multi-draw against every command to the driver (viewer/draw_list.py, issue 27): wall
time of walkthrough frames in one renderer, the two alternating in blocks (so a machine's changing
load falls on both), medians; docs/VIEWER.md, "Draws the driver never sees".

    python3 -m glint.bench.measure_draw_count [--scenes living-room many-1000 ...] [--size 640x360] [--out DIR]

Scenes: built-in names, many-N (scenes/stress.py `many_objects`, N boxes) or .glb/.gltf files. Draft bakes are
made in DIR when missing.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

BLOCKS = 8        # alternating blocks per side
FRAMES = 8        # timed frames per block
WARMUP = 3        # untimed frames after each switch


def bake_for(name: str, out: Path, quality: str | None = "draft") -> Path:
    """A bake of `name` made once in `out` (out/STEM.bake; a bake there that is out of date is redone):
    a built-in scene, many-N (scenes/stress.py `many_objects`, N boxes) or a .glb/.gltf file, at the
    quality preset `quality` (None: the scene's own settings)."""
    from glint.bake.gltf_loader import load_scene
    from glint.bake.settings import resolve_settings
    from glint.scenes import builtin_path
    from glint.scenes.stress import many_objects
    from glint.services import bake_scene

    if name.startswith("many-"):
        path = many_objects(out / "scenes", int(name[5:]), metal_every=None).path
    elif name.endswith((".glb", ".gltf")):
        path = Path(name)
    else:
        path = builtin_path(name)
    bake_dir = out / f"{Path(name).stem}.bake"
    scene = load_scene(path)
    bake_scene(scene, resolve_settings(scene.bake_settings, quality=quality), bake_dir,
               progress=False)  # no work when up to date
    return bake_dir


def alternate(ctx, render: dict, blocks: int = BLOCKS, frames: int = FRAMES, warmup: int = WARMUP) -> dict:
    """Wall times (ms) of `render`'s callables (each draws one frame), the sides alternating in
    `blocks` blocks of `frames` timed frames after `warmup` untimed ones, every other block in the
    other order, each frame followed by glFinish: {key: [ms, ...]}."""
    keys = list(render)
    times = {k: [] for k in keys}
    for block in range(blocks):
        for k in keys if block % 2 == 0 else keys[::-1]:
            for _ in range(warmup):
                render[k]()
                ctx.finish()
            for _ in range(frames):
                t = time.perf_counter()
                render[k]()
                ctx.finish()
                times[k].append((time.perf_counter() - t) * 1e3)
    return times


def main(argv=None) -> int:
    import moderngl

    from glint.core.bake_dir import Bake
    from glint.viewer.camera import ViewCamera
    from glint.viewer.renderer import Renderer

    p = argparse.ArgumentParser(prog="python3 -m glint.bench.measure_draw_count", description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="+", default=["living-room", "many-10", "many-1000", "many-10000"])
    p.add_argument("--size", default="640x360")
    p.add_argument("--out", type=Path, default=Path("draw-count"))
    args = p.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))
    args.out.mkdir(parents=True, exist_ok=True)
    ctx = moderngl.create_standalone_context(backend="egl", require=430)
    for name in args.scenes:
        bake = Bake(bake_for(name, args.out))
        camera = ViewCamera.from_manifest(bake.model.cameras[0])
        with Renderer(ctx, bake) as r:
            if not r.draws.can_count:
                print(f"{name}: the driver offers no glMultiDrawElementsIndirectCount")
                continue
            def frame(counted: bool, r=r, camera=camera) -> None:
                r.draws.indirect_count = counted
                r.render(camera, width, height)

            times = alternate(ctx, {True: lambda: frame(True), False: lambda: frame(False)})
            a, b = (statistics.median(times[k]) for k in (True, False))
            print(f"{name}: counted {a:.2f} ms, uncounted {b:.2f} ms, ratio {a / b:.3f} "
                  f"(objects drawn {r.stats['objects_drawn']} of {len(r.scene.objects)})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
