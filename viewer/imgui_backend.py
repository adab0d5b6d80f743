"""Dear ImGui (imgui-bundle) drawn through moderngl-window's integration, on ImGui 1.92's textures.

moderngl-window 3.1's `ModernglWindowRenderer` (moderngl_window/integrations/imgui_bundle.py)
was written for ImGui before 1.92: it asks the font atlas for one RGBA image
(`get_tex_data_as_rgba32`), which imgui-bundle 1.92 and later no longer have. ImGui 1.92 lets
the renderer own its textures instead (`ImGuiBackendFlags_RendererHasTextures`: the frame's
draw data lists textures to create, update and destroy; glyphs are rasterised on demand). This
subclass keeps the integration's program, buffers and draw loop and adds that protocol, with
every texture upload checked (viewer/gl.py `GL.checked`); mouse input goes through ImGui's
event queue (`add_mouse_*_event`), which 1.92 expects instead of writing `io.mouse_down`.

    imgui.create_context()
    ui = ImguiRenderer(window)       # a moderngl-window BaseWindow
    imgui.new_frame(); ...widgets...; imgui.render()
    ui.draw(imgui.get_draw_data())   # onto the bound framebuffer, blended, over its whole viewport
"""
from __future__ import annotations

import ctypes
import time

import moderngl
from imgui_bundle import imgui
from moderngl_window.integrations.imgui_bundle import ModernglWindowRenderer

from glint.viewer.gl import GL, check_texture_size

# moderngl-window key attribute -> ImGui key: every key a backend may define, so that Enter on a
# focused field, Tab between fields and Ctrl+A / C / V / X / Z in a text field reach ImGui
IMGUI_KEYS = {"TAB": imgui.Key.tab, "LEFT": imgui.Key.left_arrow, "RIGHT": imgui.Key.right_arrow,
              "UP": imgui.Key.up_arrow, "DOWN": imgui.Key.down_arrow, "PAGE_UP": imgui.Key.page_up,
              "PAGE_DOWN": imgui.Key.page_down, "HOME": imgui.Key.home, "END": imgui.Key.end,
              "INSERT": imgui.Key.insert, "DELETE": imgui.Key.delete, "SPACE": imgui.Key.space,
              "BACKSPACE": imgui.Key.backspace, "ENTER": imgui.Key.enter, "ESCAPE": imgui.Key.escape,
              "LEFT_SHIFT": imgui.Key.left_shift, "RIGHT_SHIFT": imgui.Key.right_shift,
              "LEFT_CTRL": imgui.Key.left_ctrl, "RIGHT_CTRL": imgui.Key.right_ctrl,
              "LEFT_ALT": imgui.Key.left_alt, "RIGHT_ALT": imgui.Key.right_alt,
              "COMMA": imgui.Key.comma, "MINUS": imgui.Key.minus, "PERIOD": imgui.Key.period,
              "SLASH": imgui.Key.slash, "SEMICOLON": imgui.Key.semicolon, "EQUAL": imgui.Key.equal,
              **{chr(c): getattr(imgui.Key, chr(c).lower()) for c in range(ord("A"), ord("Z") + 1)},
              **{f"NUMBER_{d}": getattr(imgui.Key, f"_{d}") for d in range(10)},
              **{f"F{n}": getattr(imgui.Key, f"f{n}") for n in range(1, 13)}}
# the keys that move between the panel's fields and open one for typing (Enter) while it has the
# keyboard focus: the window does not also walk with them then (viewer/window.py)
NAVIGATION_KEYS = frozenset((imgui.Key.tab, imgui.Key.left_arrow, imgui.Key.right_arrow, imgui.Key.up_arrow,
                             imgui.Key.down_arrow, imgui.Key.page_up, imgui.Key.page_down, imgui.Key.home,
                             imgui.Key.end, imgui.Key.enter, imgui.Key.space))
# ImGui's modifier "keys" (ImGuiMod_*: a backend submits them itself; 1.92 does not derive them from
# the left / right keys) and the moderngl-window keys that hold each down
MODIFIERS = {"ctrl": (imgui.Key.mod_ctrl, ("LEFT_CTRL", "RIGHT_CTRL")),
             "shift": (imgui.Key.mod_shift, ("LEFT_SHIFT", "RIGHT_SHIFT")),
             "alt": (imgui.Key.mod_alt, ("LEFT_ALT", "RIGHT_ALT"))}
