"""The renderer: one class for the window and for headless captures.

    renderer = Renderer(ctx, Bake(path), supersample=2)
    renderer.render(camera, 1280, 720)
    renderer.read_linear()     # (720, 1280, 3) float32 radiance, row 0 = top of the image
    renderer.read_srgb()       # (720, 1280, 3) uint8, tone-mapped
    renderer.display_texture   # RGBA8 texture (GL orientation) a window blits to the screen
    renderer.stats             # GPU ms per pass, what was drawn and skipped

It draws into its own textures and never touches the default framebuffer, so it
does not care whether a window or nothing at all is on the other side; the
framebuffer bound before `render` is bound again after it.

Per frame (DESIGN.md "Viewer"): G-buffer raster pass at N times the output size
(N = supersample) -> shading in compute -> resolve (N x N box mean; skipped for
N = 1) -> tone map. `read_linear` is the resolved radiance before exposure and
tone mapping: physical radiance, comparable with a path tracer's image.
"""
from __future__ import annotations

import moderngl
import numpy as np

from glint.errors import GlintError
from viewer.camera import ViewCamera
from viewer.context import check_context, describe
from viewer.gpu_scene import GpuScene, shader_defines
from viewer.passes.gbuffer import GBufferPass
from viewer.passes.resolve import ResolvePass
from viewer.passes.shading import ShadingPass
from viewer.passes.tonemap import TonemapPass
from viewer.timing import PassTimer

MAX_SUPERSAMPLE = 8


class Renderer:
    def __init__(self, ctx: moderngl.Context, bake, supersample: int = 1, exposure: float = 0.0):
        check_context(ctx)
        self.ctx = ctx
        self.bake = bake
        self.supersample = supersample
        self.exposure = float(exposure)  # EV: the tone-mapped image is scaled by 2^exposure
        self.scene = GpuScene(ctx, bake)
        defines = shader_defines()
        self.gbuffer = GBufferPass(ctx, self.scene, defines)
        self.shading = ShadingPass(ctx, self.scene, defines)
        self.resolve = ResolvePass(ctx, defines)
        self.tonemap = TonemapPass(ctx, defines)
        self.timer = PassTimer(ctx)
        self.size: tuple[int, int] | None = None
        self._linear: moderngl.Texture | None = None
        self._display: moderngl.Texture | None = None
        self._drawn: dict = {}
        self._device = describe(ctx)

    @property
    def supersample(self) -> int:
        return self._supersample

    @supersample.setter
    def supersample(self, n: int) -> None:
        if not (isinstance(n, (int, np.integer)) and 1 <= n <= MAX_SUPERSAMPLE):
            raise GlintError(f"supersampling must be a whole number from 1 to {MAX_SUPERSAMPLE} (got {n!r})")
        self._supersample = int(n)

    def check_size(self, width: int, height: int) -> None:
        """GlintError unless width x height (times the supersampling) can be rendered here."""
        if not (int(width) == width and int(height) == height and width >= 1 and height >= 1):
            raise GlintError(f"bad image size {width}x{height}: width and height must be at least 1")
        limit = int(self.ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384))
        n = self.supersample
        if max(width, height) * n > limit:
            raise GlintError(f"image size {width}x{height} with supersampling {n} needs "
                             f"{width * n}x{height * n} pixels; this OpenGL allows at most {limit} "
                             "per side: use a smaller size or --supersample")

    def render(self, camera: ViewCamera, width: int, height: int) -> None:
        """Render one frame of `camera` at width x height output pixels."""
        self.check_size(width, height)
        ctx, n, timer = self.ctx, self.supersample, self.timer
        aspect = width / height
        full = (width * n, height * n)
        self.gbuffer.resize(full)
        self.shading.resize(full)
        previous = ctx.fbo  # after resizing, which may have deleted our own bound framebuffer
        timer.start_frame()
        with timer("gbuffer"):
            self._drawn = self.gbuffer.run(camera, aspect)
        with timer("shading"):
            linear = self.shading.run(self.gbuffer.targets, camera, aspect)
        if n > 1:
            with timer("resolve"):
                linear = self.resolve.run(linear, n)
        with timer("tonemap"):
            self._display = self.tonemap.run(linear, self.exposure)
        self._linear = linear
        self.size = (width, height)
        if previous is not None:  # a standalone context has none bound
            previous.use()

    # -- results ---------------------------------------------------------------------------------
    def _require_frame(self) -> None:
        if self._linear is None:
            raise RuntimeError("nothing rendered yet: call render() first")

    def read_linear(self) -> np.ndarray:
        """(H, W, 3) float32 linear radiance after the resolve; row 0 is the top of the image."""
        self._require_frame()
        w, h = self._linear.size
        data = np.frombuffer(self._linear.read(alignment=1), np.float32).reshape(h, w, 4)
        return np.ascontiguousarray(data[::-1, :, :3])

    def read_srgb(self) -> np.ndarray:
        """(H, W, 3) uint8 tone-mapped sRGB; row 0 is the top of the image."""
        self._require_frame()
        w, h = self._display.size
        data = np.frombuffer(self._display.read(alignment=1), np.uint8).reshape(h, w, 4)
        return np.ascontiguousarray(data[::-1, :, :3])

    @property
    def display_texture(self) -> moderngl.Texture:
        """The last frame, tone-mapped: RGBA8, GL orientation (row 0 at the bottom), sRGB-encoded
        already (blit it to a framebuffer without GL_FRAMEBUFFER_SRGB)."""
        self._require_frame()
        return self._display

    @property
    def stats(self) -> dict:
        """GPU ms per pass (last frame and median of recent ones), what was drawn and skipped."""
        skipped: dict = {"objects_outside_view": list(self._drawn.get("objects_culled", [])),
                         "objects_without_triangles": list(self._drawn.get("objects_empty", []))}
        if self.supersample == 1:
            skipped["resolve"] = "supersample 1: the shaded image is the output"
        with_lobes = [m["name"] for m in self.bake.manifest["materials"] if m.get("lobes")]
        if with_lobes:
            skipped["lobes"] = (f"view-dependent lobes are not shaded yet (issues 4 and 5): "
                                f"{len(with_lobes)} materials show their diffuse part only")
        size = list(self.size) if self.size else None
        median = self.timer.median_ms  # reads the last frame's queries first
        return {
            "device": self._device,
            "size": size,
            "render_size": [s * self.supersample for s in size] if size else None,
            "supersample": self.supersample,
            "exposure": self.exposure,
            "gpu_ms": dict(self.timer.last_ms),
            "gpu_ms_median": median,
            "frames_timed": self.timer.frames,
            "timing": self.timer.description,
            "objects": len(self.scene.objects),
            "objects_drawn": self._drawn.get("objects_drawn", 0),
            "triangles": self._drawn.get("triangles", 0),
            "triangles_in_scene": self.scene.triangles,
            "lightmap_format": "RGBA16F" if self.scene.lightmap_dtype == "f2" else "RGBA32F",
            "skipped": skipped,
        }

    def release(self) -> None:
        for part in (self.gbuffer, self.shading, self.resolve, self.tonemap, self.scene):
            part.release()
        self._linear = self._display = None

    def __enter__(self) -> "Renderer":
        return self

    def __exit__(self, *exc) -> None:
        self.release()
