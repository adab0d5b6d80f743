"""Shading pass (compute): outgoing radiance per G-buffer pixel into an rgba32f image.

Per pixel (shaders/shading.comp): sky along the view ray where nothing was drawn;
else light-mapped diffuse + emission; black for back faces of single-sided materials.

Specular light (section 4.4) is a second dispatch (shaders/specular.comp), for
pixels whose material has lobes and whose object has a cube map, or is a planar
reflector whose plane got a mirror pass this frame (section 4.5, viewer/passes/
mirror.py, bound by `mirror.bind()`): shading.comp
queues the 8 x 8 tiles holding such pixels on two lists, pixels reading cube maps
and pixels reading their plane's mirror buffer (shaders/specular_work.glsl), and
specular.comp runs one work group per queued tile of a list (glDispatchComputeIndirect),
adding the lobes' light in one of the modes of specular.glsl (`SPECULAR_MODES`): the
walkthrough's regular patterns, still-camera quasi-random samples (frame by frame, see
viewer/progressive.py), or filtered importance sampling for comparisons. Each mode and
list is a program of its own, compiled when first used (`specular_program`): both are
constants in it, so a program holds one mode's and one kind of pixel's code (llvmpipe
runs both sides of a branch, a uniform one too: docs/VIEWER.md). Tiles
without such pixels cost nothing there (a branch inside a work group would still
cost its masked lanes on a SIMD machine, and on llvmpipe more than the diffuse
shading: docs/VIEWER.md, "The specular pass's tile queue"); a scene without lobes on cube-mapped objects skips the dispatch.
The work buffer also counts pixels and cube-map and mirror-buffer look-ups, which
`specular_counts` reads back (only when asked: reading waits for the GPU). The still
camera's planar look-ups keep per-pixel sums of the planes their samples met in two
rgba32f images (shaders/specular.glsl), allocated only for scenes with reflectors.
"""
from __future__ import annotations

import moderngl
import numpy as np

from glint.viewer.camera import ViewCamera
from glint.viewer.gl import check_compute_texture_units
from glint.viewer.gl_bindings import (
    GB_DEPTH_UNIT,
    GB_FRAME_UNIT,
    GB_SHADE_UNIT,
    MIRROR_PLANE_NORMAL_IMAGE,
    MIRROR_PLANE_POSITION_IMAGE,
    RADIANCE_IMAGE,
    SKY_UNIT,
    SPECULAR_WORK_BINDING,
    shading_units,
)
from glint.viewer.shader_source import LOCAL_SIZE, compute_program, dispatch, set_uniforms

# shaders/gbuffer_read.glsl
GBUFFER_UNITS = {"shade": GB_SHADE_UNIT, "frame": GB_FRAME_UNIT, "depth": GB_DEPTH_UNIT}
SPECULAR_MODES = {"SPECULAR_PATTERNS": 0, "SPECULAR_QMC": 1, "SPECULAR_FILTERED_IS": 2, "SPECULAR_SPLIT_SUM": 3}
# The walkthrough's pattern estimate (shaders/lobe_sampling.glsl): the lobe's albedo times the pattern's
# p cos-weighted mean of the radiance (the default; viewer/lobe_albedo.py says why), or for comparison
# the thesis' Eq. 4.25 or Eq. 4.24.
WEIGHTS = ("albedo", "eq4.25", "eq4.24")
# shaders/specular_work.glsl: its lists, and the uints of SpecularWork before the tiles (per list an indirect
# dispatch's x, y, z and one unused; pixels, look-ups, mirror look-ups, queued tiles, tiles per row, tiles per list).
SPECULAR_LISTS = {"SPECULAR_LIST_CUBE": 0, "SPECULAR_LIST_PLANAR": 1}
WORK_GROUPS = 4  # uints per list
WORK_PIXELS, WORK_LOOKUPS, WORK_MIRROR_LOOKUPS, WORK_QUEUED, WORK_TILES_X, WORK_CAPACITY = range(8, 14)
WORK_HEADER = 16


def scene_units(scene) -> dict:
    """The shading programs' scene-dependent texture units (viewer/gl_bindings.py `shading_units`)."""
    return shading_units(len(scene.cubemaps.classes))


