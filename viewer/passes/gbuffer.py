"""G-buffer pass: rasterise the visible objects once into the targets the shading pass reads.

Reads: the scene's meshes, materials, textures and light maps. Writes: the targets, whose
encoding shaders/gbuffer_layout.glsl gives. The objects are drawn GPU-driven
(viewer/draw_list.py, region 0): culled against the view frustum all at once, one multi-draw
per texture batch. Nothing is culled by facing, because back faces must show (black for
single-sided materials, as in Mitsuba).

Two ways to the same targets (`visibility`):
- raster: shaders/gbuffer.frag writes them, fragment by fragment (every fragment that passes the
  depth test at the time does the whole surface's work: light map, textures, normal map);
- a visibility buffer (viewer/passes/visibility.py): the raster pass writes depth and a 4-byte
  triangle id per pixel, a compute pass works out each pixel's surface once, from its triangle, and
  writes the targets as images. A GPU's raster back end writes 4 bytes per fragment instead of 32
  (issue 27: on an H200 the two RGBA32UI targets alone cost 2.6 ms at 1920x1080, depth and R32UI 0.5 ms). The
  same surface (shaders/raster_surface.glsl) either way, its textures' MIP levels from the same
  differences across the pixel's 2 x 2 quad (not the driver's dFdx). Scenes drawn at a level of detail
  (the bake's cube-map renders) keep the raster way: the resolve finds a pixel's triangle in its
  object's own range of the index buffer; so do scenes of more than MAX_BATCHES texture batches
  (viewer/passes/visibility.py).
"""
from __future__ import annotations

import math

import moderngl
import numpy as np

from glint.core.constants import GB_DARK_BIT, GB_ID_BITS
from glint.viewer.camera import ViewCamera
from glint.viewer.draw_list import BatchPrograms
from glint.viewer.gl import GL, release_framebuffer
from glint.viewer.gl_bindings import GB_FRAME_IMAGE, GB_FRAME_LOCATION, GB_SHADE_IMAGE, GB_SHADE_LOCATION
from glint.viewer.passes.visibility import MAX_BATCHES, VisibilityResolve

# The colour targets by fragment-output location (gbuffer.frag, shaders/gbuffer_layout.glsl).
COLOUR_TARGETS = {GB_SHADE_LOCATION: "shade", GB_FRAME_LOCATION: "frame"}


def read_gbuffer(targets: dict) -> dict[str, np.ndarray]:
    """The G-buffer read back (waits for the GPU), GL rows (row 0 at the bottom), decoded as
    shaders/gbuffer_read.glsl decodes it: {"material", "object": (H, W) int64, "drawn": depth < 1,
    "dark": back face of a single-sided material, "flags": (H, W) uint32, every GB_*_BIT shifted down by
    16, "normal": (H, W, 3) the unit shading normal, "diffuse": (H, W, 3) float32 the diffuse radiance}."""
    shade, frame = targets["shade"], targets["frame"]
    w, h = shade.size
    shade_words = np.frombuffer(shade.read(alignment=1), np.uint32).reshape(h, w, 4)
    frame_words = np.frombuffer(frame.read(alignment=1), np.uint32).reshape(h, w, 4)
    depth = np.frombuffer(targets["depth"].read(alignment=1), np.float32).reshape(h, w)
    material, obj = decode_ids(shade_words[..., 3])
    return {"material": material, "object": obj, "drawn": depth < 1.0, "dark": (frame_words[..., 2] & GB_DARK_BIT) != 0,
            "flags": frame_words[..., 2] >> 16, "normal": oct_decode(frame_words[..., 0]),
            "diffuse": shade_words[..., :3].copy().view(np.float32)}


