"""The G-buffer through a visibility buffer against the raster G-buffer (viewer/passes/gbuffer.py,
issue 27): the same frames, how close and how fast.

    python3 -m glint.bench.measure_visibility [--scenes living-room many-1000 ...] [--size 640x360]
                                              [--out DIR]

Per scene and camera, two renderers in one process, one each way (the G-buffer and the mirror passes),
drawing walkthrough frames alternately in blocks (a machine's changing load falls on both): medians of
the G-buffer's and the mirror passes' times (viewer/timing.py: glFinish-bracketed on a software
renderer, timer queries on a GPU) and of the whole frame's wall time (render() and glFinish). Then one frame each way compared pixel by pixel (linear
radiance): the largest relative difference |a - b| / max(|a|, |b|, 1e-6) of any channel, the pixels
over 1e-3, and whether the depth is the same; after the table, per view, what differs in the two
G-buffers at those pixels and the worst pixel both ways (`explain`). Scenes: built-in names, or many-N (N boxes:
bench/measure_draw_count.py); draft bakes are made in DIR when missing.
"""
from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path


def relative_difference(a, b):
    """(H, W) per pixel the largest relative difference |a - b| / max(|a|, |b|, 1e-6) of any channel of
    two (H, W, C) images."""
    import numpy as np

    return (np.abs(a - b) / np.maximum(np.maximum(np.abs(a), np.abs(b)), 1e-6)).max(axis=-1)


def rounded(values, digits: int = 5) -> list:
    return [round(float(v), digits) for v in values]


def explain(renderers: dict, images: dict, rel, bake) -> str:
    """Where the pixels over 1e-3 of `rel` come from, read off the two G-buffers (False: raster, True:
    visibility): ids or flags differ; the diffuse radiance (light map x textures) differs by over 1e-3,
    on a material with a base-colour texture or without; only the normal word differs (a lobe reads
    elsewhere); nothing in the G-buffer differs (the mirror buffers or what reads them). Then the worst
    pixel, both ways."""
    import numpy as np

    from glint.viewer.passes.gbuffer import read_gbuffer

    g = {vis: {k: v[::-1] for k, v in read_gbuffer(r.gbuffer.targets).items()} for vis, r in renderers.items()}
    a, b = g[False], g[True]  # image rows, row 0 at the top
    if a["diffuse"].shape[:2] != rel.shape:
        return "(supersampled: no breakdown)"
    over = rel > 1e-3
    diffuse = relative_difference(a["diffuse"], b["diffuse"]) > 1e-3
    ids = (a["material"] != b["material"]) | (a["object"] != b["object"]) | (a["flags"] != b["flags"])
    normal = np.any(a["normal"] != b["normal"], axis=-1)  # another octahedral word
    textured = np.array([m.kd_texture is not None for m in bake.model.materials] + [False])
    is_textured = textured[np.clip(a["material"], 0, len(textured) - 1)]
    parts = {"ids or flags": over & ids, "diffuse, textured": over & ~ids & diffuse & is_textured,
             "diffuse, untextured": over & ~ids & diffuse & ~is_textured,
             "normal word only": over & ~ids & ~diffuse & normal,
             "G-buffer the same": over & ~ids & ~diffuse & ~normal}
    words = ", ".join(f"{k} {int(v.sum())}" for k, v in parts.items())
    y, x = np.unravel_index(np.argmax(rel), rel.shape)
    names = [o.name for o in bake.model.objects]
    o = int(a["object"][y, x])
    worst = (f"worst pixel ({x}, {y} from the top left), object {names[o] if 0 <= o < len(names) else o}: "
             + "; ".join(f"{'visibility' if vis else 'raster'} image {rounded(images[vis][y, x])} "
                         f"diffuse {rounded(g[vis]['diffuse'][y, x])} normal {rounded(g[vis]['normal'][y, x], 4)} "
                         f"object {int(g[vis]['object'][y, x])} material {int(g[vis]['material'][y, x])} "
                         f"flags {int(g[vis]['flags'][y, x]):#x}" for vis in (False, True)))
    return f"over 1e-3: {words}; {worst}"


