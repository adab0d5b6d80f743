"""A glTF texture's image decoded within limits: its size read from the header before any pixel is.

A 2.5 KB PNG can declare 12000 x 12000 pixels (zlib packs a plain image 1000:1). Decoded and
converted to the loader's float32 RGBA as it stands, that is ~2.3 GB of float32 alone, and minutes
and gigabytes per `glint capture` (docs/SCENES.md, "Textures").
Here the declared size is read first (PIL's `Image.open` reads only the header) and:

- beyond MAX_DECODE_PIXELS the image is not decoded at all (`ImageRefused`; the loader warns and
  the material goes without the texture, as for an unreadable image);
- beyond MAX_TEXTURE_PIXELS or MAX_TEXTURE_SIDE it is decoded in its own pixel format (1 to 4 bytes
  a pixel; a JPEG already reduced by its decoder, `Image.draft`) and shrunk by a whole factor with
  `Image.reduce` (each texel the mean of a factor x factor box) before anything is converted to float.

The bake keeps what the loader made (textures/*.exr), so the texture is downscaled once, in the
bake; the viewer reads only the bake directory. Loading the scene again (every `glint capture`
hashes it to find its bake up to date) decodes the file again, in its own format, and shrinks it.
"""
from __future__ import annotations

import io
import math

import numpy as np
from PIL import Image

# Texels a side of the largest 2-D texture desktop GPUs take (GL_MAX_TEXTURE_SIZE is 16384 on current
# NVIDIA, AMD and Intel drivers and Mesa's llvmpipe); the viewer cannot upload a larger one.
MAX_TEXTURE_SIDE = 16384
# Texels kept of one image: the loader holds each as float32 RGBA (16 B a texel), its linear copy and
# the material's RGB and alpha slices (about 50 B a texel in all), and the bake writes it to EXR. At
# 4096^2 (16.8 Mpx) that is about 0.85 GB for a texture, the most one image may cost; GPUs sample a
# texture this size at 4096 pixels across the screen without loss.
MAX_TEXTURE_PIXELS = 4096 * 4096
# Declared pixels past which an image is not decoded at all: a PNG decodes at full size before it can
# be shrunk, at 1 to 4 bytes a pixel: at most 1 GiB for 16384^2 RGBA, the largest texture a GPU takes.
MAX_DECODE_PIXELS = MAX_TEXTURE_SIDE * MAX_TEXTURE_SIDE
# PIL's own decompression-bomb check (a DecompressionBombWarning printed past 89 Mpx, an error past
# 179 Mpx, each in PIL's words) is replaced by the limits above, checked on the declared size.
Image.MAX_IMAGE_PIXELS = None

_REDUCIBLE = ("L", "LA", "RGB", "RGBA")  # modes Image.reduce takes as they are


class ImageRefused(Exception):
    """The image declares more than MAX_DECODE_PIXELS pixels; `size` is its (width, height)."""

    def __init__(self, size: tuple[int, int]):
        super().__init__(f"{size[0]}x{size[1]}")
        self.size = size


def reduction(width: int, height: int) -> int:
    """The smallest whole factor that brings width x height within MAX_TEXTURE_PIXELS and
    MAX_TEXTURE_SIDE (Image.reduce keeps ceil(width / factor) x ceil(height / factor))."""
    factor = max(1, math.ceil(max(width, height) / MAX_TEXTURE_SIDE),
                 math.floor(math.sqrt(width * height / MAX_TEXTURE_PIXELS)))
    while math.ceil(width / factor) * math.ceil(height / factor) > MAX_TEXTURE_PIXELS:
        factor += 1
    return factor


def decode_texture(data: bytes) -> tuple[np.ndarray, tuple[int, int], tuple[int, int]]:
    """(H, W, 4) uint8 RGBA of an encoded image, (width, height) declared, (width, height) kept.
    ImageRefused past MAX_DECODE_PIXELS; PIL's exceptions for what it cannot read."""
    with Image.open(io.BytesIO(data)) as img:
        declared = img.size
        width, height = declared
        if width * height > MAX_DECODE_PIXELS:
            raise ImageRefused(declared)
        factor = reduction(width, height)
        if factor > 1 and img.format == "JPEG":  # the decoder itself scales by 1/2, 1/4 or 1/8
            img.draft("RGB", (math.ceil(width / factor), math.ceil(height / factor)))
            factor = reduction(*img.size)
        img.load()
        out = img if img.mode in _REDUCIBLE else img.convert("RGBA")
        if factor > 1:
            out = out.reduce(factor)
        rgba = np.asarray(out.convert("RGBA"), np.uint8)
    return rgba, declared, (rgba.shape[1], rgba.shape[0])
