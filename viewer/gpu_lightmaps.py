"""The light maps on the GPU: one texture array (`texture`), a layer per page, RGBA16F, or RGBA32F when a
value does not fit in half float (very bright emitters must not become Inf); GL_LINEAR and clamp to
edge, which is `glint.core.image_io.sample_bilinear`. RGB is the irradiance E (Eq. 4.1: diffuse
radiance = kd/pi E), read by shaders/raster_surface.glsl's `lightmaps` at LIGHTMAP_UNIT
(viewer/gl_bindings.py, bound by viewer/draw_list.py). Row 0 of a page (v = 0) is the first row
uploaded, i.e. GL's t = 0: no flip anywhere. The back-side pages of two-sided objects
(core/bake_dir.py `lightmaps_back`) follow the front pages in the same array: an object with a back
side has `back_layer` = the number of front pages (viewer/gpu_objects.py), which a back face adds to
its page; 0 for the others. A re-bake's pages replace them in place (`replace`).
"""
from __future__ import annotations

import moderngl
import numpy as np

from glint.core.constants import HALF_MAX
from glint.core.errors import GlintError
from glint.viewer.gl import GL, check_texture_size
from glint.viewer.gpu_textures import clean


class GpuLightmaps:
    def __init__(self, ctx: moderngl.Context, gl: GL, bake):
        self.ctx, self._gl = ctx, gl
        names = bake.model.lightmaps
        pages = [bake.lightmap(k) for k in range(len(names))]
        if names:  # the back sides' pages, layers len(names) on (GpuObject.back_layer)
            pages += [bake.lightmap(k, back=True) for k in range(len(bake.back_pages))]
        if not pages:
            pages = [np.zeros((1, 1, 4))]
        data, (w, h) = lightmap_stack(pages, f"{bake.path}: light-map pages", "run `glint bake --force`")
        self.dtype = "f2" if data.dtype == np.float16 else "f4"
        what = f"the light maps ({len(pages)} pages)"
        check_texture_size(self.ctx, w, h, what, layers=len(pages),
                           fix="bake with a lower --texels-per-metre or [bake] max_page_size")
        with self._gl.checked(f"upload {what}"):
            self.texture = self.ctx.texture_array((w, h, len(pages)), 4, data.tobytes(), dtype=self.dtype)
        self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.texture.repeat_x = self.texture.repeat_y = False  # clamp to edge

    def replace(self, front: list[np.ndarray], back: list[np.ndarray]) -> None:
        """New light maps for the same atlas (a re-bake after a material edit, bake/rebake.py): the
        front pages and the back sides' pages as the bake directory stores them ((H, W, 4), A unused
        by the shaders), as many and as large as the bake's. Written into the texture array in place;
        a half-float array that the new values no longer fit becomes float32 (never Inf)."""
        w, h, layers = self.texture.size[0], self.texture.size[1], self.texture.layers
        pages = [*front, *back]
        if len(pages) != layers or any(np.shape(p)[:2] != (h, w) for p in pages):
            raise GlintError(f"new light maps: {len(pages)} pages of {sorted({np.shape(p)[:2] for p in pages})} "
                             f"for the bake's {layers} of {(h, w)}; re-bake into the same atlas")
        data, _ = lightmap_stack(pages, "new light-map pages", "re-bake into the same atlas")
        dtype = "f2" if data.dtype == np.float16 and self.dtype == "f2" else "f4"
        if dtype != self.dtype:
            with self._gl.checked(f"allocate the light maps ({layers} pages) in float32"):
                texture = self.ctx.texture_array((w, h, layers), 4, data.astype(np.float32).tobytes(), dtype="f4")
            texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
            texture.repeat_x = texture.repeat_y = False
            self.texture.release()
            self.texture, self.dtype = texture, "f4"
            return
        with self._gl.checked(f"upload the light maps ({layers} pages)"):
            self.texture.write(data.astype(np.float16 if dtype == "f2" else np.float32).tobytes())

    def release(self) -> None:
        self.texture.release()


def lightmap_stack(pages: list[np.ndarray], what: str, fix: str) -> tuple[np.ndarray, tuple[int, int]]:
    """Pages (H, W, 3 or 4) -> one (layers, H, W, 4) array to upload, non-finite values 0 and
    negatives 0 (`clean`), in float16 where every value fits (|v| <= HALF_MAX), else float32."""
    shapes = {np.shape(p)[:2] for p in pages}
    if len(shapes) != 1:
        raise GlintError(f"{what} differ in size ({sorted(shapes)}); {fix}")
    h, w = shapes.pop()
    stack = np.zeros((len(pages), h, w, 4), np.float32)
    for k, p in enumerate(pages):
        p = clean(p)
        stack[k, :, :, :p.shape[2]] = p[..., :4]
    fits = stack.max(initial=0.0) <= HALF_MAX
    return stack.astype(np.float16) if fits else stack, (w, h)
