"""Tone mapping (compute): linear radiance -> 8-bit sRGB for display and PNG captures.

exposure 2^EV, then the ACES filmic curve as fitted by Narkowicz (2016), then the
sRGB OETF; all in shaders/colour.glsl.
"""
from __future__ import annotations

import moderngl
import numpy as np

from glint.viewer.gl_bindings import SOURCE_UNIT, TARGET_IMAGE
from glint.viewer.passes import ImagePass


class TonemapPass(ImagePass):
    name = "tonemap"
    shader = "tonemap.comp"
    images = ("display",)

    def run(self, radiance: moderngl.Texture, exposure: float) -> moderngl.Texture:
        """rgba32f radiance -> RGBA8 texture of the same size (GL orientation, row 0 at the bottom)."""
        size = radiance.size
        display = self._image("display", size, "f1", moderngl.LINEAR)
        ev = float(exposure) if np.isfinite(exposure) else 0.0
        scale = float(np.exp2(np.clip(ev, -126.0, 127.0)))  # a finite, normal fp32 scale
        radiance.use(SOURCE_UNIT)
        display.bind_to_image(TARGET_IMAGE, read=False, write=True)
        self._dispatch(size, moderngl.ALL_BARRIER_BITS, exposure_scale=scale)  # read back, blitted or sampled next
        return display
