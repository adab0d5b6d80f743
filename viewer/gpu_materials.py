"""The materials on the GPU: their rows, their lobes' rows and the lobes' sampling patterns, in five
shader storage buffers (std430), re-uploaded whole when a material changes (`set_material`).

- Materials (`MATERIAL_DTYPE`, MATERIAL_BINDING) and lobes (`LOBE_DTYPE`, LOBE_BINDING): the section
  3.3 material (Eq. 3.6: kd/pi + lobes, plus emission), read by shaders/materials.glsl, which takes
  the MAT_*, LOBE_* constants below as defines (viewer/gpu_scene.py `shader_defines`).
- Per lobe how a metallic-roughness texture changes it (`LOBE_MR`, LOBE_MR_BINDING; core/scene.py
  Lobe.mr), read by shaders/materials.glsl and specular.glsl `lobe_at_pixel`.
- Per lobe its directional albedo (viewer/lobe_albedo.py `LobeAlbedo`: a texture array and its rows,
  LOBE_ALBEDO_BINDING), rebuilt with the lobes (an edit computes only the lobes it changed): the
  walkthrough's albedo-normalised estimate and split-sum's albedo factor.
- Lobe sampling patterns (section 4.4.3): the (xi1, xi2) positions of every lobe's regular
  patterns (viewer/lobe_patterns.py) in one buffer (PATTERN_BINDING), and per lobe (offset, count)
  in another (`PATTERN_DTYPE`, LOBE_PATTERN_BINDING), both read by shaders/specular.glsl: one
  pattern for cube-map look-ups and one for mirror-buffer look-ups of planar reflectors (section
  4.5.3); the sample count is chosen per lobe from its width, or set for all lobes by
  `set_lobe_samples`.
"""
from __future__ import annotations

import moderngl
import numpy as np

from glint.core.errors import GlintError
from glint.core.manifest import Material, Sampler
from glint.core.material_schema import checked_material
from glint.viewer.gl import GL
from glint.viewer.gl_bindings import (
    LOBE_BINDING,
    LOBE_MR_BINDING,
    LOBE_PATTERN_BINDING,
    MATERIAL_BINDING,
    PATTERN_BINDING,
)
from glint.viewer.gpu_textures import GpuTextures, clean
from glint.viewer.lobe_albedo import LobeAlbedo
from glint.viewer.lobe_patterns import choose_pattern, pattern_xi, samples_for_lobe

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
# The flag of each kind of texture (viewer/gpu_textures.py TEXTURE_KINDS) a material has
TEXTURE_FLAGS = {"kd": "MAT_KD_TEXTURE", "emission": "MAT_EMISSION_TEXTURE", "metallic_roughness": "MAT_MR_TEXTURE",
                 "normal": "MAT_NORMAL_TEXTURE", "anisotropy": "MAT_ANISOTROPY_TEXTURE"}
# All of them: shaders/raster_surface.glsl's TEXTURE_KINDS for a program that may meet every kind (a batch's
# program has its own kinds only, viewer/draw_list.py BatchPrograms)
ALL_TEXTURE_KINDS = sum(MATERIAL_FLAGS[flag] for flag in TEXTURE_FLAGS.values())
LOBE_KINDS = {"LOBE_REFLECT": 0, "LOBE_TRANSMIT": 1}
# How a metallic-roughness texture changes a lobe (core/scene.py Lobe.mr; specular.glsl lobe_at_pixel)
LOBE_MR = {"LOBE_MR_NONE": 0, "LOBE_MR_DIELECTRIC": 1, "LOBE_MR_METAL": 2}

MATERIAL_DTYPE = np.dtype([("kd", "<f4", 4), ("emission", "<f4", 4), ("info", "<i4", 4), ("surface", "<f4", 4)])
LOBE_DTYPE = np.dtype([("ks", "<f4", 4), ("shape", "<f4", 4)])
# Per lobe: first pattern sample, sample count, pattern kind (PATTERN_KINDS), row of the lobe's
# pattern for planar reflectors (ivec4, std430). Rows 0 .. L-1 are the lobes' patterns for cube
# maps, rows L .. 2L-1 those for mirror buffers (section 4.5.3: multi-ring for isotropic lobes).
PATTERN_DTYPE = np.dtype([("info", "<i4", 4)])
PATTERN_KINDS = {"ring": 0, "line_x": 1, "line_y": 2, "multi_ring": 3}
PLANAR_PATTERNS = ("auto", "ring", "multi_ring")  # GpuScene(planar_pattern=...)


