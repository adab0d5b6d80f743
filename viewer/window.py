"""The walkthrough window: moderngl-window around the renderer.

`ViewerWindow` is the one WindowConfig of `glint view`. Each frame it asks the
controls (viewer/controls.py) for a camera, has the renderer draw the frame at
the window's framebuffer size, copies the tone-mapped result onto the window
with a full-screen triangle and blends the overlay on top. The renderer never
sees the window; the controls never see OpenGL.

While the camera moves, frames show the walkthrough's regular lobe patterns; as
soon as it stands still the renderer keeps refining the same view with
quasi-random samples (mode "auto", viewer/progressive.py), fading from the last
walkthrough image over `BLEND_FRAMES` frames, until `MAX_STILL_FRAMES` frames.

With imgui-bundle (a dependency) the window has the material panel (viewer/panel.py,
drawn with Dear ImGui: viewer/imgui_backend.py): a click (press and release without dragging)
or M picks the object under the cursor (`pick`: one G-buffer pixel read back) and the panel
edits its material live (`Renderer.set_material`); `on_edit(materials)` hears of every change
and Save calls `on_save(materials)` (both optional, given by the command layer, glint/view.py).

    window = create_window(size=(1280, 720), title="glint", vsync=True)
    viewer = ViewerWindow(ctx=window.ctx, wnd=window, bake=bake, controls=controls,
                          on_edit=None, on_save=None, pbr_mapping=None)
    run(viewer)   # until Esc or the window is closed
"""
from __future__ import annotations

import time
import weakref
from pathlib import Path

import moderngl
import moderngl_window
from moderngl_window.context.base import BaseWindow
from PIL import Image

from glint.core.errors import warn
from glint.viewer.collision import Collider
from glint.viewer.controls import WalkControls
from glint.viewer.gl import GL_REQUIRED, check_context
from glint.viewer.gl_bindings import BLIT_UNIT
from glint.viewer.material_edits import MaterialEdits
from glint.viewer.overlay import Overlay
from glint.viewer.panel import MaterialPanel
from glint.viewer.renderer import Renderer
from glint.viewer.shader_source import raster_program
from glint.viewer.skipping import frame_section, one_line

