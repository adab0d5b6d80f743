"""A bake directory on the GPU: one module per resource, composed here as `GpuScene`, which the renderer
and its passes use.

- meshes, one vertex and one index buffer, levels of detail: viewer/gpu_meshes.py (tangent frames:
  viewer/tangent_frames.py)
- the object table: viewer/gpu_objects.py
- materials, lobes and the lobes' sampling patterns: viewer/gpu_materials.py
- the materials' textures: viewer/gpu_textures.py
- light maps: viewer/gpu_lightmaps.py
- sky: viewer/gpu_sky.py
- cube maps of curved and transmissive objects and their bounding planes: viewer/cubemaps.py

Everything is read-only after upload but for what a material edit (`set_material`, `set_lobe_samples`)
and a re-bake (`replace_lightmaps`, `cubemaps.replace`) change; passes bind what they need.
"""
from __future__ import annotations

import moderngl

from glint.core.errors import GlintError
from glint.viewer.cubemaps import CubeMaps
from glint.viewer.gl import GL, software_renderer
from glint.viewer.gpu_lightmaps import GpuLightmaps
from glint.viewer.gpu_materials import (
    ALL_TEXTURE_KINDS,
    LOBE_KINDS,
    LOBE_MR,
    MATERIAL_FLAGS,
    PLANAR_PATTERNS,
    GpuMaterials,
)
from glint.viewer.gpu_meshes import GpuMeshes
from glint.viewer.gpu_objects import GpuObjectTable
from glint.viewer.gpu_sky import SKY_MODES, GpuSky
from glint.viewer.gpu_textures import GpuTextures


def shader_defines() -> dict:
    """The constants shaders/materials.glsl, sky.glsl and specular.glsl take as defines (their buffer
    bindings every program gets: viewer/gl_bindings.py)."""
    return {**MATERIAL_FLAGS, **LOBE_KINDS, **LOBE_MR, **SKY_MODES, "TEXTURE_KINDS": ALL_TEXTURE_KINDS}


class GpuScene:
    def __init__(self, ctx: moderngl.Context, bake, planar_pattern: str = "auto", lod: bool = False):
        """planar_pattern: the pattern of isotropic lobes on planar reflectors: "auto" (the
        multi-ring of section 4.5.3, viewer/lobe_patterns.py), or "ring" / "multi_ring" forced
        (for comparisons: `glint bench --methods patterns-ring`); anisotropic lobes keep their line.
        lod: also upload each object's levels of detail (viewer/lod.py) and their table
        (`lod_buffer`, viewer/gpu_meshes.py OBJECT_LOD_DTYPE), which viewer/draw_list.py then picks from."""
        if planar_pattern not in PLANAR_PATTERNS:
            raise GlintError(f"unknown planar pattern {planar_pattern!r}; use one of {', '.join(PLANAR_PATTERNS)}")
        self.planar_pattern = planar_pattern
        self.ctx = ctx
        self.software = software_renderer(ctx)
        gl = GL(ctx)
        manifest = bake.model
        count = len(manifest.materials)
        for entry in manifest.objects:
            if not 0 <= int(entry.material) < count:  # the shaders index the material buffer with it
                raise GlintError(f"{bake.path}: object '{entry.name}' has material {entry.material} "
                                 f"of {count}; run `glint bake --force`")
        self.lod = bool(lod)
        self.meshes = GpuMeshes(ctx, gl, bake, with_lod=self.lod)
        self.objects, self.triangles, self.bounds = self.meshes.objects, self.meshes.triangles, self.meshes.bounds
        self.lod_buffer = self.meshes.lod_buffer
        self.textures = GpuTextures(ctx, gl, self.software, bake)
        # material editing's boundary: dicts (the material schema piece will make edits typed)
        self.material_buffers = GpuMaterials(ctx, gl, [m.to_json() for m in manifest.materials], self.textures,
                                             planar_pattern)
        self.materials = self.material_buffers.materials  # the manifest entries as shown (set_material)
        self.scene_objects = GpuObjectTable(ctx, gl, self.objects, self.material_buffers.emissive())
        self.object_binding = self.scene_objects.binding
        self.lightmap_pages = GpuLightmaps(ctx, gl, bake)
        self.sky = GpuSky(ctx, gl, bake, self.textures.white)
        self.sky_mode, self.sky_map = self.sky.mode, self.sky.map
        self.cubemaps = CubeMaps(ctx, bake)

    # -- meshes and objects ------------------------------------------------------------------------
    def vertex_array(self, program: moderngl.Program) -> moderngl.VertexArray:
        return self.meshes.vertex_array(program)

    def draw_object(self, program: moderngl.Program, index: int) -> None:
        self.meshes.draw_object(program, index)

    @property
    def object_buffer(self) -> moderngl.Buffer:
        return self.scene_objects.buffer

    # -- materials ---------------------------------------------------------------------------------
    @property
    def material_table(self):
        return self.material_buffers.material_table

    @property
    def lobe_table(self):
        return self.material_buffers.lobe_table

    @property
    def lobe_count(self) -> int:
        return self.material_buffers.lobe_count

    @property
    def lobe_patterns(self) -> list[dict]:
        return self.material_buffers.lobe_patterns

    @property
    def material_count(self) -> int:
        return self.textures.material_count

    def material_textures(self, material: int) -> tuple:
        return self.textures.material_textures(material)

    def material_texture_kinds(self, material: int) -> int:
        """The MAT_*_TEXTURE flags of the textures `material` has (shaders/raster_surface.glsl TEXTURE_KINDS);
        fixed for the scene's life: an edit keeps a material's textures."""
        return int(self.material_table["info"][material, 0]) & ALL_TEXTURE_KINDS

    def set_material(self, index: int, material) -> None:
        """Show material `index` as the typed `material` (core/manifest.py Material) from the next frame
        on: kd, emission, lobes (their count may change), double_sided; its textures stay those of the
        bake. It is checked first (core/material_schema.py `checked_material`: GlintError for a NaN,
        infinite or out-of-range value, roughness raised to M_MIN), so no NaN reaches a frame.
        The object table's emitter column follows the new emission. The caller restarts what
        depends on the materials (Renderer.set_material: the G-buffer, the still-camera sum)."""
        self.material_buffers.set_material(index, material)
        self.scene_objects.upload(self.material_buffers.emissive())

    def set_lobe_samples(self, samples: int | None) -> None:
        self.material_buffers.set_lobe_samples(samples)

    def bind_materials(self) -> None:
        self.material_buffers.bind()

    def bind_specular(self) -> None:
        """Lobe patterns, cube maps and bounding planes, for the shading pass."""
        self.material_buffers.bind_patterns()
        self.cubemaps.bind_buffers()

    # -- light maps and sky ------------------------------------------------------------------------
    @property
    def lightmaps(self) -> moderngl.TextureArray:
        return self.lightmap_pages.texture

    @property
    def lightmap_dtype(self) -> str:
        return self.lightmap_pages.dtype

    def replace_lightmaps(self, front: list, back: list) -> None:
        self.lightmap_pages.replace(front, back)

    def sky_uniforms(self) -> dict:
        return self.sky.uniforms()

    def release(self) -> None:
        for part in (self.meshes, self.scene_objects, self.textures, self.lightmap_pages, self.sky,
                     self.material_buffers, self.cubemaps):
            part.release()