def decode_ids(ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ids word of the shade target (gbuffer_layout.glsl) -> (material, object) as int64."""
    ids = np.asarray(ids, np.uint32)
    return (ids & ((1 << GB_ID_BITS) - 1)).astype(np.int64), (ids >> GB_ID_BITS).astype(np.int64)


def oct_decode(words: np.ndarray) -> np.ndarray:
    """numpy twin of gbuffer_layout.glsl's gb_oct_decode(unpackSnorm2x16(word)): (...,) uint32 ->
    (..., 3) unit vectors."""
    halves = np.stack([words & 0xFFFF, words >> 16], axis=-1).astype(np.uint16).view(np.int16)
    p = np.clip(halves.astype(np.float64) / 32767.0, -1.0, 1.0)
    n = np.concatenate([p, 1.0 - np.abs(p).sum(axis=-1, keepdims=True)], axis=-1)
    folded = (1.0 - np.abs(p[..., ::-1])) * np.where(p >= 0.0, 1.0, -1.0)
    n[..., :2] = np.where(n[..., 2:] < 0.0, folded, n[..., :2])
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


class GBufferPass:
    name = "gbuffer"
    REGION = 0  # its commands in the DrawList (the mirror passes use 1, 2, ...)

    def __init__(self, ctx: moderngl.Context, scene, draws, defines: dict, visibility: bool = False):
        """draws: the scene's viewer/draw_list.py DrawList (shared with the mirror passes);
        visibility: through a visibility buffer (module docstring; not in a scene with levels of detail)."""
        self.ctx = ctx
        self.scene = scene
        self.draws = draws
        usable = bool(visibility) and not draws.lod and len(draws.batches) <= MAX_BATCHES
        self.ids = VisibilityResolve(ctx, scene, draws, defines, "RESOLVE_GBUFFER") if usable else None
        self.program = self.ids.program if self.ids else BatchPrograms(ctx, "gbuffer.vert", "gbuffer.frag", defines)
        self.size: tuple[int, int] | None = None
        self.fbo = None        # what the raster pass draws into (its depth: the occlusion queries')
        self.read_fbo = None   # the targets with the depth (`pick`)
        self.targets: dict[str, moderngl.Texture] = {}

    @property
    def visibility(self) -> bool:
        """Whether this pass goes through a visibility buffer (module docstring)."""
        return self.ids is not None

    def resize(self, size: tuple[int, int]) -> None:
        if size == self.size:
            return
        self._release_targets()
        ctx = self.ctx
        with GL(ctx).checked(f"allocate the G-buffer of {size[0]} x {size[1]} pixels"):
            t = {"shade": ctx.texture(size, 4, dtype="u4"),
                 "frame": ctx.texture(size, 4, dtype="u4"),
                 "depth": ctx.depth_texture(size)}
            if self.ids:
                self.ids.resize(size)
        for tex in t.values():
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)  # read with texelFetch; integer targets need it
            tex.repeat_x = tex.repeat_y = False
        t["depth"].compare_func = ""  # read raw depth values, not shadow comparisons
        self.targets = t
        self.read_fbo = ctx.framebuffer([t[COLOUR_TARGETS[k]] for k in range(len(COLOUR_TARGETS))], t["depth"])
        self.fbo = self.ids.framebuffer(t["depth"]) if self.ids else self.read_fbo
        self.size = size

    def run(self, camera: ViewCamera, aspect: float, hidden=(), min_radius_ndc: float = 0.0,
            triangles_per_pixel: float = 0.0) -> None:
        """Draw every object in view except those whose index is in `hidden` (a cube map leaves
        out its own object) and, with min_radius_ndc > 0, non-emitters that project smaller
        (viewer/draw_list.py); with triangles_per_pixel > 0, in a scene with levels of detail, each
        object at the coarsest level with that many triangles per pixel it covers.
        `draws.record(REGION)` says afterwards what was drawn and skipped."""
        ctx = self.ctx
        self.fbo.use()
        self.fbo.viewport = (0, 0, *self.size)
        ctx.enable_only(moderngl.DEPTH_TEST)
        ctx.depth_func = "<"
        self.fbo.clear(depth=1.0)  # colour targets need no clear: depth 1 marks the empty pixels
        self.program.set(eye=tuple(map(float, camera.eye)))
        detail = None
        if triangles_per_pixel > 0:  # pixels per radian at the centre: cot(yfov / 2) x half the height
            scale = self.size[1] / 2 / math.tan(camera.yfov / 2) * math.sqrt(triangles_per_pixel)
            detail = (camera.eye, scale)
        view_proj = camera.view_projection(aspect)
        self.draws.draw(self.program, view_proj, region=self.REGION, hidden=hidden,
                        min_radius_ndc=min_radius_ndc, detail=detail)
        if self.ids:
            self.targets["shade"].bind_to_image(GB_SHADE_IMAGE, read=False, write=True)
            self.targets["frame"].bind_to_image(GB_FRAME_IMAGE, read=False, write=True)
            self.ids.run(self.targets["depth"], view_proj, camera.eye)

    def pick(self, x: int, y: int) -> tuple[int, int] | None:
        """(object, material) drawn at G-buffer pixel (x, y) (GL rows: y = 0 at the bottom) of the
        last frame, or None for the sky, a back face of a single-sided material or outside. Reads
        that one pixel back (its ids word and depth), not the frame."""
        if self.fbo is None or not (0 <= x < self.size[0] and 0 <= y < self.size[1]):
            return None
        viewport = (int(x), int(y), 1, 1)
        attachment = next(k for k, name in COLOUR_TARGETS.items() if name == "shade")
        fbo = self.read_fbo
        shade = np.frombuffer(fbo.read(viewport=viewport, components=4, attachment=attachment, dtype="u4"), np.uint32)
        depth = np.frombuffer(fbo.read(viewport=viewport, components=1, attachment=-1, dtype="f4"), np.float32)
        if not depth[0] < 1.0:  # cleared to 1: nothing drawn there
            return None
        material, obj = decode_ids(shade[3:4])
        return int(obj[0]), int(material[0])

    def _release_targets(self) -> None:
        for fbo in {id(f): f for f in (self.fbo, self.read_fbo) if f is not None}.values():
            release_framebuffer(self.ctx, fbo)
        for tex in self.targets.values():
            tex.release()
        self.fbo, self.read_fbo, self.targets = None, None, {}

    def release(self) -> None:
        self._release_targets()
        (self.ids or self.program).release()  # the visibility buffer's raster program is its own
