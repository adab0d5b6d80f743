"""Raster fill rate of the GL device against the G-buffer pass: is the G-buffer bound by the
hardware's raster back end or by our shader?

    python3 -m glint.bench.measure_fill_rate [--size 1920x1080] [--frames 60]

Times (GPU timer queries; glFinish wall clock on llvmpipe), medians of --frames after 5 warm-up
frames, one full-screen triangle each:
- "rgba8 x1": a constant colour into one RGBA8 target (the device's plain fill rate);
- "gbuffer targets": constant values into the G-buffer's own targets (viewer/passes/gbuffer.py:
  RGBA32F + 2 x RGBA16F + R32UI + depth), no texture reads: the cost of the G-buffer's bytes;
- "compute write": a compute shader writing the same bytes into the same textures as images.
The G-buffer pass of a real scene (bench/measure_frame_times.py) minus "gbuffer targets" is the
part our vertex/fragment work adds.
"""
from __future__ import annotations

import argparse
import time
from statistics import median

from glint.viewer.context import headless_context
from glint.viewer.gl import describe
from glint.viewer.timing import default_method

VS = """#version 430
void main() { vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2); gl_Position = vec4(p * 2.0 - 1.0, 0.5, 1.0); }"""
FS_ONE = """#version 430
out vec4 colour; void main() { colour = vec4(0.2, 0.4, 0.6, 1.0); }"""
FS_GBUFFER = """#version 430
layout(location = 0) out vec4 diffuse; layout(location = 1) out vec4 normal;
layout(location = 2) out vec4 tangent; layout(location = 3) out uint material;
void main() { diffuse = vec4(0.2, 0.4, 0.6, 1.0); normal = vec4(0, 0, 1, 0); tangent = vec4(1, 0, 0, 0); material = 3u; }"""
CS_GBUFFER = """#version 430
layout(local_size_x = 8, local_size_y = 8) in;
layout(rgba32f, binding = 0) writeonly uniform image2D diffuse;
layout(rgba16f, binding = 1) writeonly uniform image2D normal;
layout(rgba16f, binding = 2) writeonly uniform image2D tangent;
layout(r32ui, binding = 3) writeonly uniform uimage2D material;
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, imageSize(diffuse)))) return;
    imageStore(diffuse, p, vec4(0.2, 0.4, 0.6, 1.0)); imageStore(normal, p, vec4(0, 0, 1, 0));
    imageStore(tangent, p, vec4(1, 0, 0, 0)); imageStore(material, p, uvec4(3u));
}"""


def timed(ctx, fn, frames: int, method: str) -> float:
    query = ctx.query(time=True) if method == "query" else None
    samples = []
    for i in range(frames + 5):
        if query is not None:
            with query:
                fn()
            ms = query.elapsed / 1e6
        else:
            ctx.finish()
            t = time.perf_counter()
            fn()
            ctx.finish()
            ms = (time.perf_counter() - t) * 1e3
        if i >= 5:
            samples.append(ms)
    return median(samples)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="1920x1080")
    ap.add_argument("--frames", type=int, default=60)
    args = ap.parse_args()
    w, h = (int(x) for x in args.size.lower().split("x"))
    ctx = headless_context()
    method = default_method(ctx)
    vao_one = ctx.vertex_array(ctx.program(vertex_shader=VS, fragment_shader=FS_ONE), [])
    vao_gb = ctx.vertex_array(ctx.program(vertex_shader=VS, fragment_shader=FS_GBUFFER), [])
    one = ctx.framebuffer([ctx.texture((w, h), 4)])
    targets = [ctx.texture((w, h), 4, dtype="f4"), ctx.texture((w, h), 4, dtype="f2"),
               ctx.texture((w, h), 4, dtype="f2"), ctx.texture((w, h), 1, dtype="u4")]
    gbuffer = ctx.framebuffer(targets, ctx.depth_texture((w, h)))
    cs = ctx.compute_shader(CS_GBUFFER)

    def fill_one():
        one.use()
        vao_one.render(vertices=3)

    def fill_gbuffer():
        gbuffer.use()
        ctx.enable(ctx.DEPTH_TEST)
        gbuffer.clear(depth=1.0)
        vao_gb.render(vertices=3)
        ctx.disable(ctx.DEPTH_TEST)

    def compute_write():
        for unit, t in enumerate(targets):
            t.bind_to_image(unit, read=False, write=True)
        cs.run((w + 7) // 8, (h + 7) // 8)

    print(describe(ctx), f"{w}x{h}, timing: {method}")
    for name, fn, bytes_per_pixel in (("rgba8 x1", fill_one, 4), ("gbuffer targets", fill_gbuffer, 40),
                                      ("compute write", compute_write, 36)):
        ms = timed(ctx, fn, args.frames, method)
        print(f"{name:16s} {ms:8.3f} ms  {w * h / ms / 1e6:8.2f} Gpixel/s  {w * h * bytes_per_pixel / ms / 1e6:8.1f} GB/s")


if __name__ == "__main__":
    main()
