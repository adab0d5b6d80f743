"""A thinner raster pass against today's G-buffer: is a visibility buffer worth building?

    python3 -m glint.bench.measure_thin_raster [--scenes living-room,...] [--sizes 640x360,1920x1080]
                                               [--frames 20] [--bake-root DIR]

For every scene (its first camera) and size, the G-buffer pass's time (viewer/passes/gbuffer.py:
five colour targets, 40 bytes per pixel, every texture and the light map read per fragment)
against the raster half of a visibility buffer drawn by the same GPU-driven draw
(viewer/draw_list.py) into one RG32UI target + depth (object and triangle id per pixel:
shaders/visibility.frag). The visibility buffer's raster time is a lower bound of what it would
cost: it still needs a compute pass that rebuilds each pixel's attributes from the triangle
(fetch three vertices, intersect the pixel's ray, interpolate, sample the textures with
analytic derivatives), which costs at least the G-buffer fragment work it moves. Medians of
--frames after 5 warm-up frames (measure_fill_rate.py `timed`); timing as viewer/timing.py (glFinish wall clock on llvmpipe,
timer queries on a GPU).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import moderngl

from glint.bench.measure_fill_rate import timed
from glint.bench.measure_frame_times import SCENES, load_bake
from glint.viewer.camera import ViewCamera
from glint.viewer.context import headless_context
from glint.viewer.gl import describe
from glint.viewer.gpu_scene import shader_defines
from glint.viewer.renderer import Renderer
from glint.viewer.shader_source import raster_program, set_uniforms
from glint.viewer.timing import default_method


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--sizes", default="640x360,1920x1080")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--bake-root", default=None)
    args = ap.parse_args()
    ctx = headless_context()
    method = default_method(ctx)
    print(f"{describe(ctx)}; timing: {method}")
    print("| scene | size | G-buffer ms | visibility raster ms | ratio |\n|---|---|---:|---:|---:|")
    visibility = raster_program(ctx, "gbuffer.vert", "visibility.frag", shader_defines())
    for scene in args.scenes.split(","):
        bake = load_bake(scene, None if args.bake_root is None else Path(args.bake_root))
        camera = ViewCamera.from_manifest(bake.model.cameras[0])
        with Renderer(ctx, bake) as r:
            for size in args.sizes.split(","):
                w, h = (int(x) for x in size.lower().split("x"))
                aspect = w / h
                r.gbuffer.resize((w, h))
                ids = ctx.texture((w, h), 2, dtype="u4")
                depth = ctx.depth_texture((w, h))
                fbo = ctx.framebuffer([ids], depth)

                def gbuffer():
                    r.gbuffer.run(camera, aspect)

                def thin():
                    fbo.use()
                    ctx.enable_only(moderngl.DEPTH_TEST)
                    fbo.clear(depth=1.0)
                    set_uniforms(visibility, eye=tuple(map(float, camera.eye)))
                    r.draws.draw(visibility, camera.view_projection(aspect))

                full_ms = timed(ctx, gbuffer, args.frames, method)
                thin_ms = timed(ctx, thin, args.frames, method)
                print(f"| {scene} | {w}x{h} | {full_ms:.2f} | {thin_ms:.2f} | {thin_ms / full_ms:.2f} |", flush=True)
                for obj in (fbo, ids, depth):
                    obj.release()


if __name__ == "__main__":
    main()
