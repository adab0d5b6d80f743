"""Accumulation pass (compute): adds one still-camera frame to the fp32 running sum and
writes the image to show, the running mean (shaders/accumulate.comp). The state around
it -- when to restart, which samples a frame takes -- is viewer/progressive.py.
"""
from __future__ import annotations

import moderngl

from glint.viewer.gl_bindings import BASE_UNIT, SHOWN_IMAGE, SOURCE_UNIT, TARGET_IMAGE
from glint.viewer.passes import ImagePass


class AccumulatePass(ImagePass):
    name = "accumulate"
    shader = "accumulate.comp"
    images = ("sum", "shown", "base")

    def resize(self, size: tuple[int, int]) -> None:
        for attribute in self.images:
            self._image(attribute, size, "f4")

    def keep_base(self, image: moderngl.Texture) -> None:
        """Copy `image` (same size, rgba32f) as the image the mean is blended from."""
        self.resize(image.size)
        # Framebuffer to framebuffer (a blit): copying into the texture itself converts the
        # values on Mesa (moderngl's glCopyTexImage2D path), a blit keeps fp32 bits exactly.
        source, target = self.ctx.framebuffer([image]), self.ctx.framebuffer([self.base])
        try:
            self.ctx.copy_framebuffer(target, source)
        finally:
            source.release()
            target.release()

    def run(self, radiance: moderngl.Texture, frame: int, blend: float = 1.0) -> moderngl.Texture:
        """Add `radiance` as frame number `frame` (0 restarts the sum); returns the image to show."""
        self.resize(radiance.size)
        radiance.use(SOURCE_UNIT)
        self.base.use(BASE_UNIT)
        self.sum.bind_to_image(TARGET_IMAGE, read=True, write=True)
        self.shown.bind_to_image(SHOWN_IMAGE, read=False, write=True)
        self._dispatch(radiance.size, moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT,
                       frame=int(frame), blend=float(min(max(blend, 0.0), 1.0)))
        return self.shown
