"""The material panel as a user meets it, in a window of moderngl-window's headless backend (EGL,
llvmpipe here) of a real window's size, with the overlay ON (its default): pick with a click, the
panel's pixels where its widgets are, a panel taller than the window scrolls, Ctrl+click (and
Enter on a focused field) to type an exact value, a double click whatever the frame rate; and the
whole round on a room baked for real with its background re-bake: edit, undo to a baked state
(from the cache, no new re-bake), redo, Save.

The scene is tests/test_panel.py's floor under constant light; the expected values come from the
user's actions (a typed "0.25" must become m = 0.25), never from the panel's code.
"""
from __future__ import annotations

import time

import imgui_bundle  # noqa: F401  (a dependency of glint)
import numpy as np
import pytest
from test_panel import CAMERA, floor_bake
from test_view import HOME, Modifiers

from glint.viewer.controls import WalkControls

SIZE = (640, 360)  # a small window (the issue met the problems at 800 x 450): fewer pixels to render
BIG = (1280, 720)  # `glint view`'s default window
TYPING = (480, 320)  # enough for the panel's first fields, and fewer pixels to render
DIFFERS = 24  # of 255: a pixel the panel covers differs from the picture under it by more than this


def keyed_window(size, bake, **kwargs):
    """A headless ViewerWindow with the overlay on and simulated keys (the headless backend has no
    keyboard: its key codes are names)."""
    from moderngl_window.context.base import BaseKeys
    from moderngl_window.context.headless import Window

    from glint.viewer.window import GL_VERSION, ViewerWindow

    class Keys(BaseKeys):
        ACTION_PRESS, ACTION_RELEASE = "press", "release"
        M, Z, Y, F1, F2, TAB, ENTER, BACKSPACE, LEFT_CTRL, ESCAPE = \
            "M", "Z", "Y", "F1", "F2", "TAB", "ENTER", "BACKSPACE", "LEFT_CTRL", "ESCAPE"

    class KeyedHeadless(Window):
        keys = Keys

    wnd = KeyedHeadless(size=size, gl_version=GL_VERSION, backend="egl", aspect_ratio=None)
    viewer = ViewerWindow(ctx=wnd.ctx, wnd=wnd, bake=bake, controls=WalkControls([CAMERA], [], HOME), **kwargs)
    assert viewer.overlay.visible  # the default, as a user meets it
    return wnd, viewer


def picture_frozen(viewer):
    """From now on the window shows the last 3-D frame again (the panel and the input are what the
    test checks; llvmpipe takes about 0.6 s to render a frame of this floor)."""
    viewer.renderer.render = lambda *args, **kwargs: None


def frames(wnd, n=1):
    for _ in range(n):
        wnd.use()
        wnd.render(0.0, 0.05)
        wnd.swap_buffers()


def picture(wnd) -> np.ndarray:
    """The window's pixels, (H, W, 3) uint8, top row first (window coordinates)."""
    w, h = wnd.size
    return np.frombuffer(wnd.fbo.read(components=3), np.uint8).reshape(h, w, 3)[::-1]


def click(wnd, x, y):
    wnd.mouse_position_event_func(x, y, 0, 0)
    wnd.mouse_press_event_func(x, y, wnd.mouse.left)
    frames(wnd)
    wnd.mouse_release_event_func(x, y, wnd.mouse.left)
    frames(wnd)


def key(wnd, name, **mods):
    m = Modifiers()
    for k, v in mods.items():
        setattr(m, k, v)
    wnd.key_event_func(name, "press", m)
    frames(wnd)
    wnd.key_event_func(name, "release", m)
    frames(wnd)


def type_text(wnd, text):
    for c in text:
        wnd.unicode_char_entered_func(c)
    frames(wnd)


def centre(rect):
    return (rect[0] + rect[2]) / 2, (rect[1] + rect[3]) / 2


def covered(with_panel, without, rect) -> float:
    """Fraction of the pixels in rect (x0, y0, x1, y1) that the panel changed by more than DIFFERS."""
    x0, y0, x1, y1 = (int(round(v)) for v in rect)
    a, b = with_panel[y0:y1, x0:x1].astype(int), without[y0:y1, x0:x1].astype(int)
    return float((np.abs(a - b).max(axis=-1) > DIFFERS).mean()) if a.size else 0.0