def setup(prog: str, doc: str, scenes: list[str], out: str, argv=None, options=None):
    """The A/B tools' command line (--scenes, --size, --out, and what `options(parser)` adds) and
    context: (args, ctx, width, height); prints the device and what the medians are of."""
    import moderngl

    from glint.bench.measure_draw_count import BLOCKS, FRAMES
    from glint.viewer.gl import describe

    p = argparse.ArgumentParser(prog=f"python3 -m glint.bench.{prog}", description=doc.splitlines()[0])
    p.add_argument("--scenes", nargs="+", default=scenes)
    p.add_argument("--size", default="640x360")
    p.add_argument("--out", type=Path, default=Path(out))
    if options is not None:
        options(p)
    args = p.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))
    args.out.mkdir(parents=True, exist_ok=True)
    ctx = moderngl.create_standalone_context(backend="egl", require=430)
    print(f"{describe(ctx)}, {width}x{height}, walkthrough frames, medians of {BLOCKS * FRAMES} per side")
    return args, ctx, width, height


def paired_views(ctx, args, width: int, height: int, option: str, values=(False, True)):
    """For every camera of every scene of `args` (draft bakes in args.out): two renderers,
    Renderer(option=values[0]) and Renderer(option=values[1]), drawing walkthrough frames alternately
    (measure_draw_count.py `alternate`); yields (scene, camera entry, {value: renderer}, {value: ms}
    medians of the frame's wall time) and releases the renderers after."""
    from glint.bench.measure_draw_count import alternate, bake_for
    from glint.core.bake_dir import Bake
    from glint.viewer.camera import ViewCamera
    from glint.viewer.renderer import Renderer

    for name in args.scenes:
        bake = Bake(bake_for(name, args.out))
        for entry in bake.model.cameras:
            camera = ViewCamera.from_manifest(entry)
            renderers = {on: Renderer(ctx, bake, **{option: on}) for on in values}
            try:
                frame = alternate(ctx, {on: (lambda r=r, camera=camera: r.render(camera, width, height))
                                        for on, r in renderers.items()})
                yield name, entry, renderers, {on: statistics.median(ms) for on, ms in frame.items()}
            finally:
                for r in renderers.values():
                    r.release()


def main(argv=None) -> int:
    import numpy as np

    args, ctx, width, height = setup("measure_visibility", __doc__, ["cornell-box", "living-room", "material-classes",
                                                                     "planar-classes", "many-1000"], "visibility", argv)
    print("| scene, camera | G-buffer ms: raster / visibility | mirror passes ms: raster / visibility "
          "| frame ms: raster / visibility | frame ratio | largest relative difference | pixels over 1e-3 | same depth |")
    print("|---|---|---|---|---:|---:|---:|---|")
    notes = []
    for name, entry, renderers, frame in paired_views(ctx, args, width, height, "visibility"):
        passes = {vis: r.timer.median_ms for vis, r in renderers.items()}
        gbuffer = {vis: m.get("gbuffer", float("nan")) for vis, m in passes.items()}
        mirror = {vis: m.get("mirror_passes") for vis, m in passes.items()}
        mirror_ms = "-" if mirror[False] is None else f"{mirror[False]:.2f} / {mirror[True]:.2f}"
        images = {vis: r.read_linear() for vis, r in renderers.items()}
        depth = {vis: np.frombuffer(r.gbuffer.targets["depth"].read(), np.float32) for vis, r in renderers.items()}
        rel = relative_difference(images[False], images[True])
        a, b = frame[False], frame[True]
        print(f"| {name}, {entry.name} | {gbuffer[False]:.2f} / {gbuffer[True]:.2f} | {mirror_ms} | {a:.2f} / {b:.2f} "
              f"| {b / a:.3f} | {rel.max():.2e} | {int((rel > 1e-3).sum())} of {width * height} "
              f"| {'yes' if np.array_equal(depth[False], depth[True]) else 'no'} |", flush=True)
        notes.append(f"- {name}, {entry.name}: {explain(renderers, images, rel, renderers[False].bake)}")
    print("\n".join(["", *notes]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
