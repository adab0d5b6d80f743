"""`glint view`: the walkthrough controls (pure numbers), the overlay text, the command line
without a display, and the window class running frames on moderngl-window's headless
backend (EGL: llvmpipe here) with simulated key events."""
from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import FAST, NOT_ERRORS, write_room

from glint.core.manifest import Camera, CameraPath
from glint.viewer.camera import ViewCamera
from glint.viewer.controls import LOOK_SENSITIVITY, MAX_DT, MAX_PITCH, RUN_FACTOR, SPEED_STEP, WalkControls

SPEED = 2.0
CAMERAS = [
    Camera(name="north", eye=[0.0, 1.6, 0.0], forward=[0.0, 0.0, -1.0], up=[0, 1, 0], yfov=0.9, znear=0.05, zfar=50.0),
    Camera(name="east", eye=[3.0, 1.2, -1.0], forward=[1.0, 0.0, 0.0], up=[0, 1, 0], yfov=1.1, znear=0.05, zfar=50.0),
    Camera(name="down", eye=[0.0, 5.0, 0.0], forward=[0.0, -1.0, 1.0], up=[0, 1, 0], yfov=0.7, znear=0.05, zfar=50.0),
]
# Two keys: the spline's tangents at both ends are the chord, so the path is the straight line
# between them, travelled at constant speed -- easy to predict without the spline code.
PATH = CameraPath.from_json({"name": "tour", "keys": [{"time": 1.0, "eye": [0.0, 1.5, 0.0], "target": [0.0, 1.5, -5.0]},
                                                      {"time": 5.0, "eye": [4.0, 1.5, 0.0], "target": [4.0, 1.5, -5.0]}]})
HOME = ViewCamera(eye=(9.0, 9.0, 9.0), forward=(0.0, 0.0, -1.0))


def controls(cameras=CAMERAS, paths=(PATH,), **kwargs) -> WalkControls:
    return WalkControls(list(cameras), list(paths), HOME, speed=SPEED, **kwargs)


def step(c: WalkControls, seconds: float, dt: float = 0.05) -> ViewCamera:
    camera = None
    for _ in range(round(seconds / dt)):
        camera = c.update(dt)
    return camera


# -- moving -------------------------------------------------------------------------------------
@pytest.mark.parametrize("key, direction", [
    ("w", (0, 0, -1)), ("s", (0, 0, 1)), ("d", (1, 0, 0)), ("a", (-1, 0, 0)),
    ("e", (0, 1, 0)), ("space", (0, 1, 0)), ("q", (0, -1, 0)), ("c", (0, -1, 0)),
    ("up", (0, 0, -1)), ("right", (1, 0, 0)),
])
def test_key_moves_eye_by_speed_times_dt(key, direction):
    c = controls()  # starts at camera "north": eye (0, 1.6, 0) looking along -Z, so right is +X
    c.key_press(key)
    camera = c.update(0.05)
    np.testing.assert_allclose(camera.eye, np.array([0, 1.6, 0]) + SPEED * 0.05 * np.array(direction), atol=1e-12)
    np.testing.assert_allclose(camera.forward, [0, 0, -1], atol=1e-12)  # moving does not turn
    c.key_release(key)
    np.testing.assert_allclose(c.update(0.05).eye, camera.eye)  # released: stands still


def test_walking_follows_the_view_direction_and_stays_level():
    c = controls(start="east")  # looking along +X: forward is +X, right is +Z
    c.key_press("w")
    np.testing.assert_allclose(c.update(0.1).eye, [3.0 + SPEED * 0.1, 1.2, -1.0], atol=1e-12)
    c.key_release("w")
    c.key_press("d")
    np.testing.assert_allclose(c.update(0.1).eye, [3.0 + SPEED * 0.1, 1.2, -1.0 + SPEED * 0.1], atol=1e-12)
    c.key_release("d")
    # Looking 45 degrees down, W still walks horizontally, at full speed.
    c = controls(start="down")
    c.key_press("w")
    np.testing.assert_allclose(c.update(0.1).eye, [0.0, 5.0, SPEED * 0.1], atol=1e-9)