def test_panel_fills_its_place_with_the_overlay_on(ctx, tmp_path):
    """A click on the floor opens the panel; with the overlay drawn just before it, the panel's
    pixels are where it says its widgets are: over the panel's rectangle at least 90 % of the
    pixels differ from the picture without the panel (its opaque background over the bright
    floor; measured 100 %), some in each widget's rectangle, and under 1 % outside the panel and
    the overlay's box (measured 0 %). It lies inside the 640 x 360 window.

    Deliberate bug this catches (tried): the overlay's viewport left set for the panel (neither the
    overlay nor the ImGui renderer setting it) -> the panel squeezed into the overlay's box: 4.4 %
    of the panel's rectangle covered."""
    from glint.viewer.overlay import MARGIN

    wnd, viewer = keyed_window(SIZE, floor_bake(tmp_path / "b"))
    try:
        frames(wnd, 3)
        click(wnd, SIZE[0] // 3, SIZE[1] * 3 // 4)
        assert viewer.panel.visible and viewer.panel.picked == 0
        frames(wnd, 2)
        with_panel = picture(wnd)
        panel_rect, widgets = viewer.panel.rect, dict(viewer.panel.widgets)
        viewer.panel.visible = False
        frames(wnd)
        without = picture(wnd)
        assert viewer.overlay.visible and viewer.overlay.texture is not None
        x0, y0, x1, y1 = panel_rect
        assert 0 <= x0 < x1 <= SIZE[0] and 0 <= y0 < y1 <= SIZE[1]
        assert covered(with_panel, without, panel_rect) > 0.9
        for name in ("Undo", "Save", "kd", "m 0", "r0 0", "alpha 0"):
            assert covered(with_panel, without, widgets[name]) > 0.1, name
        outside = np.ones(with_panel.shape[:2], bool)
        outside[int(y0):int(np.ceil(y1)), int(x0):int(np.ceil(x1))] = False
        ow, oh = viewer.overlay.texture.size
        outside[:MARGIN + oh + 1, :MARGIN + ow + 1] = False  # its numbers change between frames
        changed = np.abs(with_panel.astype(int) - without.astype(int)).max(axis=-1) > DIFFERS
        assert changed[outside].mean() < 0.01
    finally:
        viewer.release()
        wnd.destroy()


def open_gltf(wnd, viewer):
    """Open the glTF-style section with a click on its header (scrolled into view first)."""
    while "glTF-style" not in viewer.panel.widgets or viewer.panel.widgets["glTF-style"][3] > viewer.panel.rect[3]:
        x, y = centre(viewer.panel.rect)
        wnd.mouse_position_event_func(x, y, 0, 0)
        wnd.mouse_scroll_event_func(0, -1)
        frames(wnd)
    click(wnd, *centre(viewer.panel.widgets["glTF-style"]))
    frames(wnd)
    assert "roughness" in viewer.panel.widgets


def test_panel_scrolls_in_a_small_window_and_fits_a_large_one(ctx, tmp_path):
    """With the lobe and the glTF-style section open the panel is taller than 640 x 360: it stays
    inside the window (its bottom at most 8 px above the window's) and the mouse wheel scrolls it
    until the roughness and transmission sliders show; the height it needs (shown + scrolled over)
fits 1280 x 720 less the margins (measured 467 px).

    Deliberate bug this catches (tried): the panel's old fixed height (520 px, no size constraint)
    -> its bottom at 528 px, below the 450 px window."""
    from glint.view import pbr_mapping

    bake = floor_bake(tmp_path / "b")
    wnd, viewer = keyed_window(SIZE, bake, pbr_mapping=pbr_mapping)
    try:
        frames(wnd)
        viewer.pick(SIZE[0] // 3, SIZE[1] * 3 // 4)
        picture_frozen(viewer)
        frames(wnd, 2)
        assert viewer.panel.rect[3] <= SIZE[1] - 8 + 0.5
        open_gltf(wnd, viewer)
        assert viewer.panel.scroll[1] > 0  # taller than the window: it scrolls
        x, y = centre(viewer.panel.rect)
        for _ in range(20):
            if viewer.panel.widgets["transmission"][3] <= viewer.panel.rect[3]:
                break
            wnd.mouse_position_event_func(x, y, 0, 0)
            wnd.mouse_scroll_event_func(0, -1)
            frames(wnd)
        assert viewer.panel.scroll[0] > 0
        assert viewer.panel.rect[1] <= viewer.panel.widgets["roughness"][1] < viewer.panel.widgets["transmission"][3] \
            <= viewer.panel.rect[3] <= SIZE[1]
        # the height it needs without scrolling: what it shows and what it scrolls over
        needed = viewer.panel.rect[3] - viewer.panel.rect[1] + viewer.panel.scroll[1]
        print(f"panel needs {needed:.0f} px; bottom {viewer.panel.rect[3]:.0f}")
        assert needed <= BIG[1] - 16
    finally:
        viewer.release()
        wnd.destroy()


def test_ctrl_click_enter_and_double_click_type_exact_values(ctx, tmp_path):
    """As a user types a value: Ctrl held (its own key event, as X11 reports it: without the
    modifier), a click on the lobe's m slider, Ctrl released, "0.25" typed and Enter: m = 0.25
    exactly. Enter on the still focused field opens it again: "0.3" Enter gives m = 0.3 (float32).
    A double click on r0 (two clicks 0.05 s apart that arrive between two frames of 0.4 s, as at a
    few frames per second: ImGui, timing clicks by its frame clock, sees them 0.8 s apart, beyond
    its 0.3 s) opens it for typing too: "0.5" Enter gives r0 = 0.5. Typing walks nowhere.

    Deliberate bugs this catches (tried): the modifiers not forwarded to ImGui (the integration's
    key handling, Ctrl never reaching it) -> the click set m from the cursor's place on the slider
    (m = 0.0125 at once, before anything was typed); the nav cursor hidden after a click (ImGui's default) -> Enter did not
    open m again (m stayed 0.25); the double click left to ImGui's frame clock -> r0 = 0.544, the
    click's place on the slider, not the typed 0.5."""
    wnd, viewer = keyed_window(TYPING, floor_bake(tmp_path / "b"))
    try:
        frames(wnd)
        viewer.pick(TYPING[0] // 4, TYPING[1] * 3 // 4)
        picture_frozen(viewer)
        frames(wnd, 2)
        m0 = viewer.edits.materials[0].lobes[0].mx
        wnd.key_event_func("LEFT_CTRL", "press", Modifiers())  # X11: the state before the press
        frames(wnd)
        click(wnd, *centre(viewer.panel.widgets["m 0"]))
        ctrl = Modifiers()
        ctrl.ctrl = True
        wnd.key_event_func("LEFT_CTRL", "release", ctrl)  # X11: Ctrl still down in the state
        frames(wnd)
        assert viewer.edits.materials[0].lobes[0].mx == m0  # nothing set by the click itself
        type_text(wnd, "0.25")
        key(wnd, "ENTER")
        assert viewer.edits.materials[0].lobes[0].mx == 0.25
        assert viewer.edits.materials[0].lobes[0].my == 0.25

        key(wnd, "ENTER")  # the field still has the focus: Enter opens it again
        type_text(wnd, "0.3")
        key(wnd, "ENTER")
        assert viewer.edits.materials[0].lobes[0].mx == pytest.approx(0.3, abs=1e-7)

        # a double click at a few frames per second
        x, y = centre(viewer.panel.widgets["r0 0"])
        r0 = viewer.edits.materials[0].lobes[0].r0
        wnd.mouse_position_event_func(x, y, 0, 0)
        for _ in range(2):  # both clicks arrive between two slow frames, as a real window's events do
            wnd.mouse_press_event_func(x, y, wnd.mouse.left)
            wnd.mouse_release_event_func(x, y, wnd.mouse.left)
            time.sleep(0.05)
        for _ in range(4):  # ImGui takes one button change per frame
            wnd.render(0.0, 0.4)
        type_text(wnd, "0.5")
        key(wnd, "ENTER")
        assert viewer.edits.materials[0].lobes[0].r0 == 0.5, r0
        assert viewer.camera.eye == pytest.approx(CAMERA.eye)  # typing walked nowhere
    finally:
        viewer.release()
        wnd.destroy()


def test_a_user_edits_undoes_to_a_baked_state_and_saves(ctx, tmp_path):
    """The whole round as a user makes it, on a small room baked for real with its background
    re-bake as the window's light-map source: click the wall, Ctrl+click kd's red field and type
    0.5, Enter; the re-bake's passes arrive and are swapped in; Ctrl+Z (undo to the bake's state)
    brings the bake's light maps back on the next frame from the cache (no new re-bake: no pass
    arrives afterwards); Ctrl+Y (redo: the edited state, baked already) likewise; Save (its button)
    writes the sidecar with only kd, and picking the floor clears Save's message.

    Deliberate bug this catches (tried): the Rebaker without its cache -> after the undo the
    next frame swaps nothing in (the worker's new first pass comes seconds later)."""
    from test_rebake import bake_room

    from glint.bake.rebake import Rebaker
    from glint.core.manifest import Camera
    from glint.view import sidecar_saver

    room = bake_room(tmp_path)
    scene = room.path.parent / "room.glb"
    camera = Camera(name="in", eye=[0.0, 1.0, 0.8], forward=[0.0, 0.0, -1.0], up=[0, 1, 0], yfov=1.0,
                    znear=0.01, zfar=100.0)
    baked = [dict(m) for m in room.manifest["materials"]]
    swapped = []
    with Rebaker(scene, room.path, schedule=[8]) as rebaker:  # one pass: the round, not the passes, is tested here
        wnd, viewer = keyed_window(TYPING, room, on_edit=rebaker.edit, lightmap_source=rebaker,
                                   on_save=sidecar_saver(str(scene), scene, baked))
        viewer.controls = WalkControls([camera], [], HOME)
        replace = viewer.renderer.replace_lightmaps
        viewer.renderer.replace_lightmaps = lambda front, back: (swapped.append(front), replace(front, back))
        try:
            frames(wnd, 2)
            click(wnd, TYPING[0] // 4, TYPING[1] // 2)
            wall = viewer.panel.entry
            assert wall is not None and wall.name == "Wall"
            picture_frozen(viewer)
            frames(wnd)
            x0, y0, x1, y1 = viewer.panel.widgets["kd"]
            wnd.key_event_func("LEFT_CTRL", "press", Modifiers())
            click(wnd, x0 + 12, (y0 + y1) / 2)  # the red field, leftmost of the three
            ctrl = Modifiers()
            ctrl.ctrl = True
            wnd.key_event_func("LEFT_CTRL", "release", ctrl)
            frames(wnd)
            type_text(wnd, "0.5")
            key(wnd, "ENTER")
            assert viewer.edits.materials[viewer.panel.material].kd[0] == 0.5
            deadline = time.monotonic() + 120
            while not (rebaker.done and rebaker.last.final):
                frames(wnd)
                assert rebaker.error is None and time.monotonic() < deadline
            frames(wnd)
            n = len(swapped)
            assert n >= 1  # the re-bake's pass was swapped in

            key(wnd, "Z", ctrl=True)  # undo: the bake's state
            assert viewer.edits.materials == viewer.edits.baked and rebaker.from_cache
            assert len(swapped) == n + 1
            np.testing.assert_array_equal(swapped[-1][0], room.lightmap(0))
            key(wnd, "Y", ctrl=True)  # redo: the edited state, re-baked before
            assert len(swapped) == n + 2 and rebaker.from_cache
            time.sleep(1.0)  # longer than this room's 8-path pass, had one started
            frames(wnd)
            assert len(swapped) == n + 2  # no re-bake started: nothing more arrives

            click(wnd, *viewer.panel.button_centres["Save"])
            assert viewer.panel.status.startswith("saved"), viewer.panel.status
            text = (scene.parent / "room.glint.toml").read_text()
            assert 'kd = [0.5,' in text and "emission" not in text and "lobes" not in text
            viewer.pick(TYPING[0] // 4, TYPING[1] - 10)  # another object: the message goes
            assert viewer.panel.status == ""
        finally:
            viewer.release()
            wnd.destroy()
