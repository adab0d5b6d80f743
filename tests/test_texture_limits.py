"""Textures whose PNG header declares a huge size (bake/texture_image.py): read within limits, one warning.

A .glb of 173 KB whose PNG declares 12000 x 12000 grey pixels (zlib packs a plain image 1000:1)
took 47.7 s and 7.6 GB peak RSS to load before the limits (`_load_in_child` on the loader of
2880a7d, this machine; 75 s and 10.6 GB in a whole `glint capture`, issue 22), and PIL printed its
own DecompressionBombWarning. Now it is decoded in its own format (1 byte a pixel) and shrunk by 3
to 4000 x 4000 (the smallest whole factor within 4096^2 texels): 5.7 s, 912 MB. A 20000 x 20000 one
(443 KB) is not decoded: 0.1 s, 75 MB (before: PIL's DecompressionBombError quoted in the warning).

Deliberate bugs these catch (each tried, each failed the test named):
- the image converted to RGBA before it is shrunk: the 12000^2 test's memory bound (peak RSS
  1369 MB > 1100 MB);
- no refusal past MAX_DECODE_PIXELS: the 20000^2 test (the texture is kept as 4000 x 4000, not
  absent);
- PIL's bomb check left on (`Image.MAX_IMAGE_PIXELS` not set): both slow tests (PIL's warning on
  stderr; for 20000^2 PIL's DecompressionBombError quoted instead of glint's own line).
"""
from __future__ import annotations

import json
import subprocess
import struct
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
from test_gltf_fuzz import _glb, _split_glb, _writer

from glint.bake.texture_image import MAX_DECODE_PIXELS, MAX_TEXTURE_PIXELS, MAX_TEXTURE_SIDE, reduction


def grey_png(width: int, height: int, value: int = 200) -> bytes:
    """A valid 8-bit grey PNG of width x height pixels, all `value`, compressed row by row (never
    the whole image in memory)."""
    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))

    packer, row = zlib.compressobj(9), b"\0" + bytes([value]) * width  # filter byte 0, then the pixels
    idat = b"".join(packer.compress(row) for _ in range(height)) + packer.flush()
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", idat) + chunk(b"IEND", b""))


def scene_with_png(path: Path, png: bytes) -> Path:
    """The fuzz seed scene (test_gltf_fuzz._writer) as a .glb whose base colour image is `png`."""
    w = _writer()
    w.write(path)
    doc, binary = _split_glb(path.read_bytes())
    binary += b"\0" * (-len(binary) % 4)
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(binary), "byteLength": len(png)})
    doc["images"][0] = {"bufferView": len(doc["bufferViews"]) - 1, "mimeType": "image/png", "name": "big"}
    binary += png
    doc["buffers"][0]["byteLength"] = len(binary) + (-len(binary) % 4)
    path.write_bytes(_glb(doc, binary))
    return path


# Peak RSS from /proc's VmHWM, which the exec starts afresh: getrusage's ru_maxrss keeps the forking
# parent's peak across the exec (2.7 GB inside the whole test suite's process).
CHILD = """
import json, re, sys, time
from pathlib import Path
from glint.bake.gltf_loader import load_scene
t = time.perf_counter()
scene = load_scene(sys.argv[1])
floor = next(m for m in scene.materials if m.name == "Floor")
peak_kb = int(re.search(r"VmHWM:\\s*(\\d+) kB", Path("/proc/self/status").read_text()).group(1))
print(json.dumps({"seconds": time.perf_counter() - t, "peak_mb": peak_kb / 1024,
                  "kd": None if floor.kd_texture is None else list(floor.kd_texture.shape)}))
"""