def test_diagonal_is_not_faster_and_opposite_keys_cancel():
    c = controls()
    c.key_press("w")
    c.key_press("d")
    eye = c.update(0.1).eye
    np.testing.assert_allclose(eye, [SPEED * 0.1 / math.sqrt(2), 1.6, -SPEED * 0.1 / math.sqrt(2)], atol=1e-12)
    c.key_press("a")  # a cancels d
    c.key_press("s")  # s cancels w
    np.testing.assert_allclose(c.update(0.1).eye, eye, atol=1e-12)


def test_speed_shift_and_plus_minus():
    c = controls()
    c.key_press("shift")
    c.key_press("w")
    assert c.update(0.1).eye[2] == pytest.approx(-SPEED * RUN_FACTOR * 0.1)
    c.key_release("shift")
    c.text("+")
    assert c.update(0.1).eye[2] == pytest.approx(-SPEED * RUN_FACTOR * 0.1 - SPEED * SPEED_STEP * 0.1)
    c.text("-")
    c.text("-")
    z = c.pose.eye[2]
    assert c.update(0.1).eye[2] == pytest.approx(z - SPEED / SPEED_STEP * 0.1)


def test_a_long_stall_does_not_teleport():
    c = controls()
    c.key_press("w")
    assert c.update(3.0).eye[2] == pytest.approx(-SPEED * MAX_DT)


# -- looking ------------------------------------------------------------------------------------
def test_mouse_right_turns_right_and_down_looks_down():
    c = controls()  # forward -Z, right +X
    c.mouse_look(100, 0)
    angle = 100 * LOOK_SENSITIVITY
    np.testing.assert_allclose(c.update(0.0).forward, [math.sin(angle), 0, -math.cos(angle)], atol=1e-12)
    c.mouse_look(-100, 60)  # back to -Z, then 60 px down
    pitch = -60 * LOOK_SENSITIVITY
    camera = c.update(0.0)
    np.testing.assert_allclose(camera.forward, [0, math.sin(pitch), -math.cos(pitch)], atol=1e-12)
    np.testing.assert_allclose(camera.eye, [0, 1.6, 0])  # looking does not move
    assert np.dot(camera.up, [0, 1, 0]) > 0 and abs(np.dot(camera.up, camera.forward)) < 1e-12  # no roll


@pytest.mark.parametrize("dy", [-1e6, 1e6])
def test_pitch_is_clamped(dy):
    c = controls()
    c.mouse_look(0, dy)
    camera = c.update(0.0)
    assert camera.forward[1] == pytest.approx(-math.copysign(math.sin(MAX_PITCH), dy))
    assert abs(camera.forward[1]) < 1.0
    assert np.isfinite(camera.view_matrix()).all()
    c.mouse_look(0, -dy / 1e6 * 10)  # 10 px back: moves away from the limit at once
    assert abs(c.update(0.0).forward[1]) < math.sin(MAX_PITCH)


# -- cameras and paths --------------------------------------------------------------------------
def test_camera_cycling():
    c = controls()
    assert c.camera_index == 0
    seen = []
    for _ in range(4):
        c.key_press("tab")
        seen.append(c.update(0.0).eye.tolist())
    assert seen == [CAMERAS[1].eye, CAMERAS[2].eye, CAMERAS[0].eye, CAMERAS[1].eye]
    c.key_press("tab", shift=True)
    np.testing.assert_allclose(c.update(0.0).eye, CAMERAS[0].eye)
    c.key_press("3")
    camera = c.update(0.0)
    np.testing.assert_allclose(camera.eye, CAMERAS[2].eye)
    np.testing.assert_allclose(camera.forward, np.array([0, -1, 1]) / math.sqrt(2), atol=1e-12)
    assert camera.yfov == pytest.approx(0.7)
    c.key_press("9")  # no ninth camera: nothing happens
    np.testing.assert_allclose(c.update(0.0).eye, CAMERAS[2].eye)
    assert controls(start="east").camera_index == 1


