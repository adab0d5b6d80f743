"""A bake directory on the GPU: meshes, light maps, materials, textures and sky.

Everything here is read-only after upload; passes bind what they need.

- Meshes: every object's vertices in one vertex buffer, interleaved as `VERTEX_DTYPE`,
  and its triangles in one index buffer of global vertex indices (an object is a range of
  it: `GpuObject.first_index`, 3 x `triangles`); one vertex array per program on demand
  (`vertex_array`). Per object a row of the object table (`SCENE_OBJECT_DTYPE`,
  shaders/scene_objects.glsl): world box, material, back-side light-map layer, index range,
  which the raster passes read by the object id of the vertex, so one multi-draw draws every
  object (viewer/draw_list.py).
  Tangents (`surface_tangents`): the file's TANGENT where the bake has it, else
  MikkTSpace's from the texture coordinates (`tangents`; vertices equal in position,
  normal and uv share one, so light-map seams do not split them, and a vertex whose
  triangles differ in handedness is split in two). Where there are none (no texture
  coordinates, or degenerate ones) the tangent is a fixed world axis projected onto the tangent plane
  (`axis_tangents`: world X, or world Z where the normal is within ~25 degrees
  of X), so anisotropic lobes keep one orientation across such objects. Each
  vertex also carries its object's index, which the G-buffer stores beside the
  material (an object picks its cube map).
- Lobe sampling patterns (section 4.4.3): the (xi1, xi2) positions of every
  lobe's regular patterns (viewer/lobe_patterns.py) in one storage buffer, and
  per lobe (offset, count) in another (`PATTERN_DTYPE`): one pattern for cube-map
  look-ups and one for mirror-buffer look-ups of planar reflectors (section
  4.5.3); the sample count is chosen per lobe from its width, or set for all
  lobes by `set_lobe_samples`.
- Cube maps of curved and transmissive objects and their bounding planes:
  viewer/cubemaps.py.
- Light maps: one texture array, a layer per page, RGBA16F, or RGBA32F when a
  value does not fit in half float (very bright emitters must not become Inf);
  GL_LINEAR and clamp to edge, which is `glint.core.image_io.sample_bilinear`. Row 0 of a
  page (v = 0) is the first row uploaded, i.e. GL's t = 0: no flip anywhere. The back-side
  pages of two-sided objects (core/bake_dir.py `lightmaps_back`) follow the front pages in the
  same array: an object with a back side has `back_layer` = the number of front pages, which a
  back face adds to its page (shaders/raster_surface.glsl); 0 for the others.
- Materials and lobes: two shader storage buffers (`MATERIAL_DTYPE`,
  `LOBE_DTYPE`, std430; GLSL side in shaders/materials.glsl).
- Metallic-roughness textures (G roughness multiplier, B metallic): uploaded like the base colour's,
  with a per-lobe LOBE_MR_* row (`LOBE_MR_BINDING`) saying how the texel changes each lobe.
- Base-colour textures: one 2-D texture per textured material (sizes differ, so
  no array), mip-mapped, repeating (the glTF default sampler). A draw binds its
  material's texture; the others bind a 1x1 white one. A is the base colour alpha for
  MASK and BLEND materials (the raster passes' coverage test), 1 for the others.
- Sky: none, a constant radiance, or the equirectangular sky.exr (times the
  radiance as a scale), repeating in u and clamped in v as bake/lights.py samples it.
"""
from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from glint.core.constants import HALF_MAX
from glint.core.errors import GlintError
from glint.core.image_io import read_image
from glint.viewer import lod
from glint.viewer.cubemaps import CubeMaps
from glint.viewer.gl import GL, check_texture_size, software_renderer
from glint.viewer.gl_bindings import (
    LOBE_BINDING,
    LOBE_MR_BINDING,
    LOBE_PATTERN_BINDING,
    MATERIAL_BINDING,
    PATTERN_BINDING,
    SCENE_OBJECT_BINDING,
)
from glint.viewer.lobe_patterns import choose_pattern, pattern_xi, samples_for_lobe
from glint.viewer.lod import LOD_LEVELS
from glint.viewer.material_edits import checked_material


def _sampler_flags(sampler: dict) -> int:
    """MAT_KD_* flags of a manifest material's `kd_sampler` (bake/pipeline.py); {} is REPEAT, LINEAR."""
    flags = 0
    for key, axis in (("wrap_s", "S"), ("wrap_t", "T")):
        mode = sampler.get(key, "REPEAT")
        if mode == "CLAMP_TO_EDGE":
            flags |= MATERIAL_FLAGS[f"MAT_KD_CLAMP_{axis}"]
        elif mode == "MIRRORED_REPEAT":
            flags |= MATERIAL_FLAGS[f"MAT_KD_MIRROR_{axis}"]
    if sampler.get("mag_filter") == "NEAREST":
        flags |= MATERIAL_FLAGS["MAT_KD_NEAREST"]
    return flags


