"""Shading pass (compute): outgoing radiance per G-buffer pixel into an rgba32f image.

Per pixel (shaders/shading.comp): sky along the view ray where nothing was drawn;
else light-mapped diffuse + emission + the material's lobes through the per-pixel
hook of shaders/specular.glsl, which the specular issues fill; black for back faces
of single-sided materials.
"""
from __future__ import annotations

import moderngl

from viewer.camera import ViewCamera
from viewer.shader_source import compute_program, dispatch, set_uniforms

GBUFFER_UNITS = {"gb_diffuse": 0, "gb_normal": 1, "gb_tangent": 2, "gb_material": 3, "gb_depth": 4}
SKY_UNIT = 5
IMAGE_UNIT = 0


class ShadingPass:
    name = "shading"

    def __init__(self, ctx: moderngl.Context, scene, defines: dict):
        self.ctx = ctx
        self.scene = scene
        self.program = compute_program(ctx, "shading.comp", defines)
        set_uniforms(self.program, sky_map=SKY_UNIT, radiance_out=IMAGE_UNIT, **GBUFFER_UNITS)
        self.radiance: moderngl.Texture | None = None

    def resize(self, size: tuple[int, int]) -> None:
        if self.radiance is not None and self.radiance.size == size:
            return
        if self.radiance is not None:
            self.radiance.release()
        self.radiance = self.ctx.texture(size, 4, dtype="f4")
        self.radiance.filter = (moderngl.NEAREST, moderngl.NEAREST)

    def run(self, gbuffer: dict, camera: ViewCamera, aspect: float) -> moderngl.Texture:
        forward, right, up = camera.ray_basis(aspect)
        vec = lambda v: tuple(map(float, v))  # noqa: E731
        set_uniforms(self.program, eye=vec(camera.eye), cam_forward=vec(forward), cam_right=vec(right),
                     cam_up=vec(up), znear=camera.znear, zfar=camera.zfar, **self.scene.sky_uniforms())
        for name, unit in GBUFFER_UNITS.items():
            gbuffer[name[3:]].use(unit)
        self.scene.sky_map.use(SKY_UNIT)
        self.scene.bind_materials()
        self.radiance.bind_to_image(IMAGE_UNIT, read=False, write=True)
        dispatch(self.program, *self.radiance.size)
        self.ctx.memory_barrier(moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT)
        return self.radiance

    def release(self) -> None:
        if self.radiance is not None:
            self.radiance.release()
        self.program.release()