def test_no_cameras_starts_at_home_and_tab_does_nothing():
    c = controls(cameras=[], paths=[])
    c.key_press("tab")
    c.key_press("1")
    c.key_press("p")
    camera = c.update(0.1)
    np.testing.assert_allclose(camera.eye, HOME.eye)
    assert not c.playing


def test_path_playback_position_loops_and_hands_over():
    c = controls()
    c.key_press("p")
    assert c.playing
    # Path time starts at the first key (1 s); after 1 s of frames it is at t = 2 s:
    # a quarter of the way from eye (0, 1.5, 0) to (4, 1.5, 0).
    camera = step(c, 1.0)
    np.testing.assert_allclose(camera.eye, [1.0, 1.5, 0.0], atol=1e-9)
    np.testing.assert_allclose(camera.forward, [0, 0, -1], atol=1e-9)
    # The span is 4 s: after 4 s more it is back at the same place (looping, not clamped).
    np.testing.assert_allclose(step(c, 4.0).eye, [1.0, 1.5, 0.0], atol=1e-9)
    np.testing.assert_allclose(step(c, 2.0).eye, [3.0, 1.5, 0.0], atol=1e-9)
    # A walking key stops the tour where it is and walks on from there.
    c.key_press("d")
    assert not c.playing
    np.testing.assert_allclose(c.update(0.1).eye, [3.0 + SPEED * 0.1, 1.5, 0.0], atol=1e-9)
    c.key_release("d")
    # P starts the tour from its beginning again; P again stops it.
    c.key_press("p")
    np.testing.assert_allclose(c.update(0.0).eye, [0.0, 1.5, 0.0], atol=1e-9)
    step(c, 2.0)
    c.key_press("p")
    assert not c.playing
    np.testing.assert_allclose(c.update(0.5).eye, [2.0, 1.5, 0.0], atol=1e-9)


def test_action_keys():
    c = controls()
    assert c.key_press("f12") == "screenshot"
    assert c.key_press("s", ctrl=True) == "screenshot"
    assert c.key_press("f1") == "overlay"
    assert c.key_press("f") == "fullscreen"
    assert c.key_press("escape") == "quit"
    assert c.key_press("w") is None
    c.key_release("w")
    np.testing.assert_allclose(c.update(0.1).eye, CAMERAS[0].eye)  # Ctrl+S did not walk back


# -- overlay text and screenshot names ----------------------------------------------------------
def test_overlay_lines():
    from glint.viewer.overlay import overlay_lines

    lines = overlay_lines(50.0, {"gbuffer": 1.5, "shading": 2.25, "total": 3.75}, "from north")
    assert "50.0 fps" in lines[0] and "20.0 ms" in lines[0]
    assert any(line.startswith("gbuffer") and line.endswith("1.50 ms") for line in lines)
    assert any(line.startswith("shading") and line.endswith("2.25 ms") for line in lines)
    assert any(line.startswith("GPU total") and line.endswith("3.75 ms") for line in lines)
    assert "from north" in lines
    # the panel is found from the overlay: its last line names the click, M and F2
    assert "click or M" in lines[-1] and "F2 panel" in lines[-1]


def test_screenshot_names_are_unique(tmp_path):
    from glint.viewer.window import screenshot_path

    names = {screenshot_path(tmp_path, "room") for _ in range(3)}
    assert len(names) == 3 and all(p.exists() and p.suffix == ".png" and p.parent == tmp_path for p in names)


# -- command line -------------------------------------------------------------------------------
def glint(*args, env=None, cwd=None):
    return subprocess.run([sys.executable, "-m", "glint", *map(str, args)], capture_output=True, text=True,
                          env=env, cwd=cwd, timeout=300)


