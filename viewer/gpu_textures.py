"""The materials' textures on the GPU, and the one sanitiser of every value the scene uploads (`clean`).

Per material up to five 2-D textures, RGBA16F, each mip-mapped and repeating (the glTF default
sampler; a material's other samplers are its MAT_KD_* flags, viewer/gpu_materials.py), one texture
each (sizes differ, so no array):

- base colour (manifest `kd_texture`), clamped to 0..1; A is the base colour alpha for MASK and
  BLEND materials (the raster passes' coverage test), 1 for the others;
- emission (`emission_texture`, only where the material emits), linear RGB >= 0: it multiplies
  `emission` (glTF 3.9.3);
- metallic-roughness (G roughness multiplier, B metallic M'), normal map and anisotropy direction
  (`metallic_roughness_texture`, `normal_texture`, `anisotropy_texture`), linear, in 0..1.

All are read with the base colour's uv and sampler flags (the loader's choice, bake/gltf_materials.py)
by shaders/raster_surface.glsl's `kd_texture`, `emission_texture`, `metallic_roughness_texture`,
`normal_texture` and `anisotropy_texture`, at KD_TEXTURE_UNIT .. ANISOTROPY_TEXTURE_UNIT
(viewer/gl_bindings.py), which a draw binds in `material_textures` order (viewer/draw_list.py
TEXTURE_UNITS). Where a material has none of a kind the 1x1 white one (`white`) stands in; it is
also the sky map of a scene without one (viewer/gpu_sky.py).
"""
from __future__ import annotations

import moderngl
import numpy as np

from glint.core.constants import HALF_MAX
from glint.core.image_io import read_image
from glint.core.manifest import Material
from glint.viewer.gl import GL, check_texture_size

# The kinds of material texture, in the order a draw binds them (viewer/draw_list.py TEXTURE_UNITS)
TEXTURE_KINDS = ("kd", "emission", "metallic_roughness", "normal", "anisotropy")


def clean(a, lo=0.0, hi=None) -> np.ndarray:
    """Non-finite -> 0, then clamped to [lo, hi] (what bake/lights.py and irradiance.py do). float32
    input stays float32 (texture images: half the memory and time), anything else is float64."""
    a = np.asarray(a)
    a = np.nan_to_num(a if a.dtype == np.float32 else a.astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    return a if lo is None and hi is None else np.clip(a, lo, hi)


def clamped(image: np.ndarray, hi: float) -> np.ndarray:
    """`image` with non-finite values 0, clamped to [0, hi] (`clean`). A float16 image (a half-float
    bake file) whose bits show every value already there -- positive halves order as their bits --
    comes back as it is: no float32 copy, and the same half floats the copy would round back to."""
    if image.dtype == np.float16 and not (image.view(np.uint16) > np.float16(hi).view(np.uint16)).any():
        return image
    return np.clip(clean(image.astype(np.float32)), 0.0, hi)


class GpuTextures:
    def __init__(self, ctx: moderngl.Context, gl: GL, software: bool, bake):
        """Every material's textures (`<kind>_textures`: a texture or None per material) from the
        bake directory; software: the context renders on the CPU (no anisotropic filtering)."""
        self.ctx, self._gl, self.software = ctx, gl, software
        with gl.checked("upload the 1x1 white texture"):  # what every material without a texture samples
            self.white = ctx.texture((1, 1), 4, np.ones(4, np.float32).tobytes(), dtype="f4")
        self.kd_textures: list[moderngl.Texture | None] = []
        self.emission_textures: list[moderngl.Texture | None] = []
        self.metallic_roughness_textures: list[moderngl.Texture | None] = []
        self.normal_textures: list[moderngl.Texture | None] = []
        self.anisotropy_textures: list[moderngl.Texture | None] = []
        for m in bake.model.materials:
            self._load(m, bake.path)

    def _load(self, m: Material, path) -> None:
        """One material's textures, None for each kind it lacks."""
        texture = None
        if m.kd_texture:
            image = read_image(path / m.kd_texture, keep_half=True)
            # the base colour alpha only where the coverage reads it (shaders/materials.glsl)
            coverage = m.has_coverage and image.shape[-1] >= 4
            alpha = clamped(image[..., 3:4], 1.0) if coverage else None
            texture = self._texture(clamped(image[..., :3], 1.0),
                                    f"the base-colour texture of material '{m.name}'", alpha=alpha)
        self.kd_textures.append(texture)
        texture = None
        if m.emission_texture and np.any(clean(m.emission) > 0):
            image = read_image(path / m.emission_texture, keep_half=True)
            texture = self._texture(clamped(image[..., :3], HALF_MAX), f"the emissive texture of material '{m.name}'")
        self.emission_textures.append(texture)
        for kind in ("metallic_roughness", "normal", "anisotropy"):
            texture = None
            file = getattr(m, f"{kind}_texture")
            if file:
                image = clamped(read_image(path / file, keep_half=True)[..., :3], 1.0)
                what = kind.replace("_", "-")
                texture = self._texture(image, f"the {what} texture of material '{m.name}'")
            getattr(self, f"{kind}_textures").append(texture)

    def has(self, kind: str, material: int) -> bool:
        """Whether `material` has a texture of `kind` (TEXTURE_KINDS)."""
        return getattr(self, f"{kind}_textures")[material] is not None

    @property
    def material_count(self) -> int:
        return len(self.kd_textures)

    def material_textures(self, material: int) -> tuple:
        """The textures a draw of `material` binds, in viewer/draw_list.py TEXTURE_UNITS order (base
        colour, emission, metallic-roughness, normal, anisotropy; the 1x1 white where it has none)."""
        return tuple(self._material_texture(getattr(self, f"{kind}_textures"), material) for kind in TEXTURE_KINDS)

    def _material_texture(self, textures: list, material: int) -> moderngl.Texture:
        """The material's texture of one kind, or the 1x1 white one where it has none."""
        t = textures[material] if 0 <= material < len(textures) else None
        return t if t is not None else self.white

    def _texture(self, rgb: np.ndarray, what: str, *, alpha: np.ndarray | None = None) -> moderngl.Texture:
        """A mip-mapped, repeating RGBA16F texture of `rgb` and `alpha` (1 where None)."""
        h, w = rgb.shape[:2]
        check_texture_size(self.ctx, w, h, what, fix="scale it down in the modelling tool and export again")
        rgba = np.empty((h, w, 4), np.float16)  # numpy's float32 -> float16 rounding where the values are float32
        rgba[..., :3] = rgb
        rgba[..., 3:] = 1.0 if alpha is None else alpha.reshape(h, w, 1)
        with self._gl.checked(f"upload {what}"):
            tex = self.ctx.texture((w, h), 4, rgba, dtype="f2")
            tex.build_mipmaps()
        tex.repeat_x = tex.repeat_y = True
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        if not self.software:  # llvmpipe's anisotropic filter blurs magnified textures (Mesa 22.3)
            tex.anisotropy = min(8.0, self.ctx.max_anisotropy)
        return tex

    def release(self) -> None:
        for kind in TEXTURE_KINDS:
            for t in getattr(self, f"{kind}_textures"):
                if t is not None:
                    t.release()
        self.white.release()
