"""Reading and writing images with OpenImageIO (EXR, HDR, PNG, ...).

Arrays are (H, W, C) with row 0 first in the file; float32 linear for EXR/HDR,
uint8 for PNG. Writes go to a temporary name and are renamed into place, so a
crash never leaves a half-written image behind.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from glint.core.atomic import atomic_path
from glint.core.constants import HALF_MAX
from glint.core.errors import GlintError


def read_image(path: str | Path, what: str = "image", *, keep_half: bool = False) -> np.ndarray:
    """Any image OpenImageIO reads -> float32 (H, W, C) (8-bit files scaled to [0, 1]). keep_half: a
    file whose channels are all half float comes back as float16, the same values without a float32
    copy (the viewer's uploads of the bake's half-float files)."""
    if not Path(path).is_file():
        raise GlintError(f"{what}: no such file {path}")
    buf = oiio.ImageBuf(str(path))
    half = keep_half and not buf.has_error and buf.spec().format == oiio.HALF and not buf.spec().channelformats
    pixels = None if buf.has_error else buf.get_pixels(oiio.HALF if half else oiio.FLOAT)
    if pixels is None or buf.has_error:
        raise GlintError(f"{what}: cannot read {path}: {buf.geterror().strip()}")
    pixels = np.asarray(pixels, np.float16 if half else np.float32)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    if pixels.ndim == 4:  # (depth, H, W, C) for volume images; take the first slice
        pixels = pixels[0]
    return np.ascontiguousarray(pixels)


def write_image(path: str | Path, pixels: np.ndarray, *, half: bool | None = None,
                channels: tuple[str, ...] | None = None) -> str:
    """Write (H, W, C) pixels; returns the pixel type written ("half", "float" or "uint8").

    EXR: half float when every value fits (|v| <= 65504), else float32, so very
    bright emitters never turn into Inf (docs/ARCHITECTURE.md, "Numerics"). half=True/False forces it.
    """
    path = Path(path)
    pixels = np.asarray(pixels)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    if not np.all(np.isfinite(pixels)):
        raise ValueError(f"refusing to write non-finite pixels to {path}")
    h, w, c = pixels.shape
    ext = path.suffix.lower()
    if ext == ".exr":
        if half is None:
            half = float(np.abs(pixels).max(initial=0.0)) <= HALF_MAX
        fmt, kind = (oiio.HALF, "half") if half else (oiio.FLOAT, "float")
        data = pixels.astype(np.float32)
    else:
        fmt, kind = oiio.UINT8, "uint8"
        data = pixels if pixels.dtype == np.uint8 else np.clip(np.rint(pixels * 255.0), 0, 255).astype(np.uint8)
    spec = oiio.ImageSpec(w, h, c, fmt)
    if channels:
        spec.channelnames = channels
    spec.attribute("DateTime", "")  # no timestamp: the same pixels give a byte-identical file
    if ext == ".exr":
        spec.attribute("compression", "zip")
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            raise GlintError(f"{path}: cannot write image: {oiio.geterror().strip()}")
        try:
            ok = out.write_image(np.ascontiguousarray(data))
            if not ok:
                raise GlintError(f"{path}: cannot write image: {out.geterror().strip()}")
        finally:
            out.close()
    return kind


def wrap_texel(i: np.ndarray, size: int, mode: str) -> np.ndarray:
    """Integer texel indices wrapped as OpenGL 4.6 section 8.14.2 (Table 8.20) defines the glTF
    sampler modes: REPEAT i mod size, CLAMP_TO_EDGE clamped to 0..size-1, MIRRORED_REPEAT
    (i mod 2 size) read backwards in the second copy."""
    if mode == "CLAMP_TO_EDGE":
        return np.clip(i, 0, size - 1)
    if mode == "MIRRORED_REPEAT":
        m = i % (2 * size)
        return np.where(m < size, m, 2 * size - 1 - m)
    return i % size


def sample_texture(texture: np.ndarray, uv: np.ndarray, wrap: tuple[str, str] = ("REPEAT", "REPEAT"),
                   nearest: bool = False) -> np.ndarray:
    """Look-up of an (H, W) or (H, W, C) texture at glTF uv ((0, 0) = top-left of the image, texel
    centres at half-integers), as the viewer's level-0 sampler: bilinear, or the nearest texel
    (magFilter NEAREST), the indices wrapped per axis by `wrap` ((wrapS, wrapT))."""
    H, W = texture.shape[:2]
    x = np.nan_to_num(uv[:, 0]) * W
    y = np.nan_to_num(uv[:, 1]) * H
    if nearest:
        return texture[wrap_texel(np.floor(y).astype(np.int64), H, wrap[1]),
                       wrap_texel(np.floor(x).astype(np.int64), W, wrap[0])]
    x0, y0 = np.floor(x - 0.5), np.floor(y - 0.5)
    fx, fy = x - 0.5 - x0, y - 0.5 - y0
    if texture.ndim == 3:
        fx, fy = fx[:, None], fy[:, None]
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
    x1, y1 = wrap_texel(x0 + 1, W, wrap[0]), wrap_texel(y0 + 1, H, wrap[1])
    x0, y0 = wrap_texel(x0, W, wrap[0]), wrap_texel(y0, H, wrap[1])
    return ((1 - fy) * ((1 - fx) * texture[y0, x0] + fx * texture[y0, x1])
            + fy * ((1 - fx) * texture[y1, x0] + fx * texture[y1, x1]))


def sample_bilinear(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear look-up of an (H, W, C) image at (K, 2) uv -> (K, C), as OpenGL GL_LINEAR + CLAMP_TO_EDGE
    (`sample_texture` in float64, the result in the image's float type). A 2-D image gives (K,)."""
    image = np.asarray(image)
    out = sample_texture(image.astype(np.float64, copy=False), np.asarray(uv, np.float64).reshape(-1, 2),
                         ("CLAMP_TO_EDGE", "CLAMP_TO_EDGE"))
    return out.astype(image.dtype if np.issubdtype(image.dtype, np.floating) else np.float64)
