"""Tone mapping (compute): linear radiance -> 8-bit sRGB for display and PNG captures.

exposure 2^EV, then the ACES filmic curve as fitted by Narkowicz (2016), then the
sRGB OETF; all in shaders/colour.glsl.
"""
from __future__ import annotations

import moderngl
import numpy as np

from glint.viewer.gl_bindings import SOURCE_UNIT, TARGET_IMAGE
from glint.viewer.shader_source import compute_program, dispatch, set_uniforms


class TonemapPass:
    name = "tonemap"

    def __init__(self, ctx: moderngl.Context, defines: dict | None = None):
        self.ctx = ctx
        self.program = compute_program(ctx, "tonemap.comp", defines)
        self.display: moderngl.Texture | None = None

    def run(self, radiance: moderngl.Texture, exposure: float) -> moderngl.Texture:
        """rgba32f radiance -> RGBA8 texture of the same size (GL orientation, row 0 at the bottom)."""
        size = radiance.size
        if self.display is None or self.display.size != size:
            if self.display is not None:
                self.display.release()
            self.display = self.ctx.texture(size, 4, dtype="f1")
            self.display.filter = (moderngl.LINEAR, moderngl.LINEAR)
        ev = float(exposure) if np.isfinite(exposure) else 0.0
        scale = float(np.exp2(np.clip(ev, -126.0, 127.0)))  # a finite, normal fp32 scale
        set_uniforms(self.program, exposure_scale=scale)
        radiance.use(SOURCE_UNIT)
        self.display.bind_to_image(TARGET_IMAGE, read=False, write=True)
        dispatch(self.program, *size)
        self.ctx.memory_barrier(moderngl.ALL_BARRIER_BITS)  # read back, blitted or sampled next
        return self.display

    def release(self) -> None:
        if self.display is not None:
            self.display.release()
        self.program.release()
