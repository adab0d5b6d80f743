"""Cube maps on the GPU (section 4.4.1): the incident light of curved and transmissive objects,
as seen from the centre of their probe (bake/cubemap.py: an object's own bounding-box centre, or a
shared probe's, the centre of its cluster), plus the probe's bounding planes.

    cubes = CubeMaps(ctx, bake)     # every manifest object with a `cubemap` entry
    cubes.defines()                 # {"CUBE_CLASSES": k}: shaders/cubemaps.glsl's sampler array
    cubes.bind(program, first_unit) # cube-map arrays on texture units, face sizes as uniforms
    cubes.bind_buffers()            # per-object table and bounding planes (storage buffers)

Each probe's file is read and uploaded once, however many objects it serves. Probes
differ in size (the bake picks one per probe), and a cube-map *array* needs one
size, so they are grouped into size classes: one `samplerCubeArray` per distinct
face size (several where one size has more probes than an array has layers), a
probe is one layer of its class. Per object a storage buffer row
(`CUBE_OBJECT_DTYPE`) says where: class (-1: no cube map), layer, its probe's
centre and the range of its bounding planes; the planes (point, unit normal) follow
in a second buffer. Objects without a cube map (diffuse, planar) cost nothing.

GL limits, checked here so that no object is left black (`fit_classes`): a class
holds at most GL_MAX_ARRAY_TEXTURE_LAYERS / 6 probes (341 at GL 4.3's minimum of
2048 layers); the shading programs bind every class twice (the cube maps and their
split-sum prefiltered copies, viewer/gl_bindings.py `shading_units`) within
GL_MAX_COMPUTE_TEXTURE_IMAGE_UNITS, which caps the number of classes; a face is at
most GL_MAX_CUBE_MAP_TEXTURE_SIZE. Past a limit, the largest faces are resampled
to half their size (a 2 x 2 box filter, what their next MIP level holds anyway), so
that their probes join a smaller class, until everything fits, with one warning;
when even the smallest faces need more classes than the programs can bind, a
GlintError says how many probes fit ([bake] cubemap_budget). An upload that runs
out of GPU memory (GL_OUT_OF_MEMORY, through GL.checked) is retried at half the face
size, with a warning, down to `MIN_FALLBACK_SIZE`; any other failed upload is a
GlintError. Where the driver tells its free memory (GL_NVX_gpu_memory_info,
GL_ATI_meminfo), `memory()` reports it beside the cube maps' own MiB.

Every class has a full MIP chain (shaders/cube_mips.comp: 2 x 2 box filter per
level), GL_LINEAR_MIPMAP_LINEAR, and GL_TEXTURE_CUBE_MAP_SEAMLESS is on, so the
filtered look-ups of Eq. 4.14-4.17 blend across face edges. Texels are RGBA16F,
or RGBA32F for a class where a value does not fit in half float (a very bright
emitter must not turn into Inf; docs/ARCHITECTURE.md, "Numerics"). Alpha is the bake's
distance from the centre; the shaders read only rgb.

moderngl (5.13) has no cube-map arrays, so the few GL calls they need go through
ctypes to the context's own function pointers (viewer/gl.py).

The file layout (`read_cubemap`) is the bake's (bake/cubemap.py): one OpenEXR
per probe, the six faces stacked vertically in GL order +X, -X, +Y, -Y, +Z, -Z,
each face S x S with its first row at GL's t = 0 and its first column at s = 0
(the order glTexImage3D takes), so a look-up `texture(cube, dir)` returns the
radiance seen along dir.
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass
from pathlib import Path

import moderngl
import numpy as np

from glint.core.constants import HALF_MAX
from glint.core.errors import GlintError, warn
from glint.core.geometry import oriented_box
from glint.core.image_io import read_image
from glint.core.manifest import Manifest, ObjectEntry, Volume
from glint.viewer.gl import GL, GL_RGBA16F, GL_RGBA32F, GL_TEXTURE_CUBE_MAP_SEAMLESS, describe
from glint.viewer.gl_bindings import (
    BOUNDING_PLANE_BINDING,
    CUBE_OBJECT_BINDING,
    MIP_SOURCE_IMAGE,
    MIP_TARGET_IMAGE,
    shading_units,
)
from glint.viewer.shader_source import LOCAL_SIZE, compute_program, set_uniforms

FACES = ("+x", "-x", "+y", "-y", "+z", "-z")  # GL's face order (GL_TEXTURE_CUBE_MAP_POSITIVE_X + k)
MAX_PLANES = 16  # per object; more are ignored (each is a ray-plane test per sample)
MIN_FALLBACK_SIZE = 4  # texels: below this an out-of-memory upload is an error, not a smaller retry
# Driver memory queries (GL_NVX_gpu_memory_info, GL_ATI_meminfo): free memory in KiB.
GL_GPU_MEMORY_INFO_CURRENT_AVAILABLE_VIDMEM_NVX = 0x9049
GL_TEXTURE_FREE_MEMORY_ATI = 0x87FC

# Per object (std430): xyz projection centre, w unused; class (-1: none), layer, first plane, plane count;
# a glass solid's (shaders/volume.glsl) half extents of its oriented box (core/geometry.py oriented_box)
# and thickness (w), its absorption sigma_a (rgb, 1/m) and ior (a; 0: not a solid), and the box's
# axes (xyz of the three rows) with its centre (their w).
CUBE_OBJECT_DTYPE = np.dtype([("centre", "<f4", 4), ("info", "<i4", 4), ("extent", "<f4", 4), ("volume", "<f4", 4),
                              ("box", "<f4", (3, 4))])
PLANE_DTYPE = np.dtype([("point", "<f4", 4), ("normal", "<f4", 4)])


def read_cubemap(path: str | Path, *, keep_half: bool = False) -> np.ndarray:
    """The one reader of the bake's cube-map files: (6, S, S, 4) float32 in GL face order, each
    face's row 0 at t = 0 (see the module docstring); alpha = 1 where the file has none.
    Non-finite or negative radiance becomes 0. keep_half: a half-float file's faces as float16
    (the same values, without a float32 copy: what `CubeMaps` uploads)."""
    image = read_image(path, "cube map", keep_half=keep_half)
    h, w, c = image.shape
    if h != 6 * w or c < 3:
        raise GlintError(f"{path}: not a cube map (expected 6 faces of S x S stacked vertically, "
                         f"RGB or RGBA; got {w}x{h} with {c} channels); run `glint bake --force`")
    faces = np.ones((6, w, w, 4), image.dtype)
    faces[..., :3] = image.reshape(6, w, w, c)[..., :3]
    if c >= 4:
        faces[..., 3] = image.reshape(6, w, w, c)[..., 3]
    return finite_radiance(faces)


def finite_radiance(texels: np.ndarray) -> np.ndarray:
    """`texels` (float16 or float32) as they are when every value is finite and not negative,
    else a float32 copy with the others 0. Half floats are checked on their bits (exponent all
    ones: Inf or NaN; sign bit on a non-zero value), much faster than numpy's float16 arithmetic
    (docs/VIEWER.md, "Checking re-baked probes"): the viewer's thread checks a re-bake's probes
    (CubeMaps.replace)."""
    if texels.dtype == np.float16:
        bits = texels.view(np.uint16)
        fine = not ((bits & 0x7C00) == 0x7C00).any() and not (bits > 0x8000).any()
    else:
        fine = bool(np.isfinite(texels).all()) and float(texels.min(initial=0.0)) >= 0.0
    if fine:
        return texels
    return np.clip(np.nan_to_num(texels.astype(np.float32), nan=0.0, posinf=0.0, neginf=0.0), 0.0, None)


def downsample(faces: np.ndarray, size: int) -> np.ndarray:
    """(6, S, S, 4) faces box-filtered to (6, size, size, 4), size a power of two dividing S."""
    k = faces.shape[1] // size
    return faces.reshape(6, size, k, size, k, 4).mean(axis=(2, 4), dtype=np.float32)


def mip_chain(faces: np.ndarray, half: bool = False) -> list[np.ndarray]:
    """(6, S, S, 4) faces (S a power of two) and their 2 x 2 box-filtered halvings down to one
    texel: the MIP levels CubeMaps makes of them on the GPU (shaders/cube_mips.comp; a re-bake's
    probes come with theirs, computed off the viewer's thread: glint/cubemap_stage.py ProbeRefresher).
    float32; with `half`, float16 where every value fits in it (what the cube-map arrays mostly hold)."""
    chain = [np.asarray(faces, np.float32)]
    while chain[-1].shape[1] > 1:
        chain.append(downsample(chain[-1], chain[-1].shape[1] // 2))
    if half and fits_half(chain[0]):  # the box filter never exceeds level 0
        chain = [level.astype(np.float16) for level in chain]
    return chain


def fits_half(texels: np.ndarray) -> bool:
    """Whether non-negative finite `texels` fit in half float: float16 ones do, others where no value
    exceeds HALF_MAX (a class holding any other is RGBA32F: no Inf)."""
    return texels.dtype == np.float16 or float(texels.max(initial=0.0)) <= HALF_MAX


def fit_classes(sizes: list[int], per_class: int, max_classes: int, max_face: int) -> tuple[list[int], list]:
    """Face size per probe and the classes [(size, [probe, ...]), ...] for probes of `sizes`
    within the GL limits: at most `per_class` probes a class, `max_classes` classes, faces of at
    most `max_face`. The largest faces are halved until the classes fit (see the module
    docstring); GlintError when even faces of one texel would need more classes."""
    fitted = [min(s, 1 << (max(int(max_face), 1).bit_length() - 1)) for s in sizes]
    while True:
        classes = [(s, same[k:k + per_class]) for s in sorted(set(fitted))
                   for same in [[p for p, f in enumerate(fitted) if f == s]]
                   for k in range(0, len(same), per_class)]
        if len(classes) <= max_classes:
            return fitted, classes
        if len(set(fitted)) == 1:
            raise GlintError(f"{len(sizes)} cube-map probes need {len(classes)} cube-map arrays of at most "
                             f"{per_class} probes, and this OpenGL binds {max_classes} in the shading programs: "
                             f"set [bake] cubemap_budget = {per_class * max_classes} (or less) in the scene's "
                             f"sidecar and bake again")
        top = max(fitted)
        fitted = [f // 2 if f == top else f for f in fitted]


@dataclass
class CubeClass:
    """All probes of one face size: one GL cube-map array, a layer per probe."""
    size: int
    dtype: str          # "f2" or "f4"
    probes: list        # the probe (file) of each layer
    glo: int = 0

    @property
    def levels(self) -> int:
        return int(np.log2(self.size)) + 1

    @property
    def mib(self) -> float:
        texel = 8 if self.dtype == "f2" else 16
        return sum(texel * 6 * (self.size >> k) ** 2 for k in range(self.levels)) * len(self.probes) / 2 ** 20


class CubeMaps:
    def __init__(self, ctx: moderngl.Context, bake):
        self.ctx = ctx
        objects = bake.model.objects
        table = np.zeros(max(len(objects), 1), CUBE_OBJECT_DTYPE)
        table["info"][:, 0] = -1
        planes: list[np.ndarray] = []
        probes: dict[str, int] = {}  # file -> probe number (its index in `faces`)
        faces: list[np.ndarray] = []
        probe_of: dict[int, int] = {}
        for i, entry in enumerate(objects):
            cube = entry.cubemap
            if not cube:
                continue
            if cube.file not in probes:
                probes[cube.file] = len(faces)
                faces.append(read_cubemap(Path(bake.path) / cube.file, keep_half=True))
            probe_of[i] = probes[cube.file]
            table[i]["centre"][:3] = _finite(cube.centre)
            volume = _material_volume(bake.model, entry)
            if volume:  # a glass solid: bake/pipeline.py's `volume` entry of its material
                centre, axes, half = oriented_box(
                    np.nan_to_num(np.asarray(bake.meshes[i]["positions"], np.float64), posinf=0.0, neginf=0.0))
                table[i]["extent"][:3] = half
                table[i]["box"][:, :3] = axes
                table[i]["box"][:, 3] = centre
                table[i]["extent"][3] = max(_finite_scalar(volume.thickness), 0.0)
                table[i]["volume"][:3] = np.clip(_finite(volume.absorption), 0.0, HALF_MAX)
                table[i]["volume"][3] = max(_finite_scalar(volume.ior), 1.0)
            rows = _planes(cube.bounding_planes)
            table[i]["info"][2:] = (len(planes), len(rows))
            planes.extend(rows)
        limits = gl_limits(ctx)
        fitted, classes = fit_classes([f.shape[1] for f in faces], **limits)
        resampled = [(f.shape[1], s) for f, s in zip(faces, fitted) if f.shape[1] != s]
        if resampled:
            warn(f"cube maps: {len(resampled)} of {len(faces)} probes resampled to smaller faces "
                 f"({', '.join(sorted({f'{a} -> {b}' for a, b in resampled}))}) to fit this OpenGL's limits "
                 f"({limits['per_class']} probes per cube-map array, {limits['max_classes']} arrays, faces of "
                 f"{limits['max_face']}; {describe(ctx)}); fewer probes ([bake] cubemap_budget) keep them sharp")
            faces = [downsample(f.astype(np.float32), s) if f.shape[1] != s else f for f, s in zip(faces, fitted)]
        self.classes = [CubeClass(s, "f2", members) for s, members in classes]
        layer_of = {p: (k, layer) for k, cls in enumerate(self.classes) for layer, p in enumerate(cls.probes)}
        self.slots = {file: layer_of[p] for file, p in probes.items()}  # probe file -> (class, layer)
        for i, p in probe_of.items():
            table[i]["info"][:2] = layer_of[p]
        self.table = table
        self.object_buffer = ctx.buffer(table.tobytes())
        plane_rows = np.array(planes, PLANE_DTYPE) if planes else np.zeros(1, PLANE_DTYPE)
        self.plane_buffer = ctx.buffer(plane_rows.tobytes())
        self.count = len(faces)
        self.objects = len(probe_of)
        self._gl = GL(ctx) if faces else None
        self._mip_programs: dict[str, moderngl.ComputeShader] = {}  # "f2" / "f4": shaders/cube_mips.comp
        for cls in self.classes:
            self._upload(cls, [faces[p] for p in cls.probes])

    # -- GL ---------------------------------------------------------------------------------------
    def _upload(self, cls: CubeClass, maps: list[np.ndarray]) -> None:
        """Upload a class; out of GPU memory, retry at half the face size (module docstring)."""
        while True:
            # half float where every value fits (a float16 map, read from a half-float file, does)
            fits = all(fits_half(m) for m in maps)
            cls.dtype = "f2" if fits else "f4"
            # layer-face = layer * 6 + face, filled in place: no stacked float32 copy of the class
            pixels = np.empty((len(maps) * 6, cls.size, cls.size, 4), np.float16 if fits else np.float32)
            for k, m in enumerate(maps):
                pixels[6 * k:6 * k + 6] = m  # numpy's float32 -> float16 rounding, as astype
            try:
                cls.glo = self._upload_array(
                    cls, pixels, f"the cube maps of face size {cls.size} ({len(maps)} probes, "
                            f"{'RGBA16F' if cls.dtype == 'f2' else 'RGBA32F'}, {cls.mib:.0f} MiB)")
                return
            except GlintError as err:
                if "GL_OUT_OF_MEMORY" not in str(err) or cls.size // 2 < MIN_FALLBACK_SIZE:
                    raise
                warn(f"cube maps: out of GPU memory for {len(maps)} probes of face size {cls.size} "
                     f"({cls.mib:.0f} MiB); using faces of {cls.size // 2} (blurrier reflections); a smaller "
                     "[bake] cubemap_budget_mib keeps the bake and the GPU in step")
                cls.size //= 2
                maps = [downsample(f.astype(np.float32), cls.size) for f in maps]

    def replace(self, file: str, chain: list[np.ndarray]) -> int:
        """New radiance for the probe whose bake file is `file` (a material edit's re-bake,
        glint/cubemap_stage.py ProbeRefresher): `chain` is its faces' MIP chain (`mip_chain`),
        level 0 at the bake's face size or larger; the levels from the class's face size down are
        written into the probe's layer (glTexSubImage3D), nothing else is touched. A half-float
        class that a new value no longer fits becomes float32 (never Inf). Returns the class.
        Non-finite or negative radiance becomes 0 (`finite_radiance`), as `read_cubemap` reads it;
        float16 levels are written as they are (no conversion on the viewer's thread)."""
        if file not in self.slots:
            raise GlintError(f"new cube map {file}: not a probe of this bake")
        k, layer = self.slots[file]
        cls = self.classes[k]
        sizes = [level.shape[1] for level in chain]
        if cls.size not in sizes or len(chain) - sizes.index(cls.size) < cls.levels:
            raise GlintError(f"new cube map {file}: MIP levels of {sizes} for faces of {cls.size}")
        levels = [finite_radiance(level) for level in chain[sizes.index(cls.size):][:cls.levels]]
        if cls.dtype == "f2" and not all(fits_half(level) for level in levels):
            self._widen(cls)
        for n, level in enumerate(levels):
            if cls.dtype == "f2" and level.dtype != np.float16:  # else GL converts: half to float exactly
                level = level.astype(np.float16)
            self._gl.write_cube_layers(cls.glo, n, 6 * layer, level,
                                       f"level {n} of cube map {file} (face size {cls.size})")
        return k

    def _upload_array(self, cls: CubeClass, pixels: np.ndarray, what: str) -> int:
        """A new cube-map array for class `cls` holding `pixels`, (layers x 6, S, S, 4) float16 or
        float32 (layer-face = layer * 6 + face, rows from t = 0; S = cls.size), RGBA16F or RGBA32F to
        match, with its cls.levels MIP levels (shaders/cube_mips.comp); a GlintError (GL_OUT_OF_MEMORY
        among them) deletes it again."""
        gl, depth, size, levels = self._gl, pixels.shape[0], cls.size, cls.levels
        half = pixels.dtype == np.float16
        internal = GL_RGBA16F if half else GL_RGBA32F
        name = gl.allocate_cube_array(size, depth, levels, internal, what)
        try:
            gl.write_cube_layers(name, 0, 0, pixels, what)
            key = "f2" if half else "f4"
            if key not in self._mip_programs:
                self._mip_programs[key] = compute_program(self.ctx, "cube_mips.comp",
                                                          {} if half else {"CUBE_MIPS_FLOAT": 1})
            program = self._mip_programs[key]
            with gl.checked(f"the MIP levels of {what}"):
                for level in range(1, levels):
                    s = size >> level
                    gl.bind_cube_array_image(MIP_SOURCE_IMAGE, name, level - 1, internal, write=False)
                    gl.bind_cube_array_image(MIP_TARGET_IMAGE, name, level, internal, write=True)
                    set_uniforms(program, size=s)
                    program.run(-(-s // LOCAL_SIZE), -(-s // LOCAL_SIZE), depth)
                    self.ctx.memory_barrier(moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT)
                self.ctx.memory_barrier(moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.TEXTURE_UPDATE_BARRIER_BIT)
        except GlintError:
            gl.delete_textures([name])
            raise
        return name

    def _widen(self, cls: CubeClass) -> None:
        """Class `cls` as RGBA32F: its level 0 read back, uploaded again (the MIP chain regenerated)."""
        pixels = np.zeros((len(cls.probes) * 6, cls.size, cls.size, 4), np.float32)
        self._gl.read_cube_array(cls.glo, 0, pixels, f"the cube maps of face size {cls.size}")
        cls.dtype = "f4"
        glo = self._upload_array(cls, pixels, f"the cube maps of face size {cls.size} ({len(cls.probes)} "
                                              f"probes, RGBA32F, {cls.mib:.0f} MiB)")
        self._gl.delete_textures([cls.glo])
        cls.glo = glo

    def defines(self, first_unit: int) -> dict:
        """For shaders/cubemaps.glsl: CUBE_CLASSES, the length of its sampler array (at least 1),
        CUBE_FIRST_UNIT, the texture unit of class 0 (class k is on first_unit + k), and CUBE_OBJECTS,
        0 where no object has a cube map (`has_cube_map` is then a constant); for shaders/volume.glsl
        CUBE_VOLUMES, 0 where no object is a glass solid (the volume code is then left out). Both are
        fixed for the renderer's life: the object table is made once, in __init__ (llvmpipe runs both
        sides of every branch; docs/VIEWER.md, "The specular pass: one program per mode and kind")."""
        return {"CUBE_CLASSES": max(len(self.classes), 1), "CUBE_FIRST_UNIT": int(first_unit),
                "CUBE_OBJECTS": int(self.objects > 0),
                "CUBE_VOLUMES": int(bool(np.any(self.table["volume"][:, 3] > 0.0)))}

    def bind(self, program, first_unit: int) -> int:
        """Bind every class to units first_unit, first_unit + 1, ... (as `defines` told the
        shader) and set the face-size uniforms of `program` (if given); returns how many cube
        maps are bound (0: none, and nothing is bound)."""
        if not self.classes:
            return 0
        gl = self._gl
        # Global GL state that moderngl's own contexts start with; a window's context may not,
        # and the filtered look-ups across face edges rely on it: set it every time, cheaply.
        gl.Enable(GL_TEXTURE_CUBE_MAP_SEAMLESS)
        gl.bind_cube_arrays(first_unit, [cls.glo for cls in self.classes])
        if program is not None and "cube_face_size" in program:  # an array (also of length 1): raw bytes
            program["cube_face_size"].write(np.array([c.size for c in self.classes], np.float32).tobytes())
        return self.count

    def bind_buffers(self) -> None:
        self.object_buffer.bind_to_storage_buffer(CUBE_OBJECT_BINDING)
        self.plane_buffer.bind_to_storage_buffer(BOUNDING_PLANE_BINDING)

    def has_cubemap(self, obj: int) -> bool:
        return 0 <= obj < len(self.table) and int(self.table[obj]["info"][0]) >= 0

    def describe(self) -> list[dict]:
        return [{"size": c.size, "layers": len(c.probes), "format": "RGBA16F" if c.dtype == "f2" else "RGBA32F",
                 "mip_levels": c.levels, "mib": round(c.mib, 3)} for c in self.classes]

    def memory(self) -> dict:
        """Probes, the objects they serve, their MiB on the GPU, and the driver's free memory in MiB
        where it tells (None elsewhere, e.g. Mesa)."""
        return {"probes": self.count, "objects": self.objects, "classes": len(self.classes),
                "mib": round(sum(c.mib for c in self.classes), 3), "gpu_free_mib": gpu_free_mib(self.ctx)}

    def release(self) -> None:
        if self._gl is not None:
            self._gl.delete_textures([cls.glo for cls in self.classes])
            for cls in self.classes:
                cls.glo = 0
        for program in self._mip_programs.values():
            program.release()
        self._mip_programs.clear()
        self.object_buffer.release()
        self.plane_buffer.release()


def gl_limits(ctx: moderngl.Context) -> dict:
    """fit_classes' limits of `ctx`: probes per cube-map array, classes the shading programs can
    bind (each class on two units, viewer/gl_bindings.py `shading_units`), largest face."""
    info = ctx.info
    units = min(int(info.get("GL_MAX_COMPUTE_TEXTURE_IMAGE_UNITS", 16)),
                int(info.get("GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS", 16)))
    max_classes = 1
    while shading_units(max_classes + 1)["UNIT_COUNT"] <= units:
        max_classes += 1
    return {"per_class": max(int(info.get("GL_MAX_ARRAY_TEXTURE_LAYERS", 2048)) // 6, 1),
            "max_classes": max_classes, "max_face": int(info.get("GL_MAX_CUBE_MAP_TEXTURE_SIZE", 16384))}


def gpu_free_mib(ctx: moderngl.Context) -> float | None:
    """Free GPU memory in MiB as the driver tells it (NVIDIA, AMD extensions); None otherwise."""
    extensions = ctx.extensions
    for extension, enum in (("GL_NVX_gpu_memory_info", GL_GPU_MEMORY_INFO_CURRENT_AVAILABLE_VIDMEM_NVX),
                            ("GL_ATI_meminfo", GL_TEXTURE_FREE_MEMORY_ATI)):
        if extension in extensions:
            gl = GL(ctx)
            out = (ctypes.c_int * 4)()
            with gl.checked(f"query the free GPU memory ({extension})"):
                gl.GetIntegerv(enum, out)
            return round(out[0] / 1024, 1)
    return None


def _material_volume(manifest: Manifest, entry: ObjectEntry) -> Volume | None:
    materials = manifest.materials
    k = int(entry.material)
    return materials[k].volume if 0 <= k < len(materials) else None


def _finite(v) -> np.ndarray:
    return np.nan_to_num(np.asarray(v, np.float64).reshape(3), nan=0.0, posinf=0.0, neginf=0.0)


def _finite_scalar(v) -> float:
    return float(np.nan_to_num(np.float64(v), nan=0.0, posinf=0.0, neginf=0.0))


def _planes(entries: list) -> list:
    """Bounding planes as PLANE_DTYPE rows; ones with a zero or non-finite normal are dropped."""
    rows = []
    for plane in entries[:MAX_PLANES]:
        point, normal = _finite(plane.point), _finite(plane.normal)
        length = float(np.linalg.norm(normal))
        if not length > 1e-12:
            continue
        row = np.zeros((), PLANE_DTYPE)
        row["point"][:3], row["normal"][:3] = point, normal / length
        rows.append(row)
    return rows