MATERIAL_FLAGS = {
    "MAT_TWO_SIDED": 1,    # glTF doubleSided, or thin transmissive (the bake treats both as two-sided)
    "MAT_EMISSIVE": 2,
    "MAT_KD_TEXTURE": 4,
    "MAT_SPECULAR": 8,     # has reflection or transmission lobes: the shading pass calls the lobe hook
    "MAT_TRANSMISSIVE": 16,
    "MAT_ALPHA_MASK": 32,   # glTF alphaMode MASK: fragments with alpha < cutoff are discarded
    "MAT_ALPHA_BLEND": 64,  # glTF alphaMode BLEND: dithered coverage (shaders/raster_surface.glsl)
    # The base colour's glTF sampler where it is not REPEAT / LINEAR (shaders/raster_surface.glsl)
    "MAT_KD_CLAMP_S": 128,
    "MAT_KD_CLAMP_T": 256,
    "MAT_KD_MIRROR_S": 512,
    "MAT_KD_MIRROR_T": 1024,
    "MAT_KD_NEAREST": 2048,
    # glTF emissiveTexture: the raster pass adds emission x texture to the G-buffer's diffuse
    # radiance and the shading pass adds no constant emission (shaders/raster_surface.glsl)
    "MAT_EMISSION_TEXTURE": 4096,
    # glTF metallicRoughnessTexture: the raster passes write the texel's roughness multiplier and
    # metallic to the G-buffer (GB_SURFACE) and scale kd by 1 - metallic (shaders/raster_surface.glsl)
    "MAT_MR_TEXTURE": 8192,
    # glTF normalTexture: the raster passes perturb the shading normal (shaders/raster_surface.glsl)
    "MAT_NORMAL_TEXTURE": 16384,
    # KHR_materials_anisotropy's texture: direction per texel, and the strength factor the G-buffer
    # tangent's length carries to the lobes (shaders/gbuffer_layout.glsl, specular.glsl)
    "MAT_ANISOTROPY_TEXTURE": 32768,
}
LOBE_KINDS = {"LOBE_REFLECT": 0, "LOBE_TRANSMIT": 1}
# How a metallic-roughness texture changes a lobe (core/scene.py Lobe.mr; specular.glsl lobe_at_pixel)
LOBE_MR = {"LOBE_MR_NONE": 0, "LOBE_MR_DIELECTRIC": 1, "LOBE_MR_METAL": 2}
SKY_MODES = {"SKY_NONE": 0, "SKY_CONSTANT": 1, "SKY_MAP": 2}

MATERIAL_DTYPE = np.dtype([("kd", "<f4", 4), ("emission", "<f4", 4), ("info", "<i4", 4), ("surface", "<f4", 4)])
LOBE_DTYPE = np.dtype([("ks", "<f4", 4), ("shape", "<f4", 4)])
# Per lobe: first pattern sample, sample count, pattern kind (PATTERN_KINDS), row of the lobe's
# pattern for planar reflectors (ivec4, std430). Rows 0 .. L-1 are the lobes' patterns for cube
# maps, rows L .. 2L-1 those for mirror buffers (section 4.5.3: multi-ring for isotropic lobes).
PATTERN_DTYPE = np.dtype([("info", "<i4", 4)])
PATTERN_KINDS = {"ring": 0, "line_x": 1, "line_y": 2, "multi_ring": 3}
PLANAR_PATTERNS = ("auto", "ring", "multi_ring")  # GpuScene(planar_pattern=...)
VERTEX_DTYPE = np.dtype([("position", "<f4", 3), ("normal", "<f4", 3), ("tangent", "<f4", 4),
                         ("uv", "<f4", 2), ("lm_uv", "<f4", 2), ("lm_page", "<i4"), ("object", "<i4"),
                         ("color", "<f4", 3)])
VERTEX_FORMAT = "3f 3f 4f 2f 2f 1i 1i 3f"
# Per object (std430; shaders/scene_objects.glsl): world box (lo, hi; lo.w 1 for emitters) and (material,
# back-side light-map layer offset, first index, index count).
SCENE_OBJECT_DTYPE = np.dtype([("lo", "<f4", 4), ("hi", "<f4", 4), ("info", "<i4", 4)])
# Per object its levels of detail, finest first (viewer/lod.py; std430, shaders/cull.comp): first
# index in the scene's index buffer and index count of each; count 0 = no such level.
OBJECT_LOD_DTYPE = np.dtype([("first", "<i4", LOD_LEVELS), ("count", "<i4", LOD_LEVELS)])
VERTEX_ATTRIBUTES = ("in_position", "in_normal", "in_tangent", "in_uv", "in_lm_uv", "in_lm_page", "in_object",
                     "in_color")


def shader_defines() -> dict:
    """The constants shaders/materials.glsl, sky.glsl and specular.glsl take as defines (their buffer
    bindings every program gets: viewer/gl_bindings.py)."""
    return {**MATERIAL_FLAGS, **LOBE_KINDS, **LOBE_MR, **SKY_MODES}


