"""Still-camera refinement (viewer/progressive.py, section 4.4.2) on llvmpipe: the shown image is
the running mean of the frames, any change of the view starts over, and N frames always give
the same image.

The running mean is checked against an identity that does not use the accumulation: frame k
takes samples kK .. kK + K - 1 of the quasi-random sequence, so the mean of N frames of K
samples is the estimate of a single frame of N K samples (another renderer, one frame).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from test_renderer import material, quad
from test_specular import cube_file, direction_colours, lobe, specular_bake

from glint.core.manifest import Camera
from glint.viewer.camera import ViewCamera
from glint.viewer.progressive import Progressive
from glint.viewer.renderer import Renderer

SIZE = (24, 16)


@pytest.fixture
def bake(tmp_path):
    """A glossy floor (anisotropic lobe, so samples matter) under a cube map that varies with direction."""
    floor = quad((0, 0, 0), (10, 0, 0), (0, 10, 0))
    spec = lobe(m=(0.15, 0.4), r0=0.3, alpha=0.1)
    return specular_bake(tmp_path / "b", [floor], [material(kd=(0, 0, 0), lobes=[spec])], [0],
                         {0: (cube_file(direction_colours, 16), (0, 0, 0), [])})


def camera(x=0.0):
    return ViewCamera.look_at((x, -2.0, 1.5), (x, 0.5, 0.0), (0, 0, 1), math.radians(50), znear=0.01, zfar=100)


def frames(renderer, cam, n, size=SIZE):
    for _ in range(n):
        renderer.render(cam, *size, mode="converge")
    return renderer.read_linear()


def test_running_mean_equals_one_frame_with_all_the_samples(ctx, bake):
    with Renderer(ctx, bake, samples_per_frame=4) as r4, Renderer(ctx, bake, samples_per_frame=8) as r8, \
            Renderer(ctx, bake, samples_per_frame=32) as r32:
        one = frames(r4, camera(), 1)  # samples 0..3
        assert r4.stats["specular"]["progressive"]["frames"] == 1
        two_of_4 = frames(r4, camera(), 1)  # frames 0 and 1: samples 0..7
        np.testing.assert_allclose(two_of_4, frames(r8, camera(), 1), rtol=2e-5, atol=1e-7)
        eight_of_4 = frames(r4, camera(), 6)  # frames 0..7: samples 0..31
        single = frames(r32, camera(), 1)
        np.testing.assert_allclose(eight_of_4, single, rtol=2e-5, atol=1e-7)
        assert np.abs(one - single).max() > 1e-3  # the samples differ: a real test of the mean
        stats = r4.stats["specular"]
        assert stats["mode"] == "converging" and stats["progressive"]["samples_per_pixel"] == 32


def test_first_frame_after_any_change_starts_over(ctx, bake):
    """Camera, size and exposure changes restart the sum: the frame equals a fresh renderer's first."""
    with Renderer(ctx, bake, samples_per_frame=4) as fresh:
        first_moved = frames(fresh, camera(0.3), 1)
    with Renderer(ctx, bake, samples_per_frame=4) as fresh:
        first_small = frames(fresh, camera(0.3), 1, size=(16, 12))
    with Renderer(ctx, bake, samples_per_frame=4) as r:
        frames(r, camera(), 5)
        assert r.progressive.frames == 5
        moved = frames(r, camera(0.3), 1)
        assert r.progressive.frames == 1
        np.testing.assert_array_equal(moved, first_moved)
        frames(r, camera(0.3), 3, size=(16, 12))
        assert r.progressive.frames == 3
        r.exposure = 1.0
        frames(r, camera(0.3), 1, size=(16, 12))
        assert r.progressive.frames == 1
        np.testing.assert_array_equal(r.read_linear(), first_small)  # exposure: only the sum restarts
        r.render(camera(0.3), 16, 12)  # a walkthrough frame in between ends the still sequence
        frames(r, camera(0.3), 1, size=(16, 12))
        assert r.progressive.frames == 1


def test_same_frames_give_byte_identical_images(ctx, bake):
    images = []
    for _ in range(2):
        with Renderer(ctx, bake, samples_per_frame=4, supersample=2) as r:
            r.render(camera(), *SIZE)  # a walkthrough frame first, as the window does
            frames(r, camera(), 5)
            images.append((r.read_linear().tobytes(), r.read_srgb().tobytes()))
    assert images[0] == images[1]


