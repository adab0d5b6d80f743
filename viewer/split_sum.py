"""The split-sum approximation (Karis 2013, "Real Shading in Unreal Engine 4"; the glTF sample
viewer does the same): what game engines and glTF viewers use for glossy reflections, the
`split-sum` method of `glint bench` (Renderer(walkthrough="split-sum")).

Per lobe, the specular integral of Eq. 4.3 is split into two factors,

    L_spec(v) ~= [ int L(l) k_m(l, r) dl / int k_m(l, r) dl ] x [ int f(l, v) cos(theta_l) dl ],

the first the cube map's radiance prefiltered with the lobe around its centre direction r (the
mirror direction; for a transmission lobe the straight-through one), the second the lobe's
directional albedo for the view v. One look-up each per lobe and pixel, whatever n: the method
has no sample count.

Prefilter (`SplitSum`, shaders/split_sum_prefilter.comp, once when the renderer is made):
for each object cube map a MIP chain of the same face size where level k holds the radiance
convolved with the section 3.3 lobe of roughness m_k under the split-sum assumption n = v = r:
the kernel is Eq. 3.4 with F = 1 and alpha = 0 (k = D(h) cos(theta_l) / (4 v.h), the Fresnel
term and Kurt's shadowing depend on the material and are in the albedo factor instead, as
engines leave them out of the prefilter), normalised. It is estimated with importance samples
of the lobe (Eq. 4.5-4.9, a Hammersley set, as Karis) per texel, each read from the source's
box-filtered MIP chain at Colbert and Krivanek's level for its pdf (filtered importance
sampling, as the glTF viewer): smooth with few samples. Level k >= 1 takes `level_samples`:
PREFILTER_SAMPLES at level 1, doubled per level up to PREFILTER_SAMPLES_MAX (the lobes widen as
the texels get fewer, so each level costs about half the one before; tests/test_split_sum.py
holds every texel within 2 % of a numpy quadrature; more samples buy little accuracy for much
time: docs/BENCHMARKS.md, "The split-sum prefilter's sample counts"). Level 0 is the source itself (m_0 = 0). The chain stops at faces of LOWEST_FACE texels (engines stop at
4-16), so a face of S texels gets log2(S / LOWEST_FACE) + 1 levels.

Roughness to level, as the glTF viewer maps its perceptual roughness sqrt(m) linearly onto the
levels: level(m) = sqrt(m / M_MAX) (levels - 1), clamped to the chain, read trilinearly
(GL_LINEAR_MIPMAP_LINEAR between the two nearest levels); so m_k = M_MAX (k / (levels - 1))^2.
An anisotropic lobe is prefiltered as the isotropic one of m = sqrt(mx my), as engines do
(the chain has one roughness per level); only the albedo factor knows its anisotropy.

Albedo: the lobes' table of viewer/lobe_albedo.py, which the walkthrough's albedo-normalised pattern
estimate reads too (built with the materials, always; per lobe rather than a shared (cos_v, m)
table per alpha because that is exact for the scene's own r0, alpha and anisotropy, and over the
texel's roughness for lobes that follow a metallic-roughness texture).

Planar reflectors have a mirror buffer, not a cube map: what engines do for glossy planar
reflections, one look-up of the buffer at the lobe centre's projection (shaders/
mirror_buffer.glsl's two-step projection) at the MIP level of the lobe's footprint there (its
ellipse, section 4.5.3, over one sample), times the same albedo. Transmission lobes look up
around the transmitted direction in the cube map, with their own albedo, as the other methods.

    split = SplitSum(ctx, scene)   # GpuScene: prefilters every cube map
    split.defines(first_unit)      # shaders/split_sum.glsl's defines (SPLIT_SUM on)
    split.bind(program, first_unit)
    split.describe()               # prefilter_ms, levels ... (renderer.stats["split_sum"])
"""
from __future__ import annotations

import math
import time

import moderngl
import numpy as np

from glint.viewer.gl import GL, GL_RGBA16F, GL_RGBA32F, GL_WRITE_ONLY
from glint.viewer.gl_bindings import PREFILTER_CUBE_UNIT, PREFILTER_IMAGE
from glint.viewer.gpu_scene import shader_defines
from glint.viewer.shader_source import LOCAL_SIZE, compute_program, set_uniforms

PREFILTER_SAMPLES = 64    # importance samples per texel of level 1, doubled per level ...
PREFILTER_SAMPLES_MAX = 512  # ... up to this: wider lobes on fewer texels (converged: see tests)
LOWEST_FACE = 4           # texels per side of the chain's last level
M_MAX = 1.0               # the roughness of the last level


def level_count(face_size: int) -> int:
    """Levels of the prefiltered chain of faces of `face_size` texels: down to LOWEST_FACE."""
    return max(1, int(math.log2(max(face_size, 1))) - int(math.log2(LOWEST_FACE)) + 1)


def level_roughness(level: int, levels: int) -> float:
    """m_k of level k: the inverse of shaders/split_sum.glsl split_sum_lod."""
    return M_MAX * (level / (levels - 1)) ** 2 if levels > 1 else 0.0


