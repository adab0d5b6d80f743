"""Supersampling resolve (compute): the mean of each N x N block of the shaded image.

Captures render at N times the output size so a pixel integrates over its area
like a path tracer's box filter; the window uses N = 1 and skips this pass.
"""
from __future__ import annotations

import moderngl

from glint.viewer.gl_bindings import SOURCE_UNIT, TARGET_IMAGE
from glint.viewer.shader_source import compute_program, dispatch, set_uniforms


class ResolvePass:
    name = "resolve"

    def __init__(self, ctx: moderngl.Context, defines: dict | None = None):
        self.ctx = ctx
        self.program = compute_program(ctx, "resolve.comp", defines)
        self.resolved: moderngl.Texture | None = None

    def run(self, radiance: moderngl.Texture, factor: int) -> moderngl.Texture:
        """(W N, H N) rgba32f -> (W, H) rgba32f block means."""
        w, h = radiance.size
        if w % factor or h % factor:
            raise ValueError(f"image {w}x{h} is not a multiple of the supersampling factor {factor}")
        size = (w // factor, h // factor)
        if self.resolved is None or self.resolved.size != size:
            if self.resolved is not None:
                self.resolved.release()
            self.resolved = self.ctx.texture(size, 4, dtype="f4")
            self.resolved.filter = (moderngl.NEAREST, moderngl.NEAREST)
        set_uniforms(self.program, factor=int(factor))
        radiance.use(SOURCE_UNIT)
        self.resolved.bind_to_image(TARGET_IMAGE, read=False, write=True)
        dispatch(self.program, *size)
        self.ctx.memory_barrier(moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT)
        return self.resolved

    def release(self) -> None:
        if self.resolved is not None:
            self.resolved.release()
        self.program.release()
