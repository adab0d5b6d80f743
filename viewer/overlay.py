"""The on-screen overlay: frame rate, GPU time per pass and where the walker is.

The text is drawn with Pillow into an RGBA texture and blended over the frame's
top-left corner by the window's blit program. It is redrawn a few times per
second, not every frame: numbers that change 60 times a second cannot be read,
and re-uploading the texture every frame would cost time the overlay reports.
"""
from __future__ import annotations

import moderngl
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from glint.viewer.gl_bindings import BLIT_UNIT

UPDATE_INTERVAL = 0.25  # s
MARGIN = 8  # px from the window's edges
PADDING = 6  # px around the text
HELP = ("WASD/arrows walk  drag look  Q/E down/up  Shift run  +/- speed  Tab/1-9 cameras  P tour  F12 shot  F1 hide\n"
        "click or M: edit the material under the cursor  F2 panel  Ctrl+Z/Y undo/redo  Ctrl+click a field: type a value")


def overlay_lines(fps: float, gpu_ms: dict[str, float], status: str, extra=()) -> list[str]:
    """The overlay's text: fps and frame time, GPU time per pass and in total, `extra` lines (the
    skipped work, viewer/skipping.py), the walker's status."""
    lines = [f"{fps:6.1f} fps  {1000.0 / fps if fps > 0 else 0.0:6.1f} ms/frame"]
    passes = {name: ms for name, ms in gpu_ms.items() if name != "total"}
    if passes:
        total = gpu_ms.get("total", sum(passes.values()))
        width = max(map(len, [*passes, "GPU total"]))
        lines += [f"{name:<{width}}  {ms:7.2f} ms" for name, ms in passes.items()]
        lines.append(f"{'GPU total':<{width}}  {total:7.2f} ms")
    lines += [*extra, status, *HELP.split("\n")]
    return lines


def render_text(lines: list[str]) -> Image.Image:
    """White text on a translucent dark panel, just large enough for the lines."""
    font = ImageFont.load_default()
    probe = ImageDraw.Draw(Image.new("RGBA", (1, 1)))
    line_height = int(probe.textbbox((0, 0), "Ag|", font=font)[3]) + 2
    width = max(int(probe.textbbox((0, 0), line, font=font)[2]) for line in lines)
    image = Image.new("RGBA", (width + 2 * PADDING, line_height * len(lines) + 2 * PADDING), (0, 0, 0, 150))
    draw = ImageDraw.Draw(image)
    for i, line in enumerate(lines):
        draw.text((PADDING, PADDING + i * line_height), line, font=font, fill=(255, 255, 255, 255))
    return image


class Overlay:
    def __init__(self, ctx: moderngl.Context, blit: moderngl.Program, triangle: moderngl.VertexArray):
        self.ctx, self.blit, self.triangle = ctx, blit, triangle
        self.visible = True
        self.texture: moderngl.Texture | None = None
        self._frames = 0
        self._elapsed = 0.0
        self.fps = 0.0
        self.lines: list[str] = []  # the text shown

    def due(self, dt: float) -> bool:
        """Count a frame of dt seconds; True when the text should be redrawn (every UPDATE_INTERVAL)."""
        self._frames += 1
        self._elapsed += dt
        return self.texture is None or self._elapsed >= UPDATE_INTERVAL

    def update(self, gpu_ms: dict[str, float], status: str, extra=()) -> None:
        """Redraw the text, with the frame rate measured since the last update."""
        self.fps = self._frames / self._elapsed if self._elapsed > 0 else 0.0
        self._frames, self._elapsed = 0, 0.0
        self.lines = overlay_lines(self.fps, gpu_ms, status, extra)
        image = render_text(self.lines)
        if self.texture is None or self.texture.size != image.size:
            if self.texture is not None:
                self.texture.release()
            self.texture = self.ctx.texture(image.size, 4)
        # Pillow's first row is the top one, OpenGL's the bottom one.
        self.texture.write(np.ascontiguousarray(np.asarray(image)[::-1]).tobytes())

    def draw(self, window_height: int) -> None:
        """Blend the text over the currently bound framebuffer, in its top-left corner."""
        if not self.visible or self.texture is None:
            return
        w, h = self.texture.size
        viewport = self.ctx.viewport  # given back afterwards: what is drawn next covers the whole window
        self.ctx.viewport = (MARGIN, window_height - MARGIN - h, w, h)
        self.ctx.enable(moderngl.BLEND)
        # Colour blends by the text's alpha; the frame's alpha (1) stays, so the window stays opaque.
        self.ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA, moderngl.ZERO, moderngl.ONE
        self.texture.use(BLIT_UNIT)
        self.blit["opaque"] = False
        self.triangle.render(moderngl.TRIANGLES, vertices=3)
        self.ctx.disable(moderngl.BLEND)
        self.ctx.viewport = viewport

    def release(self) -> None:
        if self.texture is not None:
            self.texture.release()
            self.texture = None
