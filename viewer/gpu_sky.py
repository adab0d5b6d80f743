"""The sky on the GPU: none, a constant radiance, or the equirectangular sky.exr (times the radiance as a
scale; RGBA32F, repeating in u and clamped in v as bake/lights.py samples it). shaders/sky.glsl reads
it: the uniforms `sky_mode` (SKY_MODES, also its defines: viewer/gpu_scene.py `shader_defines`) and
`sky_scale` (`uniforms`), and the map `sky_map` at SKY_UNIT (viewer/gl_bindings.py), which the shading
and mirror passes bind (the 1x1 white texture where there is no map).
"""
from __future__ import annotations

import moderngl
import numpy as np

from glint.core.image_io import read_image
from glint.viewer.gl import GL, check_texture_size
from glint.viewer.gpu_textures import clean

SKY_MODES = {"SKY_NONE": 0, "SKY_CONSTANT": 1, "SKY_MAP": 2}


class GpuSky:
    def __init__(self, ctx: moderngl.Context, gl: GL, bake, white: moderngl.Texture):
        """white: the 1x1 texture bound as the map of a sky without one (not released here)."""
        sky = bake.model.sky
        self.mode = SKY_MODES["SKY_NONE"]
        self.scale = np.zeros(3, np.float32)
        self.map = self._white = white
        if not sky:
            return
        self.scale = clean(sky.radiance).astype(np.float32)
        if sky.map:
            image = clean(read_image(bake.path / sky.map)[..., :3])
            h, w = image.shape[:2]
            rgba = np.concatenate([image, np.ones((h, w, 1))], axis=-1).astype(np.float32)
            check_texture_size(ctx, w, h, "the sky map", fix="scale it down")
            with gl.checked("upload the sky map"):
                self.map = ctx.texture((w, h), 4, rgba.tobytes(), dtype="f4")
            self.map.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self.map.repeat_x, self.map.repeat_y = True, False  # wrap in u, clamp in v
            self.mode = SKY_MODES["SKY_MAP"]
        elif np.any(self.scale > 0):
            self.mode = SKY_MODES["SKY_CONSTANT"]

    def uniforms(self) -> dict:
        return {"sky_mode": self.mode, "sky_scale": tuple(map(float, self.scale))}

    def release(self) -> None:
        if self.map is not self._white:
            self.map.release()
