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


def read_image(path: str | Path, what: str = "image") -> np.ndarray:
    """Any image OpenImageIO reads -> float32 (H, W, C) (8-bit files scaled to [0, 1])."""
    if not Path(path).is_file():
        raise GlintError(f"{what}: no such file {path}")
    buf = oiio.ImageBuf(str(path))
    pixels = None if buf.has_error else buf.get_pixels(oiio.FLOAT)
    if pixels is None or buf.has_error:
        raise GlintError(f"{what}: cannot read {path}: {buf.geterror().strip()}")
    pixels = np.asarray(pixels, np.float32)
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


def sample_bilinear(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear look-up of an (H, W, C) image at (K, 2) uv -> (K, C), as OpenGL GL_LINEAR + CLAMP_TO_EDGE.

    Texel (y, x) has its centre at uv ((x + 0.5) / W, (y + 0.5) / H); texel
    indices outside the image are clamped to the edge. A 2-D image gives (K,).
    """
    image = np.asarray(image)
    flat = image.ndim == 2
    if flat:
        image = image[..., None]
    H, W = image.shape[:2]
    uv = np.asarray(uv, np.float64).reshape(-1, 2)
    x = uv[:, 0] * W - 0.5
    y = uv[:, 1] * H - 0.5
    xf, yf = np.floor(x), np.floor(y)
    fx, fy = (x - xf)[:, None], (y - yf)[:, None]
    x0 = np.clip(xf.astype(np.int64), 0, W - 1)
    x1 = np.clip(xf.astype(np.int64) + 1, 0, W - 1)
    y0 = np.clip(yf.astype(np.int64), 0, H - 1)
    y1 = np.clip(yf.astype(np.int64) + 1, 0, H - 1)
    img = image.astype(np.float64, copy=False)
    out = ((1 - fy) * ((1 - fx) * img[y0, x0] + fx * img[y0, x1])
           + fy * ((1 - fx) * img[y1, x0] + fx * img[y1, x1]))
    out = out.astype(image.dtype if np.issubdtype(image.dtype, np.floating) else np.float64)
    return out[:, 0] if flat else out