def one_line(result) -> str:
    lines = [l for l in result.stderr.strip().splitlines() if not l.startswith(NOT_ERRORS)]
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    return lines[0]


def test_no_display_suggests_capture(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["GLINT_CACHE"] = str(tmp_path / "cache")
    result = glint("view", "cornell-box", env=env, cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    line = one_line(result)
    assert line.startswith("glint: ") and "display" in line and "glint capture cornell-box" in line
    assert not (tmp_path / "cache").exists()  # stopped before baking


FAST_ARGS = ["-q", "draft", "--samples", FAST["samples"], "--texels-per-metre", FAST["texels_per_metre"],
             "--no-denoise"]


def test_window_that_cannot_open_and_bad_camera(tmp_path):
    room = write_room(tmp_path / "room.glb")
    env = {**os.environ, "DISPLAY": ":4321"}  # set, but no X server there
    env.pop("WAYLAND_DISPLAY", None)
    result = glint("view", room, *FAST_ARGS, "--camera", "nope", env=env)
    assert result.returncode == 2
    line = one_line(result)
    assert "unknown camera 'nope'" in line and "Camera" in line  # names the cameras it has
    result = glint("view", room, *FAST_ARGS, env=env)
    assert result.returncode == 2
    line = one_line(result)
    assert "cannot open a window" in line and "glint capture" in line


@pytest.mark.parametrize("size", ["640by480", "0x480"])
def test_bad_size(tmp_path, size):
    env = {**os.environ, "GLINT_CACHE": str(tmp_path / "cache")}
    result = glint("view", "cornell-box", "--size", size, env=env, cwd=tmp_path)
    assert result.returncode == 2
    assert "--size" in one_line(result) and size in one_line(result)
    assert not (tmp_path / "cache").exists()  # checked before baking


# -- the window, on moderngl-window's headless backend ----------------------------------------
SIDECAR = """
[cameras.side]
eye = [0.8, 1.0, 0.0]
target = [0.0, 1.0, 0.0]
"""


@pytest.fixture(scope="module")
def room_bake(tmp_path_factory):
    from glint.bake.gltf_loader import load_scene
    from glint.bake.settings import resolve_settings
    from glint.core.bake_dir import Bake
    from glint.services import bake_scene

    path = write_room(tmp_path_factory.mktemp("room") / "room.glb", sidecar=SIDECAR)
    scene = load_scene(path)
    report = bake_scene(scene, resolve_settings(scene.bake_settings, **FAST), path.with_suffix(".bake"),
                        progress=False)
    return Bake(report.bake_dir)


def headless_window(size=(96, 64)):
    from moderngl_window.context.base import BaseKeys
    from moderngl_window.context.headless import Window

    from glint.viewer.window import GL_VERSION

    class Keys(BaseKeys):  # the headless backend has no keyboard: give it codes to simulate one
        ACTION_PRESS, ACTION_RELEASE = "press", "release"
        W, S, F1, F12, TAB, ESCAPE = "W", "S", "F1", "F12", "TAB", "ESCAPE"

    class KeyedHeadless(Window):
        keys = Keys

    # Headless EGL (Mesa llvmpipe without a GPU) is part of what CI provides: no skip.
    return KeyedHeadless(size=size, gl_version=GL_VERSION, backend="egl", aspect_ratio=None)


class Modifiers:
    shift = ctrl = alt = False


def press(wnd, key, **mods):
    m = Modifiers()
    for k, v in mods.items():
        setattr(m, k, v)
    wnd.key_event_func(key, wnd.keys.ACTION_PRESS, m)


def release(wnd, key):
    wnd.key_event_func(key, wnd.keys.ACTION_RELEASE, Modifiers())


def frame(wnd, dt=0.1):
    """What moderngl-window's main loop does per frame."""
    wnd.use()
    wnd.render(0.0, dt)
    wnd.swap_buffers()


def window_pixels(wnd) -> np.ndarray:
    w, h = wnd.size
    return np.frombuffer(wnd.fbo.read(components=3), np.uint8).reshape(h, w, 3)[::-1]  # top row first


def test_window_renders_walks_and_screenshots(room_bake, tmp_path):
    from glint.viewer.overlay import MARGIN
    from glint.viewer.window import ViewerWindow

    wnd = headless_window((128, 160))
    manifest = room_bake.model
    controls = WalkControls(manifest.cameras, manifest.camera_paths, HOME)
    viewer = ViewerWindow(ctx=wnd.ctx, wnd=wnd, bake=room_bake, controls=controls, name="room",
                          screenshot_dir=tmp_path)
    try:
        frame(wnd)
        start = viewer.camera.eye.copy()
        np.testing.assert_allclose(start, [0, 1, 0.9], atol=1e-6)  # the glTF's camera, looking along -Z

        # Not empty: the lit room fills the frame with more than one colour.
        pixels = window_pixels(wnd)
        assert pixels.shape == (160, 128, 3)
        assert (pixels.max(axis=2) > 10).mean() > 0.5 and pixels.reshape(-1, 3).std(axis=0).max() > 5

        # The overlay is drawn in the top-left corner only; without it the window shows exactly
        # the renderer's tone-mapped frame (right way up).
        frame_srgb = viewer.renderer.read_srgb()
        covered = MARGIN + viewer.overlay.texture.size[1]  # rows from the top
        assert covered < pixels.shape[0]
        assert (pixels != frame_srgb).any(axis=2)[MARGIN:covered, MARGIN:].mean() > 0.2
        np.testing.assert_array_equal(pixels[covered:], frame_srgb[covered:])
        press(wnd, "F1")
        frame(wnd)
        np.testing.assert_array_equal(window_pixels(wnd), viewer.renderer.read_srgb())

        # W held for three frames of 0.1 s: forward (-Z) by 3 x 0.1 x walking speed.
        press(wnd, "W")
        for _ in range(3):
            frame(wnd, 0.1)
        release(wnd, "W")
        frame(wnd, 0.1)
        np.testing.assert_allclose(viewer.camera.eye, start + [0, 0, -0.3 * controls.speed], atol=1e-6)
        assert not np.array_equal(window_pixels(wnd), pixels)  # the picture changed with it

        # Tab: the sidecar's second camera.
        press(wnd, "TAB")
        frame(wnd)
        np.testing.assert_allclose(viewer.camera.eye, [0.8, 1.0, 0.0], atol=1e-6)

        # F12 and Ctrl+S: PNGs of the tone-mapped frame in the screenshot directory.
        press(wnd, "F12")
        press(wnd, "S", ctrl=True)
        from PIL import Image

        assert len(viewer.screenshots) == 2 and viewer.screenshots[0] != viewer.screenshots[1]
        for path in viewer.screenshots:
            assert path.parent == tmp_path
            np.testing.assert_array_equal(np.asarray(Image.open(path).convert("RGB")),
                                          viewer.renderer.read_srgb())
        np.testing.assert_allclose(viewer.camera.eye, [0.8, 1.0, 0.0], atol=1e-6)  # Ctrl+S did not walk
        viewer.screenshot_dir = tmp_path / "no-such-dir"  # cannot be written: a warning, no crash
        press(wnd, "F12")
        assert len(viewer.screenshots) == 2

        press(wnd, "ESCAPE")
        assert wnd.is_closing
    finally:
        viewer.release()
        wnd.destroy()


def test_window_resizes_with_the_window(room_bake):
    from glint.viewer.window import ViewerWindow

    wnd = headless_window((64, 48))
    manifest = room_bake.model
    viewer = ViewerWindow(ctx=wnd.ctx, wnd=wnd, bake=room_bake,
                          controls=WalkControls(manifest.cameras, [], HOME))
    try:
        frame(wnd)
        wnd.size = (80, 40)
        wnd._buffer_width, wnd._buffer_height = 80, 40  # what a real backend reports on resize
        wnd.resize(80, 40)
        frame(wnd)
        assert viewer.renderer.size == (80, 40) and window_pixels(wnd).shape == (40, 80, 3)
    finally:
        viewer.release()
        wnd.destroy()


def test_main_loop_runs_until_escape(room_bake):
    from glint.viewer.window import ViewerWindow, run

    class Scripted(ViewerWindow):
        """Presses Esc from inside the loop after a few frames, as a user would."""

        def on_render(self, time, frame_time):
            super().on_render(time, frame_time)
            if self.wnd.frames == 3:
                press(self.wnd, "ESCAPE")

    wnd = headless_window()
    manifest = room_bake.model
    viewer = Scripted(ctx=wnd.ctx, wnd=wnd, bake=room_bake, controls=WalkControls(manifest.cameras, [], HOME))
    run(viewer)  # returns only once the window closes; destroys the context
    assert wnd.frames >= 3 and wnd.is_closing


def test_exposure_reaches_the_window(room_bake, tmp_path):
    """`glint view --exposure EV` scales the window's radiance by 2^EV before the tone curve, as
    capture's does (the bake's dark-scene warning names it for both); a bad value is one line before
    any bake. Deliberate bug tried: ViewerWindow not passing exposure to its Renderer: the two frames
    are equal."""
    from glint.viewer.window import ViewerWindow

    means = []
    for ev in (0.0, 1.0):
        wnd = headless_window((64, 48))
        manifest = room_bake.model
        controls = WalkControls(manifest.cameras, manifest.camera_paths, HOME)
        viewer = ViewerWindow(ctx=wnd.ctx, wnd=wnd, bake=room_bake, controls=controls, name="room",
                              screenshot_dir=tmp_path, panel=False, exposure=ev)
        try:
            frame(wnd)
            linear = viewer.renderer.read_linear()[..., :3].astype(np.float64)
            means.append((viewer.renderer.read_srgb().astype(np.float64).mean(), linear.mean()))
        finally:
            viewer.renderer.release()
            wnd.destroy()
    (srgb0, lin0), (srgb1, lin1) = means
    assert lin1 == pytest.approx(lin0, rel=1e-6)  # the radiance is the same; only the display changes
    assert srgb1 > srgb0 + 10, means

    result = glint("view", "cornell-box", "--exposure", "bright", env={**os.environ, "GLINT_CACHE": str(tmp_path / "c")})
    assert "bad --exposure 'bright'" in one_line(result) and result.returncode == 2
    assert not (tmp_path / "c").exists()


_BAKE_APART = """
import sys
from glint.cli import build_parser
from glint.view import bake_apart
argv = ["view", "material-classes", "-q", "draft", "--bake-dir", sys.argv[1]]
args = build_parser(argv).parse_args(argv)
report = bake_apart(args)
print(report.status, "glint.cubemap_stage" in sys.modules)
"""


def test_view_bakes_in_another_process(tmp_path):
    """`glint view` on a scene not yet baked bakes it in a spawned process (glint/view.py bake_apart):
    the bake's cube maps make a headless EGL context, after which the window opened in the same
    process showed only black under Xvfb (Mesa llvmpipe), while a window on a bake already done was
    right. Seen by hand: with run_bake in the window's process, a fresh `glint view material-classes`
    under Xvfb grabbed as all 0; with bake_apart, the scene. This checks what the fix rests on: after
    a bake that renders cube maps, the cube-map stage was never imported in the viewer's process.
    Bug it catches (tried): bake_apart calling run_bake itself (the stage imported, its context made
    here)."""
    out = subprocess.run([sys.executable, "-c", _BAKE_APART, str(tmp_path / "b")], capture_output=True,
                         text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    status, stage = out.stdout.split()
    assert status != "up-to-date" and (tmp_path / "b" / "cubemaps").is_dir()
    assert stage == "False"