def _load_in_child(path: Path) -> tuple[dict, list[str]]:
    """Load `path` in a fresh process: ({seconds, peak_mb (peak RSS), kd (kd_texture's shape)}, stderr lines)."""
    done = subprocess.run([sys.executable, "-c", CHILD, str(path)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout), done.stderr.strip().splitlines()


def test_limits_are_what_the_comments_say():
    """The constants: 16384 a side (GL_MAX_TEXTURE_SIZE), 4096^2 texels kept, 16384^2 decoded at most;
    the factor is the smallest whole one that fits (values worked out by hand)."""
    assert (MAX_TEXTURE_SIDE, MAX_TEXTURE_PIXELS, MAX_DECODE_PIXELS) == (16384, 16_777_216, 268_435_456)
    assert reduction(4096, 4096) == 1 and reduction(4097, 4096) == 2 and reduction(12000, 12000) == 3
    assert reduction(20000, 100) == 2  # the side: 10000 <= 16384
    assert reduction(100000, 10) == 7  # ceil(100000 / 16384) = 7 (6 leaves 16667 > 16384)


@pytest.mark.slow
def test_12000_squared_png_is_shrunk_once(tmp_path):
    """A PNG declaring 12000 x 12000: kept as 4000 x 4000 (12000 / 3), peak RSS under 1.1 GB (912 MB
    here; 7.6 GB before the limits), one warning line naming the image and both sizes, nothing of PIL's on stderr."""
    path = scene_with_png(tmp_path / "big.glb", grey_png(12000, 12000))
    assert path.stat().st_size < 200_000
    got, err = _load_in_child(path)
    assert got["kd"] == [4000, 4000, 3], got
    assert got["peak_mb"] < 1100, got
    lines = [line for line in err if "image 'big'" in line]
    assert len(lines) == 1 and "12000x12000" in lines[0] and "4000x4000" in lines[0], err
    assert not any("DecompressionBomb" in line or "PIL" in line for line in err), err
    print(f"12000^2: {got['seconds']:.1f} s, peak RSS {got['peak_mb']:.0f} MB")


@pytest.mark.slow
def test_20000_squared_png_is_not_decoded(tmp_path):
    """A PNG declaring 20000 x 20000 (400 Mpx > 268 Mpx): not decoded (no base colour texture; peak RSS
    under 500 MB, the loader's own ~200 MB), one warning line naming it and its size, nothing of PIL's."""
    path = scene_with_png(tmp_path / "huge.glb", grey_png(20000, 20000))
    got, err = _load_in_child(path)
    assert got["kd"] is None and got["peak_mb"] < 500, got
    lines = [line for line in err if "image 'big'" in line]
    assert len(lines) == 1 and "20000x20000" in lines[0] and "not read" in lines[0], err
    assert not any("DecompressionBomb" in line or "PIL" in line for line in err), err
    print(f"20000^2: {got['seconds']:.1f} s, peak RSS {got['peak_mb']:.0f} MB")


def test_small_texture_kept_as_it_is(tmp_path):
    """A 64 x 32 PNG is kept at 64 x 32 with its values (200 / 255 in sRGB -> linear), no warning."""
    from glint.bake.gltf_loader import load_scene

    scene = load_scene(scene_with_png(tmp_path / "small.glb", grey_png(64, 32)))
    kd = next(m for m in scene.materials if m.name == "Floor").kd_texture
    assert kd.shape == (32, 64, 3)
    np.testing.assert_allclose(kd, ((200 / 255 + 0.055) / 1.055) ** 2.4, rtol=1e-5)


def test_8_bit_channels_decode_by_tables_of_their_256_values(tmp_path):
    """bake/gltf_materials.py reads a texture's 8-bit channels through tables: every k gives k / 255
    (linear data, alpha) and IEC 61966-2-1's sRGB decoding of it (float64 here, within 1e-6), and a
    glTF base colour texture loads as those values (its colour decoded, its alpha not). Catches a table
    off by one (k - 1: up to 8.9e-3 off) and alpha decoded as sRGB (0.5 -> 0.21)."""
    from glint.bake.gltf_loader import load_scene
    from glint.bake.gltf_materials import LINEAR8_TABLE, SRGB8_TABLE
    from glint.scenes.gltf_writer import GltfWriter, quad

    k = np.arange(256, dtype=np.float64) / 255.0
    iec = np.where(k <= 0.04045, k / 12.92, ((k + 0.055) / 1.055) ** 2.4)
    np.testing.assert_allclose(LINEAR8_TABLE, k, rtol=0, atol=1e-7)
    np.testing.assert_allclose(SRGB8_TABLE, iec, rtol=0, atol=1e-6)

    image = np.random.default_rng(3).integers(0, 256, (8, 8, 4)).astype(np.uint8)
    w = GltfWriter()
    mat = w.add_material("Tex", base_color=(1, 1, 1), base_color_texture=image, alpha_mode="BLEND")
    p, i = quad((0, 0, 0), (1, 0, 0), (0, 1, 0))
    w.add_node("Quad", mesh=w.add_mesh("Quad", p, i, mat, normals=np.tile((0, 0, 1), (4, 1)),
                                       uvs=np.array([[0, 1], [1, 1], [1, 0], [0, 0]], float)))
    w.write(tmp_path / "t.glb")
    (tmp_path / "t.glint.toml").write_text("[sky]\nradiance = 1.0\n")
    m = load_scene(tmp_path / "t.glb").materials[0]
    expected = iec[image[..., :3]]
    np.testing.assert_allclose(m.kd_texture, expected, rtol=0, atol=1e-6)
    np.testing.assert_allclose(m.alpha_texture, k[image[..., 3]], rtol=0, atol=1e-6)


def test_viewer_clamps_half_float_textures_as_it_clamps_float32_ones():
    """viewer/gpu_textures.py `clamped` keeps a float16 image whose values already lie in [0, hi]
    as it is (no float32 copy), and sends any other through the float32 clamp: non-finite -> 0,
    then [0, hi]. Expected values are literals. Catches a bit test that lets through values above
    hi, negative values, NaN or Inf (a wrong limit, a signed comparison)."""
    from glint.core.constants import HALF_MAX
    from glint.viewer.gpu_textures import clamped

    inside = np.array([[[0.0, 0.25, 1.0], [0.5, 0.999, 2.0 ** -24]]], np.float16)
    assert clamped(inside, 1.0) is inside
    cases = {1.0: [1.5, -0.5, np.nan, np.inf, -np.inf, 65504.0, 0.75],
             HALF_MAX: [1.5, -0.5, np.nan, np.inf, -np.inf, 65504.0, 0.75]}
    expected = {1.0: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.75], HALF_MAX: [1.5, 0.0, 0.0, 0.0, 0.0, 65504.0, 0.75]}
    for hi, values in cases.items():
        for value, want in zip(values, expected[hi]):  # each beside an in-range value: the bit test decides
            out = clamped(np.array([[[0.5], [value]]], np.float16), hi)
            np.testing.assert_array_equal(out.astype(np.float64).ravel(), [0.5, want], err_msg=f"{value} in [0, {hi}]")
        assert clamped(np.array([0.5, 1.0], np.float16), hi).dtype == np.float16
