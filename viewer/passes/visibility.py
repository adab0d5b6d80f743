"""A visibility buffer's second half (Burns and Hunt 2013), for the raster passes that draw the scene's
meshes: the G-buffer (viewer/passes/gbuffer.py) and the planar reflectors' mirror passes
(viewer/passes/mirror.py), each through its own `VisibilityResolve`.

The owner's raster pass draws with `program` (gbuffer.vert and shaders/visibility.frag: depth and one
R32UI texel per pixel, the triangle's index in the scene's index buffer and its facing: visibility.glsl) into a framebuffer of
`ids` and its own depth texture. `run` then

1. lists the drawn pixels texture batch by texture batch (shaders/visibility_classify.comp: a count,
   a prefix sum that also writes each batch's dispatch, a scatter), and
2. per batch, its textures bound (viewer/draw_list.py), resolves the batch's pixels
   (shaders/visibility_resolve.comp, dispatched indirectly: the pixel count stays on the GPU): the
   triangle's vertices interpolated at the pixel, the uv derivatives of its 2 x 2 quad, the surface
   of shaders/raster_surface.glsl, written as images -- the G-buffer's two words (RESOLVE_GBUFFER) or
   a mirror buffer's radiance, position and normal at one layer (RESOLVE_MIRROR), what gbuffer.frag
   or mirror.frag would have written.

So every pixel is resolved once whatever the number of textured materials (a dispatch over the whole
screen per batch would read every pixel's ids once per batch). Reads: the ids and depth, the
scene's vertex and index buffers (as storage buffers), object, material and batch tables, light maps
and textures. Writes: the owner's images (bound by the owner before `run`), the pixel lists.
"""
from __future__ import annotations

import moderngl
import numpy as np

from glint.viewer.camera import gl_bytes
from glint.viewer.draw_list import BatchPrograms, bind_textures
from glint.viewer.gl import GL
from glint.viewer.gl_bindings import (
    DRAW_BATCH_OF_OBJECT_BINDING,
    INDEX_BINDING,
    LIGHTMAP_UNIT,
    VERTEX_BINDING,
    VISIBILITY_DEPTH_UNIT,
    VISIBILITY_LOCATION,
    VISIBILITY_PIXELS_BINDING,
    VISIBILITY_TALLY_BINDING,
    VISIBILITY_UNIT,
)
from glint.viewer.gpu_meshes import vertex_defines
from glint.viewer.shader_source import compute_program, dispatch, set_uniforms

RESOLVE_GROUP = 64  # visibility_resolve.comp's work-group size (one invocation per listed pixel)
# visibility_classify.comp keeps two words per batch in shared memory: 16 KiB at this many, half of
# the 32 KiB every GL 4.3 driver offers; a scene with more textured materials keeps the raster passes.
MAX_BATCHES = 2048
TARGETS = ("RESOLVE_GBUFFER", "RESOLVE_MIRROR")