def sampler_flags(sampler: Sampler) -> int:
    """MAT_KD_* flags of a manifest material's `kd_sampler` (core/manifest.py Sampler)."""
    flags = 0
    for mode, axis in ((sampler.wrap_s, "S"), (sampler.wrap_t, "T")):
        if mode == "CLAMP_TO_EDGE":
            flags |= MATERIAL_FLAGS[f"MAT_KD_CLAMP_{axis}"]
        elif mode == "MIRRORED_REPEAT":
            flags |= MATERIAL_FLAGS[f"MAT_KD_MIRROR_{axis}"]
    if sampler.mag_filter == "NEAREST":
        flags |= MATERIAL_FLAGS["MAT_KD_NEAREST"]
    return flags


class GpuMaterials:
    def __init__(self, ctx: moderngl.Context, gl: GL, entries: list[dict], textures: GpuTextures,
                 planar_pattern: str = "auto"):
        """entries: the manifest's materials as JSON (the dicts material editing passes; read here through
        core/manifest.py Material, the material schema piece will make edits typed); textures: theirs (which set the MAT_*_TEXTURE flags and
        the base colour's sampler flags); planar_pattern: as GpuScene's (PLANAR_PATTERNS)."""
        self.ctx, self._gl, self.textures, self.planar_pattern = ctx, gl, textures, planar_pattern
        self.materials = [dict(m) for m in entries]  # as shown; set_material replaces one
        # What stays the bake's through edits: the texture flags and the normal map's scale
        baked = [Material.from_json(m) for m in entries]
        self._texture_flags = [self._textured(i, m) for i, m in enumerate(baked)]
        self._normal_scale = [np.float32(clean(m.normal_scale, None)) for m in baked]
        self.material_buffer = self.lobe_buffer = self.lobe_mr_buffer = None
        self.pattern_buffer = self.lobe_pattern_buffer = None
        self.lobe_samples: int | None = None
        self.albedo = LobeAlbedo(ctx, gl)
        self._upload()

    def _textured(self, i: int, m: Material) -> int:
        """The MAT_* flags of material i's textures, with its sampler's wherever it has one."""
        flags = 0
        for kind, flag in TEXTURE_FLAGS.items():
            if self.textures.has(kind, i):
                flags |= MATERIAL_FLAGS[flag] | sampler_flags(m.kd_sampler)
        return flags

    def _material_rows(self, i: int, m: dict) -> tuple[np.ndarray, list, list]:
        """Material i's row of MATERIAL_DTYPE (its lobes' first row left 0), its LOBE_DTYPE rows and
        their LOBE_MR values, from its manifest entry and the textures loaded for it."""
        m = Material.from_json(m)  # an edited entry too: the manifest's defaults
        mat = np.zeros((), MATERIAL_DTYPE)
        flags = self._texture_flags[i]
        lobes = m.lobes
        kinds = {lobe.kind for lobe in lobes}
        if m.double_sided or "transmit" in kinds:
            flags |= MATERIAL_FLAGS["MAT_TWO_SIDED"]
        if "transmit" in kinds:
            flags |= MATERIAL_FLAGS["MAT_TRANSMISSIVE"]
        if lobes:
            flags |= MATERIAL_FLAGS["MAT_SPECULAR"]
        emission = clean(m.emission)
        if np.any(emission > 0):
            flags |= MATERIAL_FLAGS["MAT_EMISSIVE"]
        if m.has_coverage:
            flags |= MATERIAL_FLAGS[f"MAT_ALPHA_{m.alpha_mode}"]
            mat["kd"][3] = float(np.clip(clean(m.alpha), 0.0, 1.0))
            mat["emission"][3] = float(clean(m.alpha_cutoff))
        mat["kd"][:3] = np.clip(clean(m.kd), 0.0, 1.0)
        mat["emission"][:3] = emission
        rotation = float(clean(m.anisotropy_rotation, None))  # editable: the panel's direction
        mat["surface"] = (self._normal_scale[i], np.cos(rotation), np.sin(rotation), 0.0)
        mat["info"] = (flags, i if self.textures.has("kd", i) else -1, 0, len(lobes))
        rows, lobe_mr = [], []
        textured = self.textures.has("metallic_roughness", i)
        for lobe in lobes:
            row = np.zeros((), LOBE_DTYPE)
            row["ks"][:3] = np.clip(clean(lobe.ks), 0.0, 1.0)
            row["ks"][3] = LOBE_KINDS["LOBE_TRANSMIT" if lobe.kind == "transmit" else "LOBE_REFLECT"]
            row["shape"] = (lobe.mx, lobe.my, lobe.r0, lobe.alpha)
            rows.append(row)
            lobe_mr.append(LOBE_MR[f"LOBE_MR_{lobe.mr or 'none'}".upper()] if textured else 0)
        return mat, rows, lobe_mr

    def _upload(self) -> None:
        """The material, lobe and LOBE_MR tables of `self.materials` and the lobes' sampling patterns
        (`lobe_samples`), (re)uploaded whole: the lobe rows of a material follow those before it, so
        a material whose lobe count changes moves every later one."""
        mats = np.zeros(max(len(self.materials), 1), MATERIAL_DTYPE)
        lobe_rows, lobe_mr, lobe_aniso = [], [], []
        for i, m in enumerate(self.materials):
            row, rows, mr = self._material_rows(i, m)
            row["info"][2] = len(lobe_rows)
            mats[i] = row
            lobe_rows += rows
            lobe_mr += mr
            lobe_aniso += [bool(self._texture_flags[i] & MATERIAL_FLAGS["MAT_ANISOTROPY_TEXTURE"])] * len(rows)
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
        self.albedo.update(self.lobe_table, lobe_mr, lobe_aniso)
        self.set_lobe_samples(self.lobe_samples)

    def set_material(self, index: int, material: Material) -> None:
        """Material `index` as the typed `material` (GpuScene.set_material): checked first (the material
        schema, core/material_schema.py `checked_material`), kept as its manifest entry (the upload's
        one conversion), then every table uploaded again."""
        if not 0 <= index < len(self.materials):
            raise GlintError(f"no material {index} (the scene has {len(self.materials)})")
        self.materials[index] = checked_material(material).to_json()
        self._upload()

    @property
    def albedo_defines(self) -> dict:
        """shaders/lobe_albedo.glsl's defines; LOBE_ALBEDO_INEXACT only where a material has both a
        metallic-roughness and an anisotropy texture (its lobes' tables are the factor's: Eq. 4.25 for
        them), fixed with the textures for the renderer's life: elsewhere the walkthrough's estimator is
        a constant the shader compiler folds."""
        both = MATERIAL_FLAGS["MAT_MR_TEXTURE"] | MATERIAL_FLAGS["MAT_ANISOTROPY_TEXTURE"]
        inexact = any(flags & both == both for flags in self._texture_flags)
        return {**self.albedo.defines(), **({"LOBE_ALBEDO_INEXACT": 1} if inexact else {})}

    def emissive(self) -> np.ndarray:
        """Per material whether it emits (MAT_EMISSIVE)."""
        return (self.material_table["info"][:, 0] & MATERIAL_FLAGS["MAT_EMISSIVE"]) != 0

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

    def bind(self) -> None:
        """The material, lobe and LOBE_MR buffers (the albedo table's: `albedo.bind`)."""
        self.material_buffer.bind_to_storage_buffer(MATERIAL_BINDING)
        self.lobe_buffer.bind_to_storage_buffer(LOBE_BINDING)
        self.lobe_mr_buffer.bind_to_storage_buffer(LOBE_MR_BINDING)

    def bind_patterns(self) -> None:
        """The lobes' sampling patterns."""
        self.pattern_buffer.bind_to_storage_buffer(PATTERN_BINDING)
        self.lobe_pattern_buffer.bind_to_storage_buffer(LOBE_PATTERN_BINDING)

    def release(self) -> None:
        for buf in (self.material_buffer, self.lobe_buffer, self.lobe_mr_buffer, self.pattern_buffer,
                    self.lobe_pattern_buffer):
            buf.release()
        self.albedo.release()
