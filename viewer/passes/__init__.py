"""Render passes, one module each; `ImagePass` is the shape the compute passes that turn one image
into another share (resolve, tone map, accumulation)."""
from __future__ import annotations

import moderngl

from glint.viewer.shader_source import compute_program, dispatch, set_uniforms


class ImagePass:
    """A compute program over an image, and the rgba textures it owns (the attributes named in
    `images`), made anew when the size asked for changes."""

    shader = ""                     # the compute shader, a file of the shaders package
    images: tuple[str, ...] = ()    # attributes holding the pass's own textures (None until made)

    def __init__(self, ctx: moderngl.Context, defines: dict | None = None):
        self.ctx = ctx
        self.program = compute_program(ctx, self.shader, defines)
        for attribute in self.images:
            setattr(self, attribute, None)

    def _image(self, attribute: str, size: tuple[int, int], dtype: str, filter: int = moderngl.NEAREST):
        """The texture in `attribute`, replaced by a new rgba one of `dtype` unless it has `size`."""
        texture = getattr(self, attribute)
        if texture is None or texture.size != size:
            if texture is not None:
                texture.release()
            texture = self.ctx.texture(size, 4, dtype=dtype)
            texture.filter = (filter, filter)
            setattr(self, attribute, texture)
        return texture

    def _dispatch(self, size: tuple[int, int], barrier: int, **uniforms) -> None:
        """Set `uniforms`, run the program over `size` pixels, then the memory barrier `barrier`."""
        set_uniforms(self.program, **uniforms)
        dispatch(self.program, *size)
        self.ctx.memory_barrier(barrier)

    def _release_images(self) -> None:
        for attribute in self.images:
            texture = getattr(self, attribute)
            if texture is not None:
                texture.release()
            setattr(self, attribute, None)

    def release(self) -> None:
        self._release_images()
        self.program.release()