def test_auto_mode_refines_while_the_view_stands_still(ctx, bake):
    with Renderer(ctx, bake, samples_per_frame=2, max_frames=3, blend_frames=2) as r:
        r.render(camera(), *SIZE, mode="auto")
        assert r.mode == "walkthrough"
        walkthrough = r.read_linear()
        assert "gbuffer" in r.stats["gpu_ms"]
        r.render(camera(), *SIZE, mode="auto")
        assert r.mode == "converge" and r.progressive.frames == 1
        assert "gbuffer" not in r.stats["gpu_ms"]  # the standing view's G-buffer is reused
        blended = r.read_linear()
        r.render(camera(), *SIZE, mode="auto")
        r.render(camera(), *SIZE, mode="auto")
        assert r.progressive.converged and r.stats["specular"]["mode"] == "converged"
        final = r.read_linear()
        r.render(camera(), *SIZE, mode="auto")  # converged: nothing more is added
        np.testing.assert_array_equal(r.read_linear(), final)
        assert r.progressive.frames == 3
        r.render(camera(0.1), *SIZE, mode="auto")  # moved: walkthrough again
        assert r.mode == "walkthrough" and r.progressive.frames == 0
    with Renderer(ctx, bake, samples_per_frame=2) as plain:
        mean_of_one = frames(plain, camera(), 1)
    # after one of blend_frames = 2 frames, halfway between the walkthrough image and the mean
    np.testing.assert_allclose(blended, 0.5 * walkthrough + 0.5 * mean_of_one, rtol=1e-5, atol=1e-7)


def test_view_key_and_sequence_bookkeeping(ctx):
    p = Progressive(ctx, samples_per_frame=8, max_frames=4)
    try:
        key = Progressive.view_key(camera(), (8, 8), 1, 0.0)
        assert key == Progressive.view_key(camera(), (8, 8), 1, 0.0)
        assert key != Progressive.view_key(camera(1e-6), (8, 8), 1, 0.0)
        assert key != Progressive.view_key(camera(), (8, 8), 2, 0.0)
        assert p.begin(key) and not p.begin(key)
        assert p.samples() == (0, 8)
        p.frames = 3
        assert p.samples() == (24, 8) and not p.converged
        p.frames = 4
        assert p.converged
        p.invalidate()
        assert p.begin(key) and p.frames == 0
        with pytest.raises(ValueError):
            Progressive(ctx, samples_per_frame=0)
    finally:
        p.release()


def glossy_furnace(tmp_path, *, m: float, r0: float, size):
    """A black glossy floor (one isotropic lobe) under a constant white cube map, seen from above at
    `size`: (bake, camera, per-pixel lobe albedo from core/bsdf.py: the expected radiance)."""
    from test_specular import constant, pinhole_rays

    from glint.core import bsdf

    spec = lobe(m=(m, m), r0=r0)
    bake = specular_bake(tmp_path / "w", [quad((0, 0, 0), (20, 0, 0), (0, 20, 0))],
                         [material(kd=(0, 0, 0), lobes=[spec])], [0], {0: (cube_file(constant(1.0), 8), (0, 0, 0), [])})
    geometry = ((0.0, -1.0, 2.0), (0.0, 0.0, 0.0), (0, 0, 1), math.radians(20))
    cam = ViewCamera.look_at(*geometry, znear=0.01, zfar=100)
    albedo = bsdf.lobe_albedo(-pinhole_rays(*geometry, *size), spec["mx"], spec["my"], spec["r0"], spec["alpha"],
                              "reflect", n=2048)
    return bake, cam, albedo


def test_each_pixel_takes_its_own_samples(ctx, tmp_path):
    """The per-pixel scramble: in a white furnace, one frame's error is noise from pixel to pixel,
    not the smooth, shared error of one sample set used everywhere (as the walkthrough does)."""
    size = (32, 32)
    bake, cam, albedo = glossy_furnace(tmp_path, m=0.3, r0=0.5, size=size)
    with Renderer(ctx, bake, samples_per_frame=2) as r:
        error = frames(r, cam, 1, size)[..., 0] / albedo - 1
    assert error.std() > 0.02  # two samples: noisy
    neighbours = np.corrcoef(error[:, :-1].ravel(), error[:, 1:].ravel())[0, 1]
    assert abs(neighbours) < 0.3


