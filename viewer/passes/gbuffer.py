"""G-buffer pass: rasterise the visible objects once into the targets the shading pass reads.

Targets and their encoding: shaders/gbuffer_layout.glsl. Objects whose bounding box
lies outside the view frustum are not drawn (viewer/camera.py `in_frustum`); nothing is culled by
facing, because back faces must show (black for single-sided materials, as in Mitsuba).
"""
from __future__ import annotations

import moderngl

from glint.viewer.camera import ViewCamera, gl_bytes, in_frustum
from glint.viewer.gl_bindings import (
    ANISOTROPY_TEXTURE_UNIT,
    EMISSION_TEXTURE_UNIT,
    GB_DIFFUSE_LOCATION,
    GB_MATERIAL_LOCATION,
    GB_NORMAL_LOCATION,
    GB_SURFACE_LOCATION,
    GB_TANGENT_LOCATION,
    KD_TEXTURE_UNIT,
    LIGHTMAP_UNIT,
    METALLIC_ROUGHNESS_TEXTURE_UNIT,
    NORMAL_TEXTURE_UNIT,
)
from glint.viewer.shader_source import raster_program, set_uniforms

# The colour targets by fragment-output location (gbuffer.frag, shaders/gbuffer_layout.glsl).
COLOUR_TARGETS = {GB_DIFFUSE_LOCATION: "diffuse", GB_NORMAL_LOCATION: "normal", GB_TANGENT_LOCATION: "tangent",
                  GB_MATERIAL_LOCATION: "material", GB_SURFACE_LOCATION: "surface"}


def draw_object(program, scene, obj) -> None:
    """One object with its material index, its base-colour, emissive, metallic-roughness, normal and
    anisotropy textures and its back-side light-map layer: the G-buffer's and the mirror passes'
    surface shaders (raster_surface.glsl) read them."""
    program["material_index"] = obj.material
    program["lightmap_back_layer"] = obj.back_layer
    scene.kd_texture(obj.material).use(KD_TEXTURE_UNIT)
    scene.emission_texture(obj.material).use(EMISSION_TEXTURE_UNIT)
    scene.metallic_roughness_texture(obj.material).use(METALLIC_ROUGHNESS_TEXTURE_UNIT)
    scene.normal_texture(obj.material).use(NORMAL_TEXTURE_UNIT)
    scene.anisotropy_texture(obj.material).use(ANISOTROPY_TEXTURE_UNIT)
    obj.vertex_array(program).render(moderngl.TRIANGLES)


class GBufferPass:
    name = "gbuffer"

    def __init__(self, ctx: moderngl.Context, scene, defines: dict):
        self.ctx = ctx
        self.scene = scene
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

    def run(self, camera: ViewCamera, aspect: float, hidden=()) -> dict:
        """Draw every object in view except those whose index is in `hidden` (a cube map leaves
        out its own object); returns what was drawn and skipped."""
        ctx, scene = self.ctx, self.scene
        view_proj = camera.view_projection(aspect)
        self.fbo.use()
        self.fbo.viewport = (0, 0, *self.size)
        ctx.enable_only(moderngl.DEPTH_TEST)
        ctx.depth_func = "<"
        self.fbo.clear(depth=1.0)  # colour targets need no clear: depth 1 marks the empty pixels
        self.program["view_proj"].write(gl_bytes(view_proj))
        set_uniforms(self.program, eye=tuple(map(float, camera.eye)))
        scene.bind_materials()
        scene.lightmaps.use(LIGHTMAP_UNIT)
        drawn = triangles = 0
        culled, empty, left_out = [], [], []
        hidden = set(hidden)
        for index, obj in enumerate(scene.objects):
            if index in hidden:
                left_out.append(obj.name)
                continue
            if not obj.triangles:
                empty.append(obj.name)
                continue
            if not in_frustum(obj.bounds, view_proj):
                culled.append(obj.name)
                continue
            draw_object(self.program, scene, obj)
            drawn += 1
            triangles += obj.triangles
        return {"objects_drawn": drawn, "triangles": triangles, "objects_culled": culled,
                "objects_empty": empty, "objects_hidden": left_out}

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