class VisibilityResolve:
    def __init__(self, ctx: moderngl.Context, scene, draws, defines: dict, target: str):
        """target: "RESOLVE_GBUFFER" or "RESOLVE_MIRROR", what the resolve writes; defines: the raster
        pass's (a mirror pass's with MIRROR_CLIP)."""
        if target not in TARGETS:
            raise ValueError(f"unknown resolve target {target!r}")
        self.ctx, self.scene, self.draws = ctx, scene, draws
        batches = max(len(draws.batches), 1)
        lists = {"RESOLVE_GROUP": RESOLVE_GROUP, "VISIBILITY_BATCHES": batches}
        self.program = BatchPrograms(ctx, "gbuffer.vert", "visibility.frag", defines)
        self.resolve = compute_program(ctx, "visibility_resolve.comp",
                                       {**defines, **vertex_defines(), **lists, "SURFACE_FROM_IDS": 1, target: 1})
        self.classify = {step: compute_program(ctx, "visibility_classify.comp",
                                               {**defines, **vertex_defines(), **lists, target: 1, f"CLASSIFY_{step}": 1})
                         for step in ("COUNT", "PLAN", "SCATTER")}
        self.target = target
        self._gl = GL(ctx)
        with self._gl.checked(f"allocate the visibility buffer's tally of {batches} batches"):
            self.tally = ctx.buffer(reserve=6 * batches * 4)  # visibility_classify.comp VisibilityTally
        self.ids: moderngl.Texture | None = None
        self.pixels: moderngl.Buffer | None = None
        self.size: tuple[int, int] | None = None
        self._checked = False  # a resolve has run, its GL errors checked

    def resize(self, size: tuple[int, int]) -> None:
        """The ids target and the pixel list for `size` (the owner makes its framebuffer with `ids`)."""
        if size == self.size:
            return
        self._release_targets()
        with self._gl.checked(f"allocate a visibility buffer of {size[0]} x {size[1]} pixels"):
            self.ids = self.ctx.texture(size, 1, dtype="u4")
            self.pixels = self.ctx.buffer(reserve=4 * size[0] * size[1])  # a word per pixel
        self.ids.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.ids.repeat_x = self.ids.repeat_y = False
        assert VISIBILITY_LOCATION == 0  # the one colour attachment of the raster pass's framebuffer
        self.size = size

    def framebuffer(self, depth) -> moderngl.Framebuffer:
        """The raster pass's framebuffer: `ids` and the owner's depth texture."""
        return self.ctx.framebuffer([self.ids], depth)

    def run(self, depth: moderngl.Texture, view_proj: np.ndarray, eye, layer: int = 0, sky: dict | None = None) -> None:
        """Resolve what the raster pass left in `ids` and `depth` (drawn with `view_proj` from `eye`)
        into the owner's images, bound before. A mirror pass's: `layer`, its slot, and `sky`, the
        uniforms of the sky its empty pixels get (mirror_sky.frag's; the sky map bound by the owner):
        its targets need no clear and no sky pass."""
        sky = sky or {}
        if self._checked:
            self._run(depth, view_proj, eye, layer, sky)
            return
        with self._gl.checked("resolve a visibility buffer"):  # once: glGetError stalls the pipeline
            self._run(depth, view_proj, eye, layer, sky)
        self._checked = True

    def _run(self, depth, view_proj, eye, layer: int, sky: dict) -> None:
        ctx, scene, batches = self.ctx, self.scene, self.draws.batches
        self.ids.use(VISIBILITY_UNIT)
        depth.use(VISIBILITY_DEPTH_UNIT)
        scene.meshes.vertex_buffer.bind_to_storage_buffer(VERTEX_BINDING)
        scene.meshes.index_buffer.bind_to_storage_buffer(INDEX_BINDING)
        self.draws.batch_of_object().bind_to_storage_buffer(DRAW_BATCH_OF_OBJECT_BINDING)
        scene.object_buffer.bind_to_storage_buffer(scene.object_binding)
        scene.bind_materials()
        scene.lightmaps.use(LIGHTMAP_UNIT)
        self.tally.clear()
        self.tally.bind_to_storage_buffer(VISIBILITY_TALLY_BINDING)
        self.pixels.bind_to_storage_buffer(VISIBILITY_PIXELS_BINDING)
        if self.target == "RESOLVE_MIRROR":  # the count writes the empty texels of the layer
            set_uniforms(self.classify["COUNT"], layer=int(layer), **sky)
        dispatch(self.classify["COUNT"], *self.size)
        ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT)
        self.classify["PLAN"].run(1)
        ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT)
        dispatch(self.classify["SCATTER"], *self.size)
        ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT | moderngl.COMMAND_BARRIER_BIT)

        self.resolve["view_proj"].write(gl_bytes(view_proj))
        set_uniforms(self.resolve, eye=tuple(map(float, eye)), layer=int(layer))
        for b, (_, _, textures) in enumerate(batches):
            bind_textures(textures)
            set_uniforms(self.resolve, batch=b)
            self.resolve.run_indirect(self.tally, offset=4 * 3 * (len(batches) + b))  # VisibilityTally.dispatch[3 b]
        ctx.memory_barrier(moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT | moderngl.TEXTURE_FETCH_BARRIER_BIT
                           | moderngl.FRAMEBUFFER_BARRIER_BIT)

    def _release_targets(self) -> None:
        for obj in (self.ids, self.pixels):
            if obj is not None:
                obj.release()
        self.ids = self.pixels = None
        self.size = None

    def release(self) -> None:
        self._release_targets()
        for obj in (self.program, self.resolve, self.tally, *self.classify.values()):
            obj.release()