def _clean(a, lo=0.0, hi=None) -> np.ndarray:
    """Non-finite -> 0, then clamped to [lo, hi] (what bake/lights.py and irradiance.py do). float32
    input stays float32 (texture images: half the memory and time), anything else is float64."""
    a = np.asarray(a)
    a = np.nan_to_num(a if a.dtype == np.float32 else a.astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    return a if lo is None and hi is None else np.clip(a, lo, hi)


@dataclass
class GpuObject:
    name: str
    material: int
    role: str
    triangles: int
    bounds: np.ndarray  # (2, 3) world-space box
    back_layer: int  # light-map layers a back face adds to its page: 0 = no back-side light map
    first_index: int = 0  # its first index in the scene's index buffer (3 per triangle)


class GpuScene:
    def __init__(self, ctx: moderngl.Context, bake, planar_pattern: str = "auto", lod: bool = False):
        """planar_pattern: the pattern of isotropic lobes on planar reflectors: "auto" (the
        multi-ring of section 4.5.3, viewer/lobe_patterns.py), or "ring" / "multi_ring" forced
        (for comparisons: `glint bench --methods patterns-ring`); anisotropic lobes keep their line.
        lod: also upload each object's levels of detail (viewer/lod.py) and their table
        (`lod_buffer`, OBJECT_LOD_DTYPE), which viewer/draw_list.py then picks from."""
        if planar_pattern not in PLANAR_PATTERNS:
            raise GlintError(f"unknown planar pattern {planar_pattern!r}; use one of {', '.join(PLANAR_PATTERNS)}")
        self.planar_pattern = planar_pattern
        self.ctx = ctx
        self.software = software_renderer(ctx)
        self._gl = GL(ctx)
        manifest = bake.manifest
        count = len(manifest["materials"])
        for entry in manifest["objects"]:
            if not 0 <= int(entry["material"]) < count:  # the shaders index the material buffer with it
                raise GlintError(f"{bake.path}: object '{entry['name']}' has material {entry['material']} "
                                 f"of {count}; run `glint bake --force`")
        self.lod = bool(lod)
        self._meshes(bake)
        drawn = [o.bounds for o in self.objects if o.triangles]
        self.bounds = (np.stack([np.min([b[0] for b in drawn], axis=0), np.max([b[1] for b in drawn], axis=0)])
                       if drawn else np.zeros((2, 3)))
        self.white = ctx.texture((1, 1), 4, np.ones(4, np.float32).tobytes(), dtype="f4")
        self._materials(bake)
        self._upload_objects()
        self._lightmaps(bake)
        self._sky(bake)
        self.cubemaps = CubeMaps(ctx, bake)

    # -- meshes ----------------------------------------------------------------------------------
    def _meshes(self, bake) -> None:
        """Every object's vertices into one vertex buffer and its triangles into one index buffer
        (global vertex indices), and the object table (`SCENE_OBJECT_DTYPE`) the raster passes
        and the culling read (viewer/draw_list.py)."""
        manifest = bake.manifest
        front_pages = len(manifest.get("lightmaps") or [])
        # The tangent frame serves the lobes only (their anisotropy and the normal map's shading
        # normal; the diffuse part is the light map's): a scene without lobes (the bake's diffuse
        # cube-map renders) skips MikkTSpace.
        frames = any(m.get("lobes") for m in manifest["materials"])
        parts = [self._object(i, entry, mesh, front_pages if bake.has_back(i) else 0, frames)
                 for i, (entry, mesh) in enumerate(zip(manifest["objects"], bake.meshes))]
        self.objects = [obj for obj, _, _ in parts]
        self.triangles = sum(o.triangles for o in self.objects)
        table = np.zeros(max(len(parts), 1), SCENE_OBJECT_DTYPE)
        vertices, indices = [], []
        first_vertex = first_index = 0
        for k, (obj, v, idx) in enumerate(parts):
            obj.first_index = first_index
            table[k]["lo"][:3], table[k]["hi"][:3] = obj.bounds
            table[k]["info"] = (obj.material, obj.back_layer, first_index, 3 * obj.triangles)
            vertices.append(v)
            indices.append(idx.reshape(-1) + np.uint32(first_vertex))
            first_vertex += len(v)
            first_index += 3 * obj.triangles
        self.object_table = table  # uploaded by _upload_objects once the materials say which emit
        self.lod_table = None
        if self.lod:  # the levels' vertices and triangles follow every object's own
            self.lod_table = np.zeros(max(len(parts), 1), OBJECT_LOD_DTYPE)
            for k, (obj, v, idx) in enumerate(parts):
                for level, (source, positions, tris) in enumerate(lod.levels(v["position"], idx)):
                    self.lod_table[k]["first"][level], self.lod_table[k]["count"][level] = first_index, tris.size
                    moved = v[source]
                    moved["position"] = positions
                    vertices.append(moved)
                    indices.append(tris.reshape(-1) + np.uint32(first_vertex))
                    first_vertex += len(moved)
                    first_index += tris.size
        what = f"the meshes ({len(parts)} objects, {self.triangles} triangles)"
        with self._gl.checked(f"upload {what}"):
            v = np.concatenate(vertices) if vertices else np.zeros(1, VERTEX_DTYPE)
            i = np.concatenate(indices) if indices and first_index else np.zeros(3, np.uint32)
            self.vertex_buffer = self.ctx.buffer(v.tobytes())
            self.index_buffer = self.ctx.buffer(i.astype(np.uint32).tobytes())
            self.lod_buffer = None if self.lod_table is None else self.ctx.buffer(self.lod_table.tobytes())
        self.object_binding = SCENE_OBJECT_BINDING
        self._vaos: dict = {}

    def _upload_objects(self) -> None:
        """The object table, lo.w marking the objects whose material emits (MAT_EMISSIVE)."""
        table = self.object_table
        if self.objects:
            flags = self.material_table["info"][table["info"][:len(self.objects), 0], 0]
            table["lo"][:len(self.objects), 3] = (flags & MATERIAL_FLAGS["MAT_EMISSIVE"]) != 0
        with self._gl.checked(f"upload the object table ({len(self.objects)} objects)"):
            self.object_buffer = self.ctx.buffer(table.tobytes())

    def vertex_array(self, program: moderngl.Program) -> moderngl.VertexArray:
        """The scene's vertex array for `program` (made once; attributes it lacks are skipped)."""
        key = program.glo
        if key not in self._vaos:
            self._vaos[key] = self.ctx.vertex_array(
                program, [(self.vertex_buffer, VERTEX_FORMAT, *VERTEX_ATTRIBUTES)], index_buffer=self.index_buffer,
                index_element_size=4, skip_errors=True)
        return self._vaos[key]

    def draw_object(self, program: moderngl.Program, index: int) -> None:
        """One object alone (the occlusion queries of planar reflectors): its range of the index buffer."""
        obj = self.objects[index]
        if obj.triangles:
            self.vertex_array(program).render(moderngl.TRIANGLES, vertices=3 * obj.triangles, first=obj.first_index)

    def _object(self, index: int, entry: dict, mesh: dict, back_layer: int, frames: bool = True) -> tuple:
        """(GpuObject, its vertices as VERTEX_DTYPE, its (M, 3) local indices); frames: False leaves
        the tangents 0 (no tangent frame: shaders/raster_surface.glsl)."""
        indices = np.asarray(mesh.get("indices", np.zeros((0, 3))), np.uint32).reshape(-1, 3)
        positions = np.asarray(mesh["positions"], np.float64).reshape(-1, 3)
        n = len(positions)
        if len(indices) and (not np.all(np.isfinite(positions)) or int(indices.max()) >= n):
            raise GlintError(f"bake: object '{entry['name']}' has invalid positions or indices; run "
                             "`glint bake --force`")
        normals = _clean(mesh["normals"], None).reshape(-1, 3)  # zero-length is guarded in GLSL
        uvs = mesh.get("uvs")
        uvs = None if uvs is None else _clean(uvs, None).reshape(-1, 2)
        supplied = mesh.get("tangents")  # glTF TANGENT
        # Tangents may split vertices (MikkTSpace's handedness): the other attributes follow `source`.
        if frames:
            source, indices, frame = surface_tangents(positions, normals, uvs, indices,
                                                      None if supplied is None else _clean(supplied, None).reshape(-1, 4))
        else:
            source, frame = np.arange(n), 0.0
        indices = indices.astype(np.uint32)
        positions = positions[source]
        v = np.zeros(len(source), VERTEX_DTYPE)
        v["position"] = positions
        v["normal"] = normals[source]
        v["tangent"] = frame
        if uvs is not None:
            v["uv"] = uvs[source]
        v["object"] = index
        colors = mesh.get("colors")  # glTF COLOR_0; -1 without (shaders/raster_surface.glsl)
        v["color"] = -1.0 if colors is None else np.clip(_clean(colors), 0.0, 1.0).reshape(-1, 3)[source]
        v["lm_uv"] = _clean(mesh["lm_uv"], None).reshape(-1, 2)[source]
        v["lm_page"] = np.asarray(mesh["lm_page"], np.int32).reshape(-1)[source]
        bounds = (np.stack([positions[indices.ravel()].min(axis=0), positions[indices.ravel()].max(axis=0)])
                  if len(indices) else np.zeros((2, 3)))
        obj = GpuObject(entry["name"], int(entry["material"]), entry.get("role", "diffuse"), len(indices), bounds,
                        back_layer)
        return obj, (v if len(indices) else v[:0]), indices

    # -- materials -------------------------------------------------------------------------------
    def _materials(self, bake) -> None:
        """Every material's textures (kept per material), then its rows (`_material_rows`)."""
        entries = bake.manifest["materials"]
        self.materials = [dict(m) for m in entries]  # as shown; GpuScene.set_material replaces one
        self._surface = np.zeros(max(len(entries), 1), MATERIAL_DTYPE)["surface"]
        self._texture_flags: list[int] = []
        self.kd_textures: list[moderngl.Texture | None] = []
        self.emission_textures: list[moderngl.Texture | None] = []
        self.metallic_roughness_textures: list[moderngl.Texture | None] = []
        self.normal_textures: list[moderngl.Texture | None] = []
        self.anisotropy_textures: list[moderngl.Texture | None] = []
        for i, m in enumerate(entries):
            flags = 0
            mode = m.get("alpha_mode", "OPAQUE")
            texture = None
            if m.get("kd_texture"):
                image = read_image(bake.path / m["kd_texture"])
                # the base colour alpha only where the coverage reads it (shaders/materials.glsl)
                alpha = image[..., 3:4] if mode in ("MASK", "BLEND") and image.shape[-1] >= 4 else None
                texture = self._texture(np.clip(_clean(image[..., :3]), 0.0, 1.0), f"the base-colour texture of "
                                        f"material '{m['name']}'", mipmaps=True,
                                        alpha=None if alpha is None else np.clip(_clean(alpha), 0.0, 1.0))
                flags |= MATERIAL_FLAGS["MAT_KD_TEXTURE"] | _sampler_flags(m.get("kd_sampler") or {})
            self.kd_textures.append(texture)
            emission_texture = None
            if m.get("emission_texture") and np.any(_clean(m.get("emission", (0, 0, 0))) > 0):
                # linear RGB >= 0 (glTF 3.9.3: it multiplies emissiveFactor); read with the
                # base colour's uv and sampler flags (the loader's choice, bake/gltf_loader.py)
                image = read_image(bake.path / m["emission_texture"])
                emission_texture = self._texture(np.clip(_clean(image[..., :3]), 0.0, HALF_MAX),
                                                 f"the emissive texture of material '{m['name']}'", mipmaps=True)
                flags |= MATERIAL_FLAGS["MAT_EMISSION_TEXTURE"] | _sampler_flags(m.get("kd_sampler") or {})
            self.emission_textures.append(emission_texture)
            row = np.zeros((), MATERIAL_DTYPE)
            flags |= self._surface_detail(m, row, bake.path)
            self._surface[i] = row["surface"]
            self._texture_flags.append(flags)
        self.material_buffer = self.lobe_buffer = self.lobe_mr_buffer = None
        self.pattern_buffer = self.lobe_pattern_buffer = None
        self.lobe_samples: int | None = None
        self._upload_materials()

    def _material_rows(self, i: int, m: dict) -> tuple[np.ndarray, list, list]:
        """Material i's row of MATERIAL_DTYPE (its lobes' first row left 0), its LOBE_DTYPE rows and
        their LOBE_MR values, from its manifest entry and the textures loaded for it."""
        mat = np.zeros((), MATERIAL_DTYPE)
        flags = self._texture_flags[i]
        lobes = m.get("lobes") or []
        kinds = {lobe.get("kind", "reflect") for lobe in lobes}
        if m.get("double_sided") or "transmit" in kinds:
            flags |= MATERIAL_FLAGS["MAT_TWO_SIDED"]
        if "transmit" in kinds:
            flags |= MATERIAL_FLAGS["MAT_TRANSMISSIVE"]
        if lobes:
            flags |= MATERIAL_FLAGS["MAT_SPECULAR"]
        emission = _clean(m.get("emission", (0, 0, 0)))
        if np.any(emission > 0):
            flags |= MATERIAL_FLAGS["MAT_EMISSIVE"]
        mode = m.get("alpha_mode", "OPAQUE")
        if mode in ("MASK", "BLEND"):
            flags |= MATERIAL_FLAGS[f"MAT_ALPHA_{mode}"]
            mat["kd"][3] = float(np.clip(_clean(m.get("alpha", 1.0)), 0.0, 1.0))
            mat["emission"][3] = float(_clean(m.get("alpha_cutoff", 0.5)))
        mat["kd"][:3] = np.clip(_clean(m.get("kd", (0.8, 0.8, 0.8))), 0.0, 1.0)
        mat["emission"][:3] = emission
        rotation = float(_clean(m.get("anisotropy_rotation", 0.0), None))  # editable: the panel's direction
        mat["surface"] = (self._surface[i][0], np.cos(rotation), np.sin(rotation), 0.0)
        mat["info"] = (flags, i if self.kd_textures[i] is not None else -1, 0, len(lobes))
        rows, lobe_mr = [], []
        textured = self.metallic_roughness_textures[i] is not None
        for lobe in lobes:
            row = np.zeros((), LOBE_DTYPE)
            row["ks"][:3] = np.clip(_clean(lobe.get("ks", (1, 1, 1))), 0.0, 1.0)
            row["ks"][3] = LOBE_KINDS["LOBE_TRANSMIT" if lobe.get("kind") == "transmit" else "LOBE_REFLECT"]
            row["shape"] = (lobe.get("mx", 0.1), lobe.get("my", 0.1), lobe.get("r0", 0.04), lobe.get("alpha", 0.0))
            rows.append(row)
            lobe_mr.append(LOBE_MR[f"LOBE_MR_{lobe.get('mr') or 'none'}".upper()] if textured else 0)
        return mat, rows, lobe_mr

    def _upload_materials(self) -> None:
        """The material, lobe and LOBE_MR tables of `self.materials` and the lobes' sampling patterns
        (`lobe_samples`), (re)uploaded whole: the lobe rows of a material follow those before it, so
        a material whose lobe count changes moves every later one."""
        mats = np.zeros(max(len(self.materials), 1), MATERIAL_DTYPE)
        lobe_rows, lobe_mr = [], []
        for i, m in enumerate(self.materials):
            row, rows, mr = self._material_rows(i, m)
            row["info"][2] = len(lobe_rows)
            mats[i] = row
            lobe_rows += rows
            lobe_mr += mr
        self.material_table = mats
        self.lobe_table = np.array(lobe_rows, LOBE_DTYPE) if lobe_rows else np.zeros(1, LOBE_DTYPE)
        self.lobe_count = len(lobe_rows)
        for buf in (self.material_buffer, self.lobe_buffer, self.lobe_mr_buffer):
            if buf is not None:
                buf.release()
        with self._gl.checked(f"upload the materials ({len(self.materials)}, {self.lobe_count} lobes)"):
            self.material_buffer = self.ctx.buffer(mats.tobytes())
            self.lobe_buffer = self.ctx.buffer(self.lobe_table.tobytes())
            self.lobe_mr_buffer = self.ctx.buffer(np.array(lobe_mr or [0], np.int32).tobytes())
        self.set_lobe_samples(self.lobe_samples)

    def set_material(self, index: int, entry: dict) -> None:
        """Show material `index` as the manifest entry `entry` from the next frame on: kd, emission,
        lobes (their count may change), double_sided; its textures stay those of the bake.
        The entry is checked first (viewer/material_edits.py `checked_material`: GlintError for a
        NaN, infinite or negative value, roughness raised to M_MIN), so no NaN reaches a frame.
        The object table's emitter column follows the new emission. The caller restarts what
        depends on the materials (Renderer.set_material: the G-buffer, the still-camera sum)."""
        if not 0 <= index < len(self.materials):
            raise GlintError(f"no material {index} (the scene has {len(self.materials)})")
        self.materials[index] = checked_material({**entry, "name": entry.get("name", self.materials[index]["name"])})
        self._upload_materials()
        self.object_buffer.release()
        self._upload_objects()  # its emitter column (viewer/draw_list.py never culls emitters as too small)

    def _surface_detail(self, m: dict, row, path) -> int:
        """A material's metallic-roughness texture (G roughness multiplier, B metallic M'), normal map
        and anisotropy direction (manifest `metallic_roughness_texture`, `normal_texture`,
        `normal_scale`, `anisotropy_rotation`, `anisotropy_texture`): their textures (linear, in 0..1,
        read with the base colour's uv and sampler flags, bake/gltf_loader.py) into
        self.<kind>_textures, `row["surface"]` = (normal scale, cos, sin of the rotation, 0);
        -> the MAT_* flags they set."""
        flags = 0
        for kind, flag in (("metallic_roughness", "MAT_MR_TEXTURE"), ("normal", "MAT_NORMAL_TEXTURE"),
                           ("anisotropy", "MAT_ANISOTROPY_TEXTURE")):
            texture = None
            if m.get(f"{kind}_texture"):
                image = np.clip(_clean(read_image(path / m[f"{kind}_texture"])[..., :3]), 0.0, 1.0)
                what = kind.replace("_", "-")
                texture = self._texture(image, f"the {what} texture of material '{m['name']}'", mipmaps=True)
                flags |= MATERIAL_FLAGS[flag] | _sampler_flags(m.get("kd_sampler") or {})
            getattr(self, f"{kind}_textures").append(texture)
        rotation = float(_clean(m.get("anisotropy_rotation", 0.0), None))
        row["surface"] = (float(_clean(m.get("normal_scale", 1.0), None)), np.cos(rotation), np.sin(rotation), 0.0)
        return flags

    def set_lobe_samples(self, samples: int | None) -> None:
        """Build every lobe's regular sampling pattern (section 4.4.3): the pattern kind from the
        lobe's anisotropy, and `samples` positions per lobe, or the automatic count from its width
        (viewer/lobe_patterns.py) when None."""
        if samples is not None and not (isinstance(samples, (int, np.integer)) and samples >= 1):
            raise GlintError(f"samples per lobe must be a whole number of at least 1 (got {samples!r})")
        self.lobe_samples = samples  # kept for the patterns of edited materials (set_material)
        count = self.lobe_count
        table = np.zeros(max(2 * count, 1), PATTERN_DTYPE)
        points, self.lobe_patterns = [], []
        first = 0
        for k in range(count):
            mx, my = (float(x) for x in self.lobe_table[k]["shape"][:2])
            entry = {}
            for row, planar in ((k, False), (count + k, True)):
                kind = choose_pattern(mx, my, planar)
                if planar and kind == "multi_ring" and self.planar_pattern != "auto":
                    kind = self.planar_pattern  # forced, isotropic lobes only
                n = int(samples) if samples is not None else int(samples_for_lobe(mx, my, planar))
                xi = np.asarray(pattern_xi(kind, n), np.float32).reshape(-1, 2)
                table[row]["info"] = (first, len(xi), PATTERN_KINDS.get(kind, -1), count + k)
                points.append(xi)
                entry.update({"planar_pattern": kind, "planar_samples": len(xi)} if planar else
                             {"pattern": kind, "samples": len(xi)})
                first += len(xi)
            self.lobe_patterns.append(entry)
        xi = np.concatenate(points) if points else np.zeros((1, 2), np.float32)
        for buf in (self.pattern_buffer, self.lobe_pattern_buffer):
            if buf is not None:
                buf.release()
        with self._gl.checked(f"upload the lobes' sampling patterns ({len(xi)} samples)"):
            self.pattern_buffer = self.ctx.buffer(np.ascontiguousarray(xi, np.float32).tobytes())
            self.lobe_pattern_buffer = self.ctx.buffer(table.tobytes())

    def bind_materials(self) -> None:
        self.material_buffer.bind_to_storage_buffer(MATERIAL_BINDING)
        self.lobe_buffer.bind_to_storage_buffer(LOBE_BINDING)
        self.lobe_mr_buffer.bind_to_storage_buffer(LOBE_MR_BINDING)

    def bind_specular(self) -> None:
        """Lobe patterns, cube maps and bounding planes, for the shading pass."""
        self.pattern_buffer.bind_to_storage_buffer(PATTERN_BINDING)
        self.lobe_pattern_buffer.bind_to_storage_buffer(LOBE_PATTERN_BINDING)
        self.cubemaps.bind_buffers()

    @property
    def material_count(self) -> int:
        return len(self.kd_textures)

    def material_textures(self, material: int) -> tuple:
        """The textures a draw of `material` binds, in viewer/draw_list.py TEXTURE_UNITS order (base
        colour, emission, metallic-roughness, normal, anisotropy; the 1x1 white where it has none)."""
        return (self.kd_texture(material), self.emission_texture(material), self.metallic_roughness_texture(material),
                self.normal_texture(material), self.anisotropy_texture(material))

    def kd_texture(self, material: int) -> moderngl.Texture:
        t = self.kd_textures[material] if 0 <= material < len(self.kd_textures) else None
        return t if t is not None else self.white

    def emission_texture(self, material: int) -> moderngl.Texture:
        t = self.emission_textures[material] if 0 <= material < len(self.emission_textures) else None
        return t if t is not None else self.white

    def metallic_roughness_texture(self, material: int) -> moderngl.Texture:
        return self._material_texture(self.metallic_roughness_textures, material)

    def normal_texture(self, material: int) -> moderngl.Texture:
        return self._material_texture(self.normal_textures, material)

    def anisotropy_texture(self, material: int) -> moderngl.Texture:
        return self._material_texture(self.anisotropy_textures, material)

    def _material_texture(self, textures: list, material: int) -> moderngl.Texture:
        """The material's texture of one kind, or the 1x1 white one where it has none."""
        t = textures[material] if 0 <= material < len(textures) else None
        return t if t is not None else self.white

    def _texture(self, rgb: np.ndarray, what: str, *, mipmaps: bool, alpha: np.ndarray | None = None) -> moderngl.Texture:
        h, w = rgb.shape[:2]
        check_texture_size(self.ctx, w, h, what, fix="scale it down in the modelling tool and export again")
        rgba = np.concatenate([rgb, np.ones((h, w, 1), rgb.dtype) if alpha is None else alpha.reshape(h, w, 1)], axis=-1)
        with self._gl.checked(f"upload {what}"):
            tex = self.ctx.texture((w, h), 4, rgba.astype(np.float16).tobytes(), dtype="f2")
            if mipmaps:
                tex.build_mipmaps()
        tex.repeat_x = tex.repeat_y = True
        if mipmaps:
            tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            if not self.software:  # llvmpipe's anisotropic filter blurs magnified textures (Mesa 22.3)
                tex.anisotropy = min(8.0, self.ctx.max_anisotropy)
        else:
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        return tex

    # -- light maps ------------------------------------------------------------------------------
    def _lightmaps(self, bake) -> None:
        names = bake.manifest.get("lightmaps") or []
        pages = [bake.lightmap(k) for k in range(len(names))]
        if names:  # the back sides' pages, layers len(names) on (GpuObject.back_layer)
            pages += [bake.lightmap(k, back=True) for k in range(len(bake.back_pages))]
        if not pages:
            pages = [np.zeros((1, 1, 4))]
        data, (w, h) = self._lightmap_stack(pages, f"{bake.path}: light-map pages", "run `glint bake --force`")
        self.lightmap_dtype = "f2" if data.dtype == np.float16 else "f4"
        what = f"the light maps ({len(pages)} pages)"
        check_texture_size(self.ctx, w, h, what, layers=len(pages),
                           fix="bake with a lower --texels-per-metre or [bake] max_page_size")
        with self._gl.checked(f"upload {what}"):
            self.lightmaps = self.ctx.texture_array((w, h, len(pages)), 4, data.tobytes(), dtype=self.lightmap_dtype)
        self.lightmaps.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.lightmaps.repeat_x = self.lightmaps.repeat_y = False  # clamp to edge

    @staticmethod
    def _lightmap_stack(pages: list[np.ndarray], what: str, fix: str) -> tuple[np.ndarray, tuple[int, int]]:
        """Pages (H, W, 3 or 4) -> one (layers, H, W, 4) array to upload, non-finite values 0 and
        negatives 0 (`_clean`), in float16 where every value fits (|v| <= HALF_MAX), else float32."""
        shapes = {np.shape(p)[:2] for p in pages}
        if len(shapes) != 1:
            raise GlintError(f"{what} differ in size ({sorted(shapes)}); {fix}")
        h, w = shapes.pop()
        stack = np.zeros((len(pages), h, w, 4), np.float32)
        for k, p in enumerate(pages):
            p = _clean(p)
            stack[k, :, :, :p.shape[2]] = p[..., :4]
        fits = stack.max(initial=0.0) <= HALF_MAX
        return stack.astype(np.float16) if fits else stack, (w, h)

    def replace_lightmaps(self, front: list[np.ndarray], back: list[np.ndarray]) -> None:
        """New light maps for the same atlas (a re-bake after a material edit, bake/rebake.py): the
        front pages and the back sides' pages as the bake directory stores them ((H, W, 4), A unused
        by the shaders), as many and as large as the bake's. Written into the texture array in place;
        a half-float array that the new values no longer fit becomes float32 (never Inf)."""
        w, h, layers = self.lightmaps.size[0], self.lightmaps.size[1], self.lightmaps.layers
        pages = [*front, *back]
        if len(pages) != layers or any(np.shape(p)[:2] != (h, w) for p in pages):
            raise GlintError(f"new light maps: {len(pages)} pages of {sorted({np.shape(p)[:2] for p in pages})} "
                             f"for the bake's {layers} of {(h, w)}; re-bake into the same atlas")
        data, _ = self._lightmap_stack(pages, "new light-map pages", "re-bake into the same atlas")
        dtype = "f2" if data.dtype == np.float16 and self.lightmap_dtype == "f2" else "f4"
        if dtype != self.lightmap_dtype:
            with self._gl.checked(f"allocate the light maps ({layers} pages) in float32"):
                texture = self.ctx.texture_array((w, h, layers), 4, data.astype(np.float32).tobytes(), dtype="f4")
            texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
            texture.repeat_x = texture.repeat_y = False
            self.lightmaps.release()
            self.lightmaps, self.lightmap_dtype = texture, "f4"
            return
        with self._gl.checked(f"upload the light maps ({layers} pages)"):
            self.lightmaps.write(data.astype(np.float16 if dtype == "f2" else np.float32).tobytes())

    # -- sky -------------------------------------------------------------------------------------
    def _sky(self, bake) -> None:
        sky = bake.manifest.get("sky")
        self.sky_mode = SKY_MODES["SKY_NONE"]
        self.sky_scale = np.zeros(3, np.float32)
        self.sky_map = self.white
        if not sky:
            return
        self.sky_scale = _clean(sky.get("radiance", (1, 1, 1))).astype(np.float32)
        if sky.get("map"):
            image = _clean(read_image(bake.path / sky["map"])[..., :3])
            h, w = image.shape[:2]
            rgba = np.concatenate([image, np.ones((h, w, 1))], axis=-1).astype(np.float32)
            check_texture_size(self.ctx, w, h, "the sky map", fix="scale it down")
            with self._gl.checked("upload the sky map"):
                self.sky_map = self.ctx.texture((w, h), 4, rgba.tobytes(), dtype="f4")
            self.sky_map.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self.sky_map.repeat_x, self.sky_map.repeat_y = True, False  # wrap in u, clamp in v
            self.sky_mode = SKY_MODES["SKY_MAP"]
        elif np.any(self.sky_scale > 0):
            self.sky_mode = SKY_MODES["SKY_CONSTANT"]

    def sky_uniforms(self) -> dict:
        return {"sky_mode": self.sky_mode, "sky_scale": tuple(map(float, self.sky_scale))}

    def release(self) -> None:
        for vao in self._vaos.values():
            vao.release()
        self._vaos.clear()
        for buf in (self.vertex_buffer, self.index_buffer, self.object_buffer, self.lod_buffer):
            if buf is not None:
                buf.release()
        for t in [*self.kd_textures, *self.emission_textures, *self.metallic_roughness_textures,
                  *self.normal_textures, *self.anisotropy_textures, self.lightmaps, self.white]:
            if t is not None:
                t.release()
        if self.sky_map is not self.white:
            self.sky_map.release()
        self.material_buffer.release()
        self.lobe_buffer.release()
        self.lobe_mr_buffer.release()
        self.pattern_buffer.release()
        self.lobe_pattern_buffer.release()
        self.cubemaps.release()


def surface_tangents(positions, normals, uvs, indices, supplied=None):
    """The tangent frame of a mesh, for normal maps and anisotropic lobes: -> (source (K,) the
    vertex each output vertex copies, indices (M, 3) into the output vertices, tangents (K, 4):
    xyz unit, w the bitangent sign, b = w n x t as glTF defines it). The file's TANGENT where
    given (`supplied`, non-zero rows); else MikkTSpace from the uvs (`tangents`, which splits a
    vertex whose faces disagree in handedness); else a world axis (`axis_tangents`)."""
    tri = np.asarray(indices, np.int64).reshape(-1, 3)
    n = len(positions)
    if supplied is not None and np.all(np.any(np.asarray(supplied)[:, :3] != 0, axis=1)):
        source, out = np.arange(n), np.asarray(supplied, np.float32).reshape(-1, 4).copy()
    elif uvs is not None and len(tri):
        corner = tangents(positions, normals, uvs, tri)
        # one output vertex per (vertex, handedness) its corners have: usually the vertex itself
        key = tri.ravel() * 2 + (corner[..., 3].ravel() < 0)
        keys, inverse = np.unique(key, return_inverse=True)
        source, tri = keys // 2, inverse.reshape(-1, 3)
        out = np.zeros((len(keys), 4), np.float32)
        out[inverse] = corner.reshape(-1, 4)
        if supplied is not None:  # the file's tangents where it has usable ones
            given = np.asarray(supplied, np.float32)[source]
            usable = np.any(given[:, :3] != 0, axis=1)
            out[usable] = given[usable]
    else:
        source, out = np.arange(n), np.zeros((n, 4), np.float32)
    nrm = np.asarray(normals, np.float64)[source]
    none = ~np.any(out[:, :3] != 0, axis=1)  # no uvs, or degenerate ones
    out[none] = axis_tangents(nrm[none])
    return source, tri, out


def tangents(positions, normals, uvs, indices) -> np.ndarray:
    """(M, 3, 4) tangents per triangle corner by MikkTSpace's rule (Mikkelsen 2008, the
    reference mikktspace.c that Blender's glTF exporter and glTF's sample viewer use): xyz
    unit, w = +-1 with the bitangent b = w n x t. Per triangle the unit dp/du (Mikkelsen's vOs),
    at each corner projected onto the vertex normal and weighted by the corner's angle (the
    edges projected onto the normal's plane), summed over the corners of one vertex group:
    vertices equal in position, normal and uv (so light-map seams, which split vertices, do not
    split the frame), and of one handedness, the sign of the triangle's uv area (glTF's v runs
    down the image, Mikkelsen's up: w = -sign of the area in glTF's uv, as three.js's
    computeMikkTSpaceTangents(negateSign=True)). Zero where every triangle of a group is
    degenerate in uv. Differences from the reference: it also requires the faces of a group to
    be connected through the vertex (two fans of one vertex that touch only there get one frame
    here); it gives degenerate triangles their neighbours' frame (here they add nothing); and
    its per-vertex bitangent magnitudes (the 'magS/magT' outputs) are not computed."""
    tri = np.asarray(indices, np.int64).reshape(-1, 3)
    out = np.zeros((len(tri), 3, 4), np.float32)
    if not len(tri):
        return out
    pos = np.asarray(positions, np.float64)
    nrm = np.asarray(normals, np.float64)
    tex = np.asarray(uvs, np.float64)
    p, t = pos[tri], tex[tri]
    d1, d2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    t21, t31 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    area = t21[:, 0] * t31[:, 1] - t21[:, 1] * t31[:, 0]  # twice the signed uv area
    # [d1 d2] = [dp/du dp/dv] [t21 t31]: dp/du = (t31v d1 - t21v d2) / area
    os = (t31[:, 1:2] * d1 - t21[:, 1:2] * d2) * np.sign(area)[:, None]
    length = np.linalg.norm(os, axis=1, keepdims=True)
    ok = (np.abs(area) > 1e-20) & (length[:, 0] > 1e-20)
    os = np.where(ok[:, None], os / np.maximum(length, 1e-300), 0.0)
    w = np.where(area < 0, 1.0, -1.0)  # handedness in glTF's v-down uv (docstring)
    # per corner: the face tangent projected onto the vertex normal, weighted by the corner angle
    n = nrm[tri]  # (M, 3, 3)
    vs = os[:, None, :] - n * np.einsum("fcj,fj->fc", n, os)[..., None]
    vs /= np.maximum(np.linalg.norm(vs, axis=2, keepdims=True), 1e-300)
    e1 = np.roll(p, -1, axis=1) - p
    e2 = np.roll(p, 1, axis=1) - p

    def in_plane(e):
        e = e - n * np.einsum("fcj,fcj->fc", n, e)[..., None]
        return e / np.maximum(np.linalg.norm(e, axis=2, keepdims=True), 1e-300)

    angle = np.arccos(np.clip(np.einsum("fcj,fcj->fc", in_plane(e1), in_plane(e2)), -1.0, 1.0))
    contribution = vs * (angle * ok[:, None])[..., None]
    # vertex groups: equal position, normal and uv, and one handedness
    weld = np.unique(np.concatenate([pos, nrm, tex], axis=1), axis=0, return_inverse=True)[1].reshape(-1)
    group = np.unique(weld[tri] * 2 + (w[:, None] < 0), return_inverse=True)[1].reshape(-1)
    sums = np.zeros((group.max() + 1, 3))
    np.add.at(sums, group, contribution.reshape(-1, 3))
    corner = sums[group]
    length = np.linalg.norm(corner, axis=1, keepdims=True)
    good = length[:, 0] > 1e-12
    flat = out.reshape(-1, 4)
    flat[good, :3] = corner[good] / length[good]
    flat[good, 3] = np.repeat(w, 3)[good]
    return out


def axis_tangents(normals) -> np.ndarray:
    """(N, 4) tangents for vertices without texture coordinates: world X projected onto the
    tangent plane (world Z where the normal lies within ~25 degrees of X, where that projection
    gets short), bitangent sign +1; zero for zero-length normals (the shader then builds any frame)."""
    nrm = np.asarray(normals, np.float64).reshape(-1, 3)
    out = np.zeros((len(nrm), 4), np.float32)
    length = np.linalg.norm(nrm, axis=1)
    good = length > 1e-12
    n = nrm[good] / length[good, None]
    axis = np.where((np.abs(n[:, 0]) > 0.9)[:, None], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    t = axis - n * np.einsum("ij,ij->i", axis, n)[:, None]  # |t| >= sin(25 deg) by the choice of axis
    out[good, :3] = t / np.linalg.norm(t, axis=1, keepdims=True)
    out[good, 3] = 1.0
    return out