def test_filtered_importance_walkthrough_in_a_white_furnace(ctx, tmp_path):
    """The comparison method: n importance samples, the same at every pixel, Eq. 4.4 weights."""
    size = (16, 16)
    bake, cam, albedo = glossy_furnace(tmp_path, m=0.2, r0=0.9, size=size)
    with Renderer(ctx, bake, walkthrough="filtered-importance", lobe_samples=64) as r:
        r.render(cam, *size)
        linear = r.read_linear()[..., 0]
        assert r.stats["specular"]["walkthrough"] == "filtered-importance"
    np.testing.assert_allclose(linear, albedo, rtol=0.02)


def test_window_refines_while_the_camera_stands_still(bake):
    from test_view import frame, headless_window, press, release

    from glint.viewer.controls import WalkControls
    from glint.viewer.window import BLEND_FRAMES, ViewerWindow

    wnd = headless_window()
    try:
        start = Camera(name="start", eye=[0.0, -2.0, 1.5], forward=[0.0, 2.5, -1.5], up=[0, 0, 1], yfov=0.9,
                       znear=0.01, zfar=100.0)
        controls = WalkControls([start], [], ViewCamera(eye=(0, 0, 5), forward=(0, 0, -1)), speed=1.0)
        viewer = ViewerWindow(ctx=wnd.ctx, wnd=wnd, bake=bake, controls=controls)
        wnd.config = viewer
        renderer = viewer.renderer
        frame(wnd)
        assert renderer.mode == "walkthrough"
        for k in range(1, BLEND_FRAMES + 3):
            frame(wnd)
            assert renderer.mode == "converge" and renderer.progressive.frames == k
        press(wnd, wnd.keys.W)
        frame(wnd)
        assert renderer.mode == "walkthrough" and renderer.progressive.frames == 0
        release(wnd, wnd.keys.W)
        frame(wnd)  # standing still again: refining starts over from the new view
        assert renderer.mode == "converge" and renderer.progressive.frames == 1
    finally:
        wnd.destroy()


def test_capture_converge_is_deterministic(tmp_path):
    """`glint capture --converge N` twice: byte-identical files, the mean of N still frames."""
    import json

    from conftest import write_room

    from glint.cli import main
    from glint.core.image_io import read_image

    lobes = [{"kind": "reflect", "ks": [1, 1, 1], "mx": 0.2, "my": 0.2, "r0": 0.5}]
    scene = write_room(tmp_path / "room.glb", floor_lobes=lobes, sidecar='[objects."Floor"]\nrole = "curved"\n')
    common = [str(scene), "--size", "48x32", "--supersample", "1", "-q", "draft", "--samples", "8",
              "--texels-per-metre", "6", "--no-denoise", "--bake-dir", str(tmp_path / "room.bake"),
              "--eye", "-0.5,1.2,0.8", "--target", "0,0,-0.5"]
    for name in ("a", "b"):
        assert main(["capture", *common, "-o", str(tmp_path / f"{name}.exr"), "--converge", "6",
                     "--stats", str(tmp_path / f"{name}.json")]) == 0
    assert main(["capture", *common, "-o", str(tmp_path / "walk.exr")]) == 0
    assert (tmp_path / "a.exr").read_bytes() == (tmp_path / "b.exr").read_bytes()
    stats = json.loads((tmp_path / "a.json").read_text())["per_frame"][0]["specular"]
    assert stats["progressive"]["frames"] == 6 and stats["mode"] == "converged"
    assert stats["pixels_with_lobes"] > 500 and stats["cube_maps_bound"] == 1
    still, walk = read_image(tmp_path / "a.exr"), read_image(tmp_path / "walk.exr")
    assert np.all(np.isfinite(still)) and 1e-4 < np.abs(still - walk).max()


@pytest.mark.parametrize("option, value", [("--converge", "-1"), ("--converge", "x"), ("--lobe-samples", "0")])
def test_capture_rejects_bad_still_camera_options(tmp_path, capsys, option, value):
    from glint.cli import main

    code = main(["capture", "cornell-box", "-o", str(tmp_path / "a.png"), option, value])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err[-1].startswith(f"glint: bad {option} '{value}'")
    assert not (tmp_path / "a.png").exists()