def level_samples(level: int, samples: int = PREFILTER_SAMPLES) -> int:
    """Importance samples per texel of prefiltered level `level` (level 0, the source: one)."""
    return 1 if level == 0 else min(samples << (level - 1), max(PREFILTER_SAMPLES_MAX, samples))


class SplitSum:
    """Prefiltered cube-map arrays (one per size class of viewer/cubemaps.py, same layers) of a GpuScene."""

    def __init__(self, ctx, scene, samples: int = PREFILTER_SAMPLES):
        self.ctx = ctx
        self.samples = int(samples)
        cubes = scene.cubemaps
        self.classes = cubes.classes
        self.levels = [level_count(c.size) for c in self.classes]
        self.textures: list[int] = []
        self._programs: dict = {}  # the prefilter's compute programs by image format
        self._gl = GL(ctx) if self.classes else None
        self.prefilter_ms = 0.0
        if not self.classes:
            return
        ctx.finish()
        started = time.perf_counter()
        cubes.bind_buffers()
        for k in range(len(self.classes)):
            self.textures.append(self._prefilter(cubes, k))
        ctx.finish()
        self.prefilter_ms = (time.perf_counter() - started) * 1e3

    def refresh(self, cubes, k: int) -> None:
        """Prefilter class k again (its cube maps were replaced: CubeMaps.replace)."""
        cubes.bind_buffers()
        name = self._prefilter(cubes, k)
        self._gl.delete_textures([self.textures[k]])
        self.textures[k] = name

    def _prefilter(self, cubes, k: int) -> int:
        """The prefiltered chain of class k: a new cube-map array, each level written by one dispatch."""
        gl, cls, levels = self._gl, self.classes[k], self.levels[k]
        fmt = "rgba16f" if cls.dtype == "f2" else "rgba32f"
        if fmt not in self._programs:
            defines = {**shader_defines(), **cubes.defines(PREFILTER_CUBE_UNIT), "SPLIT_SUM_FORMAT": fmt}
            self._programs[fmt] = compute_program(self.ctx, "split_sum_prefilter.comp", defines)
        program = self._programs[fmt]
        internal = GL_RGBA16F if cls.dtype == "f2" else GL_RGBA32F
        what = (f"the split-sum prefiltered cube maps of face size {cls.size} ({len(cls.probes)} probes, "
                f"{levels} levels, {'RGBA16F' if cls.dtype == 'f2' else 'RGBA32F'})")
        name = gl.allocate_cube_array(cls.size, 6 * len(cls.probes), levels, internal, what)
        cubes.bind(program, PREFILTER_CUBE_UNIT)
        with gl.checked(f"prefilter {what}"):  # an image binding GL refuses leaves the level unwritten
            for level in range(levels):
                face = max(cls.size >> level, 1)
                gl.BindImageTexture(PREFILTER_IMAGE, name, level, 1, 0, GL_WRITE_ONLY, internal)
                set_uniforms(program, source_class=k, face_size=face, roughness=level_roughness(level, levels),
                             samples=level_samples(level, self.samples))
                program.run(-(-face // LOCAL_SIZE), -(-face // LOCAL_SIZE), 6 * len(cls.probes))
        self.ctx.memory_barrier(moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT)
        return name

    # -- shading ----------------------------------------------------------------------------------
    def defines(self, first_unit: int) -> dict:
        """shaders/split_sum.glsl: the prefiltered classes on units first_unit .. first_unit + C - 1
        (C = CUBE_CLASSES, at least 1; viewer/gl_bindings.py `shading_units`)."""
        return {"SPLIT_SUM": 1, "SPLIT_SUM_FIRST_UNIT": int(first_unit), "SPLIT_SUM_M_MAX": float(M_MAX)}

    def bind(self, program, first_unit: int) -> None:
        """Bind the prefiltered arrays as `defines(first_unit)` told the shader."""
        if not self.classes:
            return
        self._gl.bind_cube_arrays(first_unit, self.textures)
        if program is not None and "split_sum_levels" in program:
            program["split_sum_levels"].write(np.array(self.levels, np.float32).tobytes())

    def read_level(self, k: int, level: int) -> np.ndarray:
        """(layers, 6, s, s, 4) float32: level `level` of class k's prefiltered chain, faces in GL
        order, row 0 at t = 0 (for tests and debugging)."""
        cls = self.classes[k]
        s = max(cls.size >> level, 1)
        out = np.zeros((len(cls.probes), 6, s, s, 4), np.float32)
        return self._gl.read_cube_array(self.textures[k], level, out, f"level {level} of split-sum class {k}")

    def describe(self) -> dict:
        return {"prefilter_ms": round(self.prefilter_ms, 3),
                "levels": [{"face_size": c.size, "levels": n,
                            "roughness": [round(level_roughness(k, n), 6) for k in range(n)],
                            "samples": [level_samples(k, self.samples) for k in range(n)]}
                           for c, n in zip(self.classes, self.levels)]}

    def release(self) -> None:
        if self._gl is not None:
            self._gl.delete_textures(self.textures)
        self.textures = []
        for program in self._programs.values():
            program.release()
        self._programs = {}
