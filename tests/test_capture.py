"""`glint capture`: files, views, sequences, determinism, statistics and one-line errors.

Runs in-process through glint.cli.main (one EGL context per capture, llvmpipe in CI)
on a small room from conftest.py, baked once at a tiny quality.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from conftest import error_of, write_room

from glint.cli import main
from glint.core.image_io import read_image

SIDECAR = """
[cameras.side]
eye = [0.9, 1.2, 0.0]
target = [-1.0, 0.8, 0.0]
yfov = 60

[camera_paths.orbit]
keys = [
  { time = 0.0, eye = [0.0, 1.0, 0.9], target = [0.0, 0.8, -1.0] },
  { time = 1.0, eye = [0.6, 1.2, 0.6], target = [-0.5, 0.6, -0.5] },
  { time = 2.0, eye = [0.8, 1.0, -0.2], target = [-1.0, 0.9, 0.0], yfov = 70 },
]
"""
BAKE = ["-q", "draft", "--samples", "8", "--texels-per-metre", "6", "--no-denoise"]
SIZE = ["--size", "48x32", "--supersample", "1"]


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    """(scene file, bake options): baked by the first capture, up to date for the others."""
    d = tmp_path_factory.mktemp("room")
    scene = write_room(d / "room.glb", sidecar=SIDECAR)
    opts = [*BAKE, "--bake-dir", str(d / "room.bake")]
    assert main(["capture", str(scene), "-o", str(d / "warm.png"), *SIZE, *opts]) == 0
    return scene, opts


def capture(room, out, *extra):
    scene, opts = room
    return main(["capture", str(scene), "-o", str(out), *SIZE, *opts, *map(str, extra)])


def aces_srgb(x):
    """The tone curve of the PNG, from its published formulas (Narkowicz's ACES fit, sRGB OETF)."""
    x = np.clip(np.asarray(x, np.float64), 0, 1e4)
    y = np.clip((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0, 1)
    return np.where(y <= 0.0031308, 12.92 * y, 1.055 * y ** (1 / 2.4) - 0.055) * 255


# -- files ----------------------------------------------------------------------------------------
def test_png_and_exr_show_the_same_frame(room, tmp_path):
    assert capture(room, tmp_path / "a.png") == 0
    assert capture(room, tmp_path / "a.exr") == 0
    png = oiio.ImageBuf(str(tmp_path / "a.png"))
    exr = oiio.ImageBuf(str(tmp_path / "a.exr"))
    assert (png.spec().width, png.spec().height, png.spec().nchannels) == (48, 32, 3)
    assert png.spec().format == oiio.UINT8 and exr.spec().format == oiio.FLOAT  # float32, not half
    linear = read_image(tmp_path / "a.exr")
    assert np.all(np.isfinite(linear)) and linear.max() > 0
    srgb = read_image(tmp_path / "a.png") * 255
    assert srgb.std() > 5  # an image, not a flat colour
    np.testing.assert_allclose(srgb, aces_srgb(linear), atol=0.51)  # the PNG is the tone-mapped EXR


def test_exposure_brightens_the_png_only(room, tmp_path):
    capture(room, tmp_path / "e0.png")
    capture(room, tmp_path / "e2.png", "--exposure", 2)
    capture(room, tmp_path / "e2.exr", "--exposure", 2)
    linear = read_image(tmp_path / "e2.exr")
    np.testing.assert_allclose(read_image(tmp_path / "e2.png") * 255, aces_srgb(linear * 4), atol=0.51)
    assert read_image(tmp_path / "e2.png").mean() > read_image(tmp_path / "e0.png").mean()


def test_same_command_gives_identical_files(room, tmp_path):
    for name in ("a.png", "b.png", "a.exr", "b.exr"):
        assert capture(room, tmp_path / name, "--supersample", 2) == 0
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()
    assert (tmp_path / "a.exr").read_bytes() == (tmp_path / "b.exr").read_bytes()


# -- views ----------------------------------------------------------------------------------------
def test_camera_selection(room, tmp_path):
    capture(room, tmp_path / "default.exr")
    capture(room, tmp_path / "first.exr", "--camera", "Camera")
    capture(room, tmp_path / "side.exr", "--camera", "side")
    default, first, side = (read_image(tmp_path / f"{n}.exr") for n in ("default", "first", "side"))
    np.testing.assert_array_equal(default, first)  # the default is the scene's first camera
    assert np.abs(side - first).mean() > 0.05 * first.mean()


def test_eye_and_target_reproduce_a_camera(room, tmp_path):
    """--eye/--target/--fov with the sidecar camera's values give that camera's image."""
    capture(room, tmp_path / "side.exr", "--camera", "side")
    capture(room, tmp_path / "eye.exr", "--eye", "0.9,1.2,0", "--target", "-1,0.8,0", "--fov", 60)
    side, eye = read_image(tmp_path / "side.exr"), read_image(tmp_path / "eye.exr")
    assert np.abs(eye - side).mean() < 1e-3 * side.mean()
    capture(room, tmp_path / "wide.exr", "--eye", "0.9,1.2,0", "--target", "-1,0.8,0", "--fov", 90)
    assert np.abs(read_image(tmp_path / "wide.exr") - side).mean() > 0.05 * side.mean()


def test_negative_vector_values_parse(room, tmp_path):
    """'-1,0.8,0' is a value, not an option (argparse would otherwise refuse it)."""
    assert capture(room, tmp_path / "n.png", "--eye", "-0.5,1,0.5", "--target", "0.5,0.8,-0.5",
                   "--up", "0,1,0") == 0


def test_path_writes_a_numbered_sequence(room, tmp_path):
    assert capture(room, tmp_path / "seq.exr", "--path", "orbit", "--frames", 3) == 0
    files = sorted(p.name for p in tmp_path.iterdir())
    assert files == ["seq_0000.exr", "seq_0001.exr", "seq_0002.exr"]
    frames = [read_image(tmp_path / f) for f in files]
    for a, b in [(0, 1), (1, 2), (0, 2)]:
        assert np.abs(frames[a] - frames[b]).mean() > 0.02 * frames[a].mean(), (a, b)
    # The first and last frames are the first and last keys (the last one with its own fov).
    capture(room, tmp_path / "k0.exr", "--eye", "0,1,0.9", "--target", "0,0.8,-1", "--fov", 50)
    capture(room, tmp_path / "k2.exr", "--eye", "0.8,1,-0.2", "--target", "-1,0.9,0", "--fov", 70)
    assert np.abs(read_image(tmp_path / "k0.exr") - frames[0]).mean() < 1e-3 * frames[0].mean()
    assert np.abs(read_image(tmp_path / "k2.exr") - frames[2]).mean() < 1e-3 * frames[2].mean()


# -- statistics -----------------------------------------------------------------------------------
def test_stats_file(room, tmp_path):
    assert capture(room, tmp_path / "s.png", "--stats", tmp_path / "s.json", "--supersample", 2) == 0
    stats = json.loads((tmp_path / "s.json").read_text())
    assert stats["size"] == [48, 32] and stats["render_size"] == [96, 64] and stats["supersample"] == 2
    assert set(stats["gpu_ms_median"]) == {"gbuffer", "shading", "resolve", "tonemap", "total"}
    assert all(v > 0 for v in stats["gpu_ms_median"].values())
    assert stats["frames"] == 1 and stats["frames_timed"] >= 2
    frame = stats["per_frame"][0]
    assert frame["file"].endswith("s.png")
    # The room's camera: at (0, 1, 0.9) facing -Z, yfov 1 rad (+-28.6 deg), 3:2. The front wall
    # (z = 1) is behind it; the lamp (y = 1.99, 0.9 m ahead: 48 deg up) is above the view; the
    # box (top at y = 0.5, 0.05 to 0.65 m ahead: at least 37 deg down) is below it. The four
    # other walls and the floor are drawn, two triangles each.
    assert frame["skipped"]["objects_outside_view"] == ["Front", "Lamp", "Box"]
    assert frame["objects_drawn"] == 5 and frame["triangles"] == 10
    assert math.isclose(frame["camera"]["yfov_degrees"], math.degrees(1.0), rel_tol=1e-6)
    # the bake's texel counts, as its manifest has them (the end-of-run line's moved and invalid too)
    manifest = json.loads((Path(stats["bake_dir"]) / "manifest.json").read_text())["statistics"]["lightmaps"]
    counts = stats["lightmap_texels"]
    assert counts["texels"] > 0
    for key in ("texels", "invalid_texels", "moved_texels", "refined_texels", "enclosed_texels"):
        assert isinstance(counts[key], int) and counts[key] == manifest[key], key


def test_gbuffer_option_chooses_the_way_and_stats_say_which(room, tmp_path):
    """--gbuffer raster / visibility: the stats name the way that ran (auto on llvmpipe: raster, a
    software renderer's faster one), and the two frames agree within 1e-3 relative per pixel
    (linear EXR; tests/test_visibility_buffer.py compares the targets themselves).

    Deliberate bug this catches (tried): the option not handed to the renderer (auto always): the
    visibility run's stats say raster."""
    images = {}
    for way in ("auto", "raster", "visibility"):
        out = tmp_path / f"{way}.exr"
        assert capture(room, out, "--gbuffer", way, "--stats", tmp_path / f"{way}.json") == 0
        assert json.loads((tmp_path / f"{way}.json").read_text())["gbuffer"] == ("raster" if way == "auto" else way)
        images[way] = read_image(out)
    a, b = images["raster"], images["visibility"]
    assert np.array_equal(images["auto"], a)
    assert (np.abs(a - b) / np.maximum(np.maximum(np.abs(a), np.abs(b)), 1e-6)).max() <= 1e-3


# -- errors: one line, before any work, nothing written -------------------------------------------
@pytest.mark.parametrize("size, words", [("12x", ["--size", "WIDTHxHEIGHT"]), ("0x10", ["at least 1"]),
                                         ("big", ["--size"])])
def test_bad_size(room, tmp_path, capsys, size, words):
    scene, opts = room
    line = error_of(capsys, main(["capture", str(scene), "-o", str(tmp_path / "x.png"), "--size", size, *opts]))
    for w in words:
        assert w in line
    assert not any(tmp_path.iterdir())


def test_unknown_camera_lists_the_cameras(room, tmp_path, capsys):
    line = error_of(capsys, capture(room, tmp_path / "x.png", "--camera", "nope"))
    assert "nope" in line and "Camera" in line and "side" in line
    assert not any(tmp_path.iterdir())


def test_unknown_path_lists_the_paths(room, tmp_path, capsys):
    line = error_of(capsys, capture(room, tmp_path / "x.png", "--path", "nope"))
    assert "nope" in line and "orbit" in line


@pytest.mark.parametrize("extra, words", [
    (["--camera", "side", "--eye", "0,1,0", "--target", "0,0,0"], ["--camera", "--eye"]),
    (["--eye", "0,1,0"], ["--target"]),
    (["--eye", "0,1,0", "--target", "0,1,0"], ["same point"]),
    (["--eye", "0,1", "--target", "0,0,0"], ["--eye", "X,Y,Z"]),
    (["--path", "orbit", "--camera", "side"], ["--path", "--camera"]),
    (["--frames", "3"], ["--path"]),
    (["--fov", "180"], ["--fov"]),
    (["--supersample", "9"], ["--supersample"]),
    (["--exposure", "bright"], ["--exposure"]),
    (["--size", "40000x10"], ["40000x10", "at most"]),
])
def test_conflicting_or_bad_view_options(room, tmp_path, capsys, extra, words):
    line = error_of(capsys, capture(room, tmp_path / "x.png", *extra))
    for w in words:
        assert w in line, line
    assert not any(tmp_path.iterdir())


def test_unsupported_extension(room, tmp_path, capsys):
    line = error_of(capsys, capture(room, tmp_path / "x.jpg"))
    assert "x.jpg" in line and ".png" in line and ".exr" in line


def test_unwritable_output(room, tmp_path, capsys):
    line = error_of(capsys, capture(room, tmp_path / "missing" / "x.png"))
    assert "missing" in line and "does not exist" in line
    (tmp_path / "dir.png").mkdir()
    line = error_of(capsys, capture(room, tmp_path / "dir.png"))
    assert "directory" in line


def test_no_egl_is_a_clear_message(room, tmp_path, capsys, monkeypatch):
    import moderngl

    def fail(**kwargs):
        raise Exception("eglGetDisplay failed")

    monkeypatch.setattr(moderngl, "create_standalone_context", fail)
    line = error_of(capsys, capture(room, tmp_path / "x.png"))
    assert "EGL" in line and "eglGetDisplay failed" in line
    assert not (tmp_path / "x.png").exists()


def test_no_bake_possible(tmp_path, capsys):
    line = error_of(capsys, main(["capture", str(tmp_path / "missing.glb"), "-o", str(tmp_path / "x.png")]))
    assert "missing.glb" in line


def test_command_line_entry_point(room, tmp_path):
    """The installed command: exit code 0 and one line on stdout; a bad size is one line on stderr."""
    scene, opts = room
    run = lambda *a: subprocess.run([sys.executable, "-m", "glint", "capture", str(scene), *opts, *a],  # noqa: E731
                                    capture_output=True, text=True, timeout=300)
    ok = run("-o", str(tmp_path / "x.png"), *SIZE)
    assert ok.returncode == 0 and ok.stdout.count("\n") == 1 and "x.png" in ok.stdout, ok.stderr
    bad = run("-o", str(tmp_path / "y.png"), "--size", "wide")
    assert bad.returncode == 2 and bad.stderr.strip().count("\n") == 0 and bad.stderr.startswith("glint: ")