GL_VERSION = (GL_REQUIRED // 100, GL_REQUIRED % 100 // 10)
BLEND_FRAMES = 4  # from the walkthrough image to the running mean when the camera stops
MAX_STILL_FRAMES = 512  # then the image is final: 4096 samples per lobe and pixel
CLICK_PIXELS = 4  # a press and release closer than this (window pixels) is a click (pick), not a look

# moderngl-window key constant (attribute of the backend's Keys class) -> controls' key name
KEY_NAMES = {
    **{chr(c): chr(c).lower() for c in range(ord("A"), ord("Z") + 1)},
    **{f"NUMBER_{d}": str(d) for d in range(1, 10)},
    "SPACE": "space", "TAB": "tab", "ESCAPE": "escape", "F1": "f1", "F2": "f2", "F11": "f11", "F12": "f12",
    "LEFT_SHIFT": "shift", "RIGHT_SHIFT": "shift",
    "UP": "up", "DOWN": "down", "LEFT": "left", "RIGHT": "right",
}


def key_table(keys) -> dict:
    """Backend key code -> key name; keys the backend does not define are left out."""
    table = {}
    for attribute, name in KEY_NAMES.items():
        code = getattr(keys, attribute, "undefined")
        if code != "undefined":
            table[code] = name
    return table


def create_window(*, size: tuple[int, int], title: str, vsync: bool = True, fullscreen: bool = False,
                  backend: str = "pyglet", **options) -> BaseWindow:
    """Open a window of moderngl-window's `backend` (the MODERNGL_WINDOW environment variable
    overrides it) with an OpenGL 4.3 core context. Raises whatever the backend raises when there
    is no display; the command line turns that into its message."""
    window_cls = moderngl_window.get_local_window_cls(backend)
    window = window_cls(title=title, size=size, fullscreen=fullscreen, resizable=True, vsync=vsync,
                        gl_version=GL_VERSION, aspect_ratio=None, **options)
    moderngl_window.activate_context(window=window)
    return window


def screenshot_path(directory: Path, stem: str) -> Path:
    """A new file `stem-YYYYmmdd-HHMMSS.png` in directory, with -2, -3, ... when taken within one second."""
    base = f"{stem}-{time.strftime('%Y%m%d-%H%M%S')}"
    for k in range(1, 10_000):
        path = Path(directory) / (base + (f"-{k}" if k > 1 else "") + ".png")
        try:
            path.open("xb").close()  # claim the name, so two viewers never write the same file
            return path
        except FileExistsError:
            continue
    raise FileExistsError(f"{directory}: no free screenshot name for {base}")


class ViewerWindow(moderngl_window.WindowConfig):
    gl_version = GL_VERSION
    title = "glint"
    aspect_ratio = None  # the frame always fills the window, whatever its shape
    clear_color = None  # the blit writes every pixel
    resizable = True

    def __init__(self, *, bake, controls: WalkControls, supersample: int = 1, name: str = "glint",
                 screenshot_dir: Path | None = None, panel: bool = True, on_edit=None, on_save=None,
                 pbr_mapping=None, lightmap_source=None, exposure: float = 0.0, **kwargs):
        """exposure: stops, radiance x 2^exposure before the tone curve (`glint view --exposure`); panel: the material panel when imgui-bundle is installed (else a warning, and the window
        without it); on_edit(materials), on_save(materials): the command layer's callbacks with the
        whole list of manifest material entries as edited; pbr_mapping: the glTF-style controls'
        mapping (viewer/panel.py); lightmap_source: an object whose `poll()` returns None or new
        light-map pages (front, back) for the bake's atlas, never blocking, whose `poll_probes()`
        (if it has one) returns None or new cube-map probes {bake file: MIP chain}, and whose
        `status` is None or one line for the overlay (glint/view.py gives the background re-bake,
        glint.bake.rebake.Rebaker); polled every frame."""
        super().__init__(**kwargs)
        self.lightmap_source = lightmap_source
        check_context(self.ctx)
        self.controls = controls
        self.name = name
        self.screenshot_dir = Path.cwd() if screenshot_dir is None else Path(screenshot_dir)
        self.screenshots: list[Path] = []
        self.renderer = Renderer(self.ctx, bake, supersample=supersample, exposure=exposure,
                                 blend_frames=BLEND_FRAMES, max_frames=MAX_STILL_FRAMES)
        self.blit = raster_program(self.ctx, "blit.vert", "blit.frag")
        self.triangle = self.ctx.vertex_array(self.blit, [])
        self.overlay = Overlay(self.ctx, self.blit, self.triangle)
        self.keys = key_table(self.wnd.keys)
        if getattr(bake, "meshes", None) is not None and self.controls.collide is None:
            # walking stops short of surfaces: a step through a wall showed the black outside
            self.controls.collide = Collider.of_meshes(bake.meshes).move
        # Esc and fullscreen go through the controls like every other key, not the backend's defaults.
        self.wnd.exit_key = None
        self.wnd.fullscreen_key = None
        self.camera = None  # the last frame's, for tests and screenshots
        self.on_edit = on_edit
        self.edits = MaterialEdits(self.renderer.scene.materials, self.renderer.set_material, on_edit=self._edited)
        self.panel = MaterialPanel(self.edits, [(o.name, o.material) for o in self.renderer.scene.objects],
                                   pbr_mapping=pbr_mapping, on_save=on_save)
        self.ui = self._imgui() if panel else None
        self.mouse = (0, 0)  # last cursor position, window coordinates (for M)
        self._press: tuple[int, int] | None = None  # where a left-button press began (a click picks)

    def _imgui(self):
        """ImGui's context and renderer, or None (with a warning) without imgui-bundle."""
        try:
            from imgui_bundle import imgui

            from glint.viewer.imgui_backend import ImguiRenderer
        except ImportError as e:
            warn(f"no material panel: {e.name or 'imgui-bundle'} is not installed (pip install imgui-bundle)")
            return None
        self._imgui_context = imgui.create_context()
        io = imgui.get_io()
        io.set_ini_filename("")  # no imgui.ini written into the working directory
        io.config_flags |= imgui.ConfigFlags_.nav_enable_keyboard  # Tab between fields, Enter types a value
        # ImGui hides its keyboard focus after a mouse click and then ignores Enter: shown always, Enter
        # opens the field last clicked or tabbed to, and the user sees which one that is
        io.config_nav_cursor_visible_always = True
        return ImguiRenderer(self.wnd)

    def _edited(self, materials: list[dict]) -> None:
        if self.on_edit is not None:
            self.on_edit(materials)

    # -- drawing ---------------------------------------------------------------------------------
    def on_render(self, time: float, frame_time: float) -> None:
        self.camera = self.controls.update(frame_time)
        self.swap_lightmaps()
        width, height = self.wnd.buffer_size
        if width < 1 or height < 1:
            return  # minimised: some backends report a 0 x 0 framebuffer
        self.renderer.render(self.camera, width, height, mode="auto")  # refines while the camera is still

        self.wnd.use()
        self.ctx.viewport = (0, 0, width, height)
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
        self.renderer.display_texture.use(BLIT_UNIT)
        self.blit["opaque"] = True
        self.triangle.render(moderngl.TRIANGLES, vertices=3)

        if self.overlay.visible and self.overlay.due(frame_time):
            # stats waits for the GPU's timer queries: read it only when the text is redrawn
            stats = self.renderer.stats
            status = getattr(self.lightmap_source, "status", None)
            self.overlay.update(stats["gpu_ms_median"], self.controls.status,
                                [one_line(frame_section(stats)), *([status] if status else [])])
        self.overlay.draw(height)
        if self.ui is not None:
            self.draw_panel(frame_time)

    def draw_panel(self, frame_time: float) -> None:
        """The ImGui frame: the panel's widgets (which apply their edits at once, for the next
        frame), drawn over the picture."""
        from imgui_bundle import imgui

        io = imgui.get_io()
        io.display_size = self.wnd.size
        width, height = self.wnd.size
        bw, bh = self.wnd.buffer_size
        io.display_framebuffer_scale = (bw / max(width, 1), bh / max(height, 1))  # HiDPI: framebuffer pixels per window pixel
        io.delta_time = max(float(frame_time), 1e-4)  # ImGui asserts on 0
        imgui.new_frame()
        self.panel.draw()
        imgui.render()
        self.ui.draw(imgui.get_draw_data())

    def swap_lightmaps(self) -> bool:
        """Take the light-map source's newest pages and probes, if any, into the GPU scene and
        restart the still camera's refinement (its running mean holds the old light). True when
        something was swapped."""
        if self.lightmap_source is None:
            return False
        pages = self.lightmap_source.poll()
        if pages is not None:
            self.renderer.replace_lightmaps(*pages)
        poll_probes = getattr(self.lightmap_source, "poll_probes", None)
        probes = poll_probes() if poll_probes is not None else None
        if probes:
            self.renderer.replace_probes(probes)
        return pages is not None or bool(probes)

    def on_resize(self, width: int, height: int) -> None:
        pass  # every frame renders at the current framebuffer size; the renderer follows it

    # -- picking ---------------------------------------------------------------------------------
    def pick(self, x: float, y: float) -> int | None:
        """The object drawn at window position (x, y) (from the top left, in window coordinates) in
        the last frame, selected in the panel; None where there is none."""
        if self.renderer.size is None:
            return None
        width, height = self.wnd.size
        bw, bh = self.renderer.size
        hit = self.renderer.pick(x * bw / max(width, 1), y * bh / max(height, 1))
        self.panel.select_object(None if hit is None else hit[0])
        return None if hit is None else hit[0]

    def _ui_wants(self, what: str) -> bool:
        if self.ui is None:
            return False
        from imgui_bundle import imgui

        return bool(getattr(imgui.get_io(), what))

    # -- input -----------------------------------------------------------------------------------
    def _ui_takes(self, key) -> bool:
        """Whether a key is the panel's alone: every key while a field is being typed into; the
        keys that move between its fields and open one for typing (PANEL_KEYS) while it has the
        keyboard focus (after a click on it). Letters walk even then."""
        if self.ui is None:
            return False
        from imgui_bundle import imgui

        io = imgui.get_io()
        if io.want_text_input:
            return True
        return bool(io.want_capture_keyboard) and self.ui.REVERSE_KEYMAP.get(key) in self.ui.navigation_keys

    def on_key_event(self, key, action, modifiers) -> None:
        if self.ui is not None:
            self.ui.key_event(key, action, modifiers)
            if self._ui_takes(key):
                return  # typing into a field of the panel, or moving between its fields
        name = self.keys.get(key)
        if name is None:
            return
        if action == self.wnd.keys.ACTION_PRESS:
            action_name = self.controls.key_press(name, ctrl=bool(modifiers.ctrl), shift=bool(modifiers.shift))
            if action_name is not None:
                self.perform(action_name)
        elif action == self.wnd.keys.ACTION_RELEASE:
            self.controls.key_release(name)

    def on_unicode_char_entered(self, char: str) -> None:
        if self.ui is not None:
            self.ui.unicode_char_entered(char)
            if self._ui_wants("want_text_input"):
                return
        self.controls.text(char)

    def on_mouse_position_event(self, x: int, y: int, dx: int, dy: int) -> None:
        self.mouse = (x, y)
        if self.ui is not None:
            self.ui.mouse_position_event(x, y, dx, dy)

    def on_mouse_press_event(self, x: int, y: int, button: int) -> None:
        self.mouse = (x, y)
        if self.ui is not None:
            self.ui.mouse_press_event(x, y, button)
        # ImGui's flag is a frame late for a press that comes with its first move over the panel
        over_panel = self._ui_wants("want_capture_mouse") or (self.ui is not None and self.panel.contains(x, y))
        self._press = (x, y) if button == self.wnd.mouse.left and not over_panel else None

    def on_mouse_release_event(self, x: int, y: int, button: int) -> None:
        if self.ui is not None:
            self.ui.mouse_release_event(x, y, button)
        press, self._press = self._press, None
        if press is not None and button == self.wnd.mouse.left and \
                abs(x - press[0]) + abs(y - press[1]) < CLICK_PIXELS:
            self.pick(x, y)

    def on_mouse_scroll_event(self, x_offset: float, y_offset: float) -> None:
        if self.ui is not None:
            self.ui.mouse_scroll_event(x_offset, y_offset)

    def on_mouse_drag_event(self, x: int, y: int, dx: int, dy: int) -> None:
        self.mouse = (x, y)
        if self.ui is not None:
            self.ui.mouse_drag_event(x, y, dx, dy)
        if self._press is None and self._ui_wants("want_capture_mouse"):
            return  # dragging a slider of the panel
        self.controls.mouse_look(dx, dy)

    def on_iconify(self, iconified: bool) -> None:
        self.controls.release_all()  # key releases while minimised never arrive

    def perform(self, action: str) -> None:
        if action == "screenshot":
            self.save_screenshot()
        elif action == "overlay":
            self.overlay.visible = not self.overlay.visible
        elif action == "fullscreen":
            self.wnd.fullscreen = not self.wnd.fullscreen
        elif action == "quit":
            self.wnd.close()
        elif action == "pick":
            self.pick(*self.mouse)
        elif action == "panel":
            self.panel.visible = not self.panel.visible
        elif action in ("undo", "redo"):
            getattr(self.panel, action)()

    def save_screenshot(self) -> Path | None:
        """The last frame, tone-mapped, without the overlay, as a PNG in `screenshot_dir`."""
        if self.renderer.size is None:
            return None
        try:
            path = screenshot_path(self.screenshot_dir, self.name)
            try:
                Image.fromarray(self.renderer.read_srgb(), "RGB").save(path, format="PNG")
            except BaseException:
                path.unlink(missing_ok=True)  # no empty or half-written file left behind
                raise
        except OSError as e:  # a read-only directory must not end the walkthrough
            warn(f"screenshot not saved: {e}")
            return None
        self.screenshots.append(path)
        print(f"glint: screenshot {path}", flush=True)
        return path

    def release(self) -> None:
        if self.ui is not None:
            from imgui_bundle import imgui

            self.ui.release()
            imgui.destroy_context(self._imgui_context)
            self.ui = None
        self.overlay.release()
        self.renderer.release()
        self.triangle.release()
        self.blit.release()


def run(viewer: ViewerWindow) -> None:
    """The main loop, until the window closes (moderngl-window's own loop)."""
    window = viewer.wnd
    window._config = weakref.ref(viewer)  # as moderngl_window.create_window_config_instance does
    window.swap_buffers()  # can report the real framebuffer size before the first frame
    window.set_default_viewport()
    moderngl_window.run_window_config_instance(viewer)