class ShadingPass:
    name = "shading"

    def __init__(self, ctx: moderngl.Context, scene, defines: dict, weights: str = "albedo", mirror=None,
                 split_sum=None, footprint: int = 0):
        """defines: shader_defines() with the mirror buffers' units of scene_units(scene); mirror: the
        frame's MirrorPasses (None: no planar reflectors are shaded); split_sum: a
        viewer/split_sum.py SplitSum, which compiles SPECULAR_SPLIT_SUM in (None: not); footprint: a
        value of viewer/renderer.py FOOTPRINTS, the pattern look-ups' MIP footprint."""
        if weights not in WEIGHTS:
            raise ValueError(f"weights must be one of {WEIGHTS}, not {weights!r}")
        self.ctx = ctx
        self.scene = scene
        self.mirror = mirror
        self.units = scene_units(scene)
        extra = {**scene.cubemaps.defines(self.units["CUBE_FIRST_UNIT"]), **SPECULAR_MODES, **SPECULAR_LISTS,
                 "SPECULAR_LIST_COUNT": len(SPECULAR_LISTS)}
        if weights != "albedo":
            extra["WEIGHTS_EQ_4_24" if weights == "eq4.24" else "WEIGHTS_EQ_4_25"] = 1
        extra.update(scene.material_buffers.albedo_defines)
        self.split_sum = split_sum
        if split_sum is not None:
            extra.update(split_sum.defines(self.units["SPLIT_SUM_FIRST_UNIT"]))
        last = self.units["UNIT_COUNT"] - 1 if split_sum is not None else self.units["MIRROR_NORMAL_UNIT"]
        check_compute_texture_units(ctx, last + 1, f"shading this scene (cube maps of {len(scene.cubemaps.classes)} "
                                                   f"face sizes{', split-sum' if split_sum is not None else ''})")
        planar = self._planar()
        self.has_planar = bool(planar)
        # Without planar reflectors that can get a pass, mirror_slot_at is a constant -1 (specular_work.glsl).
        extra["MIRROR_ACTIVE"] = int(self.has_planar)
        self.program = compute_program(ctx, "shading.comp", {**defines, **extra})
        extra["PATTERN_FOOTPRINT"] = int(footprint)
        # Where no planar reflector has a cube map, the planar program leaves the cube-map code out.
        extra["PLANAR_CUBE_MAPS"] = int(any(scene.cubemaps.has_cubemap(i) for i in planar))
        self._defines = {**defines, **extra}
        self._specular: dict[tuple[str, str], moderngl.ComputeShader] = {}
        for kind in self.lists():  # the walkthrough's, wanted by the first frame
            self.specular_program("SPECULAR_PATTERNS", kind)
        self.update_specular(scene)
        self.planes: tuple[moderngl.Texture, moderngl.Texture] | None = None
        self.radiance: moderngl.Texture | None = None
        self.work: moderngl.Buffer | None = None
        self.tiles = (0, 0)
        self.cube_maps_bound = 0
        self.specular_ran = False

    def lists(self) -> tuple[str, ...]:
        """The tile lists a frame may fill (keys of SPECULAR_LISTS): the planar one only with planar reflectors."""
        return tuple(SPECULAR_LISTS) if self.has_planar else ("SPECULAR_LIST_CUBE",)

    def specular_program(self, mode: str, kind: str) -> moderngl.ComputeShader:
        """specular.comp for `mode` (a key of SPECULAR_MODES) over the tiles of list `kind` (a key of
        SPECULAR_LISTS), compiled on first use."""
        key = (mode, kind)
        if key not in self._specular:
            if (mode not in SPECULAR_MODES or kind not in SPECULAR_LISTS
                    or (mode == "SPECULAR_SPLIT_SUM" and self.split_sum is None)):
                raise ValueError(f"no specular program for mode {mode!r} and list {kind!r}")
            self._specular[key] = compute_program(self.ctx, "specular.comp", {
                **self._defines, "SPECULAR_MODE": mode, "SPECULAR_LIST": kind})
        return self._specular[key]

    def update_specular(self, scene) -> None:
        """Whether any specular work is possible (again after a material edit): only where a material
        with lobes meets an object with a cube map or a planar reflector that can get a mirror pass."""
        planar = self._planar()
        self.has_specular = any((scene.cubemaps.has_cubemap(i) or i in planar)
                                and scene.material_table[o.material]["info"][3] > 0
                                for i, o in enumerate(scene.objects))

    def _planar(self) -> set[int]:
        """The planar reflectors' object indices (those that can get a mirror pass)."""
        mirror = self.mirror
        return {i for i, _ in mirror.objects} if mirror is not None and mirror.active else set()

    def resize(self, size: tuple[int, int]) -> None:
        if self.radiance is not None and self.radiance.size == size:
            return
        self._release_targets()
        self.radiance = self.ctx.texture(size, 4, dtype="f4")
        self.radiance.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.tiles = (-(-size[0] // LOCAL_SIZE), -(-size[1] // LOCAL_SIZE))
        count = self.tiles[0] * self.tiles[1]
        self.work = self.ctx.buffer(reserve=(WORK_HEADER + len(SPECULAR_LISTS) * count) * 4)
        plane_size = size if self.has_planar else (1, 1)
        self.planes = tuple(self.ctx.texture(plane_size, 4, dtype="f4") for _ in range(2))

    def _bind_common(self, program, gbuffer: dict, camera: ViewCamera, aspect: float) -> None:
        forward, right, up = camera.ray_basis(aspect)
        vec = lambda v: tuple(map(float, v))  # noqa: E731
        set_uniforms(program, eye=vec(camera.eye), cam_forward=vec(forward), cam_right=vec(right),
                     cam_up=vec(up), znear=camera.znear, zfar=camera.zfar, **self.scene.sky_uniforms())
        for name, unit in GBUFFER_UNITS.items():
            gbuffer[name].use(unit)
        self.scene.bind_materials()
        self.scene.bind_specular()
        self.scene.material_buffers.albedo.bind()
        if self.mirror is not None:
            self.mirror.bind()
        self.work.bind_to_storage_buffer(SPECULAR_WORK_BINDING)

    def run(self, gbuffer: dict, camera: ViewCamera, aspect: float) -> moderngl.Texture:
        """The view-independent part of every pixel; queues the tiles that need specular light."""
        header = np.zeros(WORK_HEADER, np.uint32)
        for k in SPECULAR_LISTS.values():
            header[WORK_GROUPS * k + 1:WORK_GROUPS * k + 3] = 1  # the indirect dispatch's y and z sizes
        header[WORK_TILES_X] = self.tiles[0]
        header[WORK_CAPACITY] = self.tiles[0] * self.tiles[1]
        self.work.write(header.tobytes())
        self._bind_common(self.program, gbuffer, camera, aspect)
        self.scene.sky_map.use(SKY_UNIT)
        self.radiance.bind_to_image(RADIANCE_IMAGE, read=False, write=True)
        dispatch(self.program, *self.radiance.size)
        self.ctx.memory_barrier(moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT
                                | moderngl.SHADER_STORAGE_BARRIER_BIT | moderngl.COMMAND_BARRIER_BIT)
        self.specular_ran = False
        self.cube_maps_bound = 0
        return self.radiance

    def run_specular(self, gbuffer: dict, camera: ViewCamera, aspect: float, *, mode: str = "SPECULAR_PATTERNS",
                     qmc_first: int = 0, qmc_count: int = 0) -> moderngl.Texture:
        """Add the lobes' light over the queued tiles (after `run`). mode: a key of SPECULAR_MODES;
        with SPECULAR_QMC, samples qmc_first .. qmc_first + qmc_count - 1 of the quasi-random
        sequence per lobe and pixel."""
        if not self.has_specular:
            return self.radiance
        self.radiance.bind_to_image(RADIANCE_IMAGE, read=True, write=True)
        self.planes[0].bind_to_image(MIRROR_PLANE_POSITION_IMAGE, read=True, write=True)
        self.planes[1].bind_to_image(MIRROR_PLANE_NORMAL_IMAGE, read=True, write=True)
        # The lists' pixels are disjoint: no barrier between their dispatches.
        for kind in self.lists():
            program = self.specular_program(mode, kind)
            self._bind_common(program, gbuffer, camera, aspect)
            set_uniforms(program, qmc_first=int(qmc_first), qmc_count=int(qmc_count))
            self.cube_maps_bound = self.scene.cubemaps.bind(program, self.units["CUBE_FIRST_UNIT"])
            if self.split_sum is not None:
                self.split_sum.bind(program, self.units["SPLIT_SUM_FIRST_UNIT"])
            program.run_indirect(self.work, offset=WORK_GROUPS * 4 * SPECULAR_LISTS[kind])
        self.ctx.memory_barrier(moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT
                                | moderngl.BUFFER_UPDATE_BARRIER_BIT)
        self.specular_ran = True
        return self.radiance

    def specular_counts(self) -> dict:
        """What the last frame did: pixels with specular light, tiles with and without them,
        cube-map and mirror-buffer look-ups."""
        header = np.frombuffer(self.work.read(size=WORK_HEADER * 4), np.uint32) if self.work else np.zeros(WORK_HEADER)
        total = self.tiles[0] * self.tiles[1]
        queued = int(header[WORK_QUEUED]) if self.specular_ran else 0
        pixels, lookups, mirror = ((int(header[WORK_PIXELS]), int(header[WORK_LOOKUPS]),
                                    int(header[WORK_MIRROR_LOOKUPS])) if self.specular_ran else (0, 0, 0))
        return {"pixels": pixels, "tiles": queued, "tiles_skipped": total - queued, "lookups": lookups,
                "mirror_lookups": mirror}

    def _release_targets(self) -> None:
        for obj in (self.radiance, self.work, *(self.planes or ())):
            if obj is not None:
                obj.release()
        self.radiance = self.work = self.planes = None

    def release(self) -> None:
        self._release_targets()
        self.program.release()
        for program in self._specular.values():
            program.release()
        self._specular.clear()
