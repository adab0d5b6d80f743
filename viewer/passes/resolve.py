"""Supersampling resolve (compute): the mean of each N x N block of the shaded image.

Captures render at N times the output size so a pixel integrates over its area
like a path tracer's box filter; the window uses N = 1 and skips this pass.
"""
from __future__ import annotations

import moderngl

from glint.viewer.gl_bindings import SOURCE_UNIT, TARGET_IMAGE
from glint.viewer.passes import ImagePass


class ResolvePass(ImagePass):
    name = "resolve"
    shader = "resolve.comp"
    images = ("resolved",)

    def run(self, radiance: moderngl.Texture, factor: int) -> moderngl.Texture:
        """(W N, H N) rgba32f -> (W, H) rgba32f block means."""
        w, h = radiance.size
        if w % factor or h % factor:
            raise ValueError(f"image {w}x{h} is not a multiple of the supersampling factor {factor}")
        size = (w // factor, h // factor)
        resolved = self._image("resolved", size, "f4")
        radiance.use(SOURCE_UNIT)
        resolved.bind_to_image(TARGET_IMAGE, read=False, write=True)
        self._dispatch(size, moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT,
                       factor=int(factor))
        return resolved
