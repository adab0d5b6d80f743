"""G-buffer pass: rasterise the visible objects once into the targets the shading pass reads.

Reads: the scene's meshes, materials, textures and light maps. Writes: the targets, whose
encoding shaders/gbuffer_layout.glsl gives. The objects are drawn GPU-driven
(viewer/draw_list.py, region 0): culled against the view frustum all at once, one multi-draw
per texture batch. Nothing is culled by facing, because back faces must show (black for
single-sided materials, as in Mitsuba).
"""
from __future__ import annotations

import moderngl

from glint.viewer.camera import ViewCamera
from glint.viewer.gl_bindings import (
    GB_DIFFUSE_LOCATION,
    GB_MATERIAL_LOCATION,
    GB_NORMAL_LOCATION,
    GB_SURFACE_LOCATION,
    GB_TANGENT_LOCATION,
)
from glint.viewer.shader_source import raster_program, set_uniforms

# The colour targets by fragment-output location (gbuffer.frag, shaders/gbuffer_layout.glsl).
COLOUR_TARGETS = {GB_DIFFUSE_LOCATION: "diffuse", GB_NORMAL_LOCATION: "normal", GB_TANGENT_LOCATION: "tangent",
                  GB_MATERIAL_LOCATION: "material", GB_SURFACE_LOCATION: "surface"}


class GBufferPass:
    name = "gbuffer"
    REGION = 0  # its commands in the DrawList (the mirror passes use 1, 2, ...)

    def __init__(self, ctx: moderngl.Context, scene, draws, defines: dict):
        """draws: the scene's viewer/draw_list.py DrawList (shared with the mirror passes)."""
        self.ctx = ctx
        self.scene = scene
        self.draws = draws
        self.program = raster_program(ctx, "gbuffer.vert", "gbuffer.frag", defines)
        self.size: tuple[int, int] | None = None
        self.fbo = None
        self.targets: dict[str, moderngl.Texture] = {}

    def resize(self, size: tuple[int, int]) -> None:
        if size == self.size:
            return
        self._release_targets()
        ctx = self.ctx
        t = {"diffuse": ctx.texture(size, 4, dtype="f4"),
             "normal": ctx.texture(size, 4, dtype="f2"),
             "tangent": ctx.texture(size, 4, dtype="f2"),
             "material": ctx.texture(size, 1, dtype="u4"),
             "surface": ctx.texture(size, 2, dtype="f2"),
             "depth": ctx.depth_texture(size)}
        for tex in t.values():
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)  # read with texelFetch; integer targets need it
            tex.repeat_x = tex.repeat_y = False
        t["depth"].compare_func = ""  # read raw depth values, not shadow comparisons
        self.targets = t
        self.fbo = ctx.framebuffer([t[COLOUR_TARGETS[k]] for k in range(len(COLOUR_TARGETS))], t["depth"])
        self.size = size

    def run(self, camera: ViewCamera, aspect: float, hidden=()) -> None:
        """Draw every object in view except those whose index is in `hidden` (a cube map leaves
        out its own object); `draws.record(REGION)` says afterwards what was drawn and skipped."""
        ctx = self.ctx
        self.fbo.use()
        self.fbo.viewport = (0, 0, *self.size)
        ctx.enable_only(moderngl.DEPTH_TEST)
        ctx.depth_func = "<"
        self.fbo.clear(depth=1.0)  # colour targets need no clear: depth 1 marks the empty pixels
        set_uniforms(self.program, eye=tuple(map(float, camera.eye)))
        self.draws.draw(self.program, camera.view_projection(aspect), region=self.REGION, hidden=hidden)

    def _release_targets(self) -> None:
        if self.fbo is not None:
            if self.ctx.fbo is self.fbo:  # deleting a bound framebuffer binds none (GL); say so
                self.ctx.fbo = None
            self.fbo.release()
        for tex in self.targets.values():
            tex.release()
        self.fbo, self.targets = None, {}

    def release(self) -> None:
        self._release_targets()
        self.program.release()