DOUBLE_CLICK_SECONDS = 0.3  # two presses this close in wall-clock time (ImGui's own default window) ...
DOUBLE_CLICK_PIXELS = 6  # ... and space are a double click, whatever the frame rate


class ImguiRenderer(ModernglWindowRenderer):
    navigation_keys = NAVIGATION_KEYS

    def __init__(self, window):
        self._gl = GL(window.ctx)
        super().__init__(window)

    def _init_key_maps(self) -> None:
        keys = self.wnd.keys
        self.REVERSE_KEYMAP = {getattr(keys, name): key for name, key in IMGUI_KEYS.items()
                               if getattr(keys, name, "undefined") not in (None, "undefined")}
        self._modifier_keys = {getattr(keys, key): mod for mod, (_, names) in MODIFIERS.items() for key in names
                               if getattr(keys, key, "undefined") not in (None, "undefined")}
        self._held: set[str] = set()  # modifiers whose key is down, from the key events
        self._last_press: tuple[float, float, float] | None = None  # (wall-clock s, x, y) of the last left press

    def refresh_font_texture(self) -> None:
        """No atlas image up front: ImGui 1.92 asks for its textures in `draw` (module docstring)."""
        io = imgui.get_io()
        io.backend_flags |= imgui.BackendFlags_.renderer_has_textures
        platform = imgui.get_platform_io()
        platform.renderer_texture_max_width = platform.renderer_texture_max_height = \
            int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])

    def _update_textures(self) -> None:
        """Create, update (the whole image again: the font atlas is small) or destroy what ImGui asks."""
        status = imgui.ImTextureStatus
        for tex in imgui.get_platform_io().textures:
            # A texture this renderer never made (its id from a renderer released before, in an
            # earlier window of the same process: the atlas outlives it) is made here.
            foreign = tex.status in (status.ok, status.want_updates) and tex.tex_id not in self._textures
            if tex.status in (status.want_create, status.want_updates) or foreign:
                pixels = tex.get_pixels_array()
                what = f"upload ImGui's texture ({tex.width} x {tex.height})"
                if tex.status == status.want_create or foreign:
                    check_texture_size(self.ctx, tex.width, tex.height, "ImGui's font atlas", fix="use a smaller font")
                    with self._gl.checked(what):
                        texture = self.ctx.texture((tex.width, tex.height), 4, pixels.tobytes())
                    self.register_texture(texture)
                    tex.set_tex_id(texture.glo)
                else:
                    with self._gl.checked(what):
                        self._textures[tex.tex_id].write(pixels.tobytes())
                tex.status = status.ok
            elif tex.status == status.want_destroy:
                texture = self._textures.pop(tex.tex_id, None)
                if texture is not None:
                    texture.release()
                tex.set_tex_id(0)
                tex.status = status.destroyed

    def draw(self, draw_data) -> None:
        """The frame's ImGui draw lists onto the bound framebuffer, alpha-blended (the integration's
        `render`, with the textures of ImGui 1.92's draw commands)."""
        self._update_textures()
        io = self.io
        width, height = io.display_size
        scale = io.display_framebuffer_scale
        fb_height = int(height * scale[1])
        if width <= 0 or height <= 0:
            return
        self.projMat.value = (2.0 / width, 0.0, 0.0, 0.0, 0.0, -2.0 / height, 0.0, 0.0,
                              0.0, 0.0, -1.0, 0.0, -1.0, 1.0, 0.0, 1.0)  # pixels -> NDC, y down
        draw_data.scale_clip_rects(imgui.ImVec2(*scale))
        ctx = self.ctx
        # Every piece of GL state the draw depends on is set here, not inherited from the pass
        # before: the overlay leaves the viewport on its own box, which squeezed the panel into it.
        ctx.viewport = (0, 0, int(width * scale[0]), fb_height)
        ctx.wireframe = False
        ctx.enable_only(moderngl.BLEND)
        ctx.blend_equation = moderngl.FUNC_ADD
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        for commands in draw_data.cmd_lists:
            vertices = (ctypes.c_byte * (commands.vtx_buffer.size() * imgui.VERTEX_SIZE)).from_address(
                commands.vtx_buffer.data_address())
            indices = (ctypes.c_byte * (commands.idx_buffer.size() * imgui.INDEX_SIZE)).from_address(
                commands.idx_buffer.data_address())
            self._vertex_buffer.orphan(max(len(vertices), self._vertex_buffer.size))
            self._index_buffer.orphan(max(len(indices), self._index_buffer.size))
            self._vertex_buffer.write(vertices)
            self._index_buffer.write(indices)
            for command in commands.cmd_buffer:
                self._textures[command.get_tex_id()].use(0)
                x, y, z, w = command.clip_rect
                ctx.scissor = int(x), int(fb_height - w), int(z - x), int(w - y)
                self._vao.render(moderngl.TRIANGLES, vertices=command.elem_count, first=command.idx_offset)
        ctx.scissor = None
        ctx.disable(moderngl.BLEND)

    # -- input: ImGui 1.92's event queue ---------------------------------------------------------
    def _modifiers(self, modifiers=None) -> None:
        """Submit ImGui's Ctrl / Shift / Alt state: down while its key is held (the key events) or
        while the backend's modifier state says so (`modifiers`, or the window's, which pyglet and
        GLFW set at every key and mouse event)."""
        state = self.wnd.modifiers if modifiers is None else modifiers
        for name, (mod, _) in MODIFIERS.items():
            self.io.add_key_event(mod, name in self._held or bool(getattr(state, name, False)))

    def key_event(self, key, action, modifiers) -> None:
        """Every key the backend defines (IMGUI_KEYS), and the modifiers with it. A modifier key's
        own event carries the state from before it (X11), so its own press or release decides."""
        down = action == self.wnd.keys.ACTION_PRESS
        mod = self._modifier_keys.get(key)
        if mod is not None:
            (self._held.add if down else self._held.discard)(mod)
            self.io.add_key_event(MODIFIERS[mod][0], down)
        else:
            self._modifiers(modifiers)
        if key in self.REVERSE_KEYMAP:
            self.io.add_key_event(self.REVERSE_KEYMAP[key], down)

    def unicode_char_entered(self, char: str) -> None:
        for c in char:
            self.io.add_input_character(ord(c))

    def mouse_position_event(self, x, y, dx, dy) -> None:
        self.io.add_mouse_pos_event(*self._mouse_pos_viewport(x, y))

    def mouse_drag_event(self, x, y, dx, dy) -> None:
        self.io.add_mouse_pos_event(*self._mouse_pos_viewport(x, y))

    def mouse_press_event(self, x, y, button) -> None:
        double = False
        if button == self.wnd.mouse.left:
            now, last = time.monotonic(), self._last_press
            double = last is not None and now - last[0] < DOUBLE_CLICK_SECONDS and \
                abs(x - last[1]) + abs(y - last[2]) < DOUBLE_CLICK_PIXELS
            self._last_press = None if double else (now, x, y)
        self._modifiers()
        if double:
            # ImGui times its double clicks in frames (io.delta_time): at a few frames per second the
            # second press comes too late. A double click measured here is handed over as what it
            # means on a slider or drag field, a Ctrl+click: type a value.
            self.io.add_key_event(imgui.Key.mod_ctrl, True)
        self._button(x, y, button, True)
        if double:
            self._modifiers()

    def mouse_release_event(self, x, y, button) -> None:
        self._button(x, y, button, False)

    def _button(self, x, y, button, down: bool) -> None:
        self.io.add_mouse_pos_event(*self._mouse_pos_viewport(x, y))
        mouse = self.wnd.mouse
        index = {mouse.left: 0, mouse.right: 1, mouse.middle: 2}.get(button)
        if index is not None:
            self.io.add_mouse_button_event(index, down)

    def mouse_scroll_event(self, x_offset, y_offset) -> None:
        self.io.add_mouse_wheel_event(x_offset, y_offset)

    def release(self) -> None:
        for texture in self._textures.values():
            texture.release()
        self._textures.clear()
        for part in (self._vao, self._vertex_buffer, self._index_buffer, self._prog):
            part.release()  # the integration's own teardown touches the pre-1.92 font atlas
