"""Per-object cube maps on the GPU (section 4.4.1): the incident light of a curved or
transmissive object, as seen from its bounding-box centre, plus its bounding planes.

    cubes = CubeMaps(ctx, bake)     # every manifest object with a `cubemap` entry
    cubes.defines()                 # {"CUBE_CLASSES": k}: shaders/cubemaps.glsl's sampler array
    cubes.bind(program, first_unit) # cube-map arrays on texture units, face sizes as uniforms
    cubes.bind_buffers()            # per-object table and bounding planes (storage buffers)

Cube maps differ in size (the bake picks one per object), and a cube-map *array*
needs one size, so they are grouped into size classes: one `samplerCubeArray`
per distinct face size, an object's map is one layer of its class. Per object a
storage buffer row (`CUBE_OBJECT_DTYPE`) says where: class (-1: no cube map),
layer, and its bounding planes' range; the planes (point, unit normal) follow in
a second buffer. Objects without a cube map (diffuse, planar) cost nothing.

Every class has a full MIP chain (GL's glGenerateMipmap: 2 x 2 box filter per
level), GL_LINEAR_MIPMAP_LINEAR, and GL_TEXTURE_CUBE_MAP_SEAMLESS is on, so the
filtered look-ups of Eq. 4.14-4.17 blend across face edges. Texels are RGBA16F,
or RGBA32F for a class where a value does not fit in half float (a very bright
emitter must not turn into Inf; DESIGN.md "Numerics"). Alpha is the bake's
distance from the centre; the shaders read only rgb.

moderngl (5.13) has no cube-map arrays, so the few GL calls they need go through
ctypes to the context's own function pointers (`_GL`).

The file layout (`read_cubemap`) is the bake's (bake/cubemap.py): one OpenEXR
per object, the six faces stacked vertically in GL order +X, -X, +Y, -Y, +Z, -Z,
each face S x S with its first row at GL's t = 0 and its first column at s = 0
(the order glTexImage3D takes), so a look-up `texture(cube, dir)` returns the
radiance seen along dir.
"""
from __future__ import annotations

import ctypes
import ctypes.util
from dataclasses import dataclass
from pathlib import Path

import moderngl
import numpy as np

from glint.core.constants import HALF_MAX
from glint.core.errors import GlintError
from glint.viewer.gl_bindings import BOUNDING_PLANE_BINDING, CUBE_OBJECT_BINDING

FACES = ("+x", "-x", "+y", "-y", "+z", "-z")  # GL's face order (GL_TEXTURE_CUBE_MAP_POSITIVE_X + k)
MAX_PLANES = 16  # per object; more are ignored (each is a ray-plane test per sample)

# Per object (std430): xyz projection centre, w unused; class (-1: none), layer, first plane, plane count.
CUBE_OBJECT_DTYPE = np.dtype([("centre", "<f4", 4), ("info", "<i4", 4)])
PLANE_DTYPE = np.dtype([("point", "<f4", 4), ("normal", "<f4", 4)])

# GL enums (glcorearb.h)
GL_TEXTURE_CUBE_MAP_ARRAY = 0x9009
GL_TEXTURE_CUBE_MAP_SEAMLESS = 0x884F
GL_TEXTURE0 = 0x84C0
GL_TEXTURE_MIN_FILTER, GL_TEXTURE_MAG_FILTER = 0x2801, 0x2800
GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T, GL_TEXTURE_WRAP_R = 0x2802, 0x2803, 0x8072
GL_LINEAR, GL_LINEAR_MIPMAP_LINEAR, GL_CLAMP_TO_EDGE = 0x2601, 0x2703, 0x812F
GL_RGBA, GL_RGBA16F, GL_RGBA32F = 0x1908, 0x881A, 0x8814
GL_HALF_FLOAT, GL_FLOAT = 0x140B, 0x1406
GL_UNPACK_ALIGNMENT = 0x0CF5
GL_PIXEL_UNPACK_BUFFER, GL_PIXEL_UNPACK_BUFFER_BINDING = 0x88EC, 0x88EF


def read_cubemap(path: str | Path) -> np.ndarray:
    """The one reader of the bake's cube-map files: (6, S, S, 4) float32 in GL face order, each
    face's row 0 at t = 0 (see the module docstring); alpha = 1 where the file has none.
    Non-finite or negative radiance becomes 0."""
    from glint.core.image_io import read_image

    image = read_image(path, "cube map")
    h, w, c = image.shape
    if h != 6 * w or c < 3:
        raise GlintError(f"{path}: not a cube map (expected 6 faces of S x S stacked vertically, "
                         f"RGB or RGBA; got {w}x{h} with {c} channels); run `glint bake --force`")
    faces = np.ones((6, w, w, 4), np.float32)
    faces[..., :3] = image.reshape(6, w, w, c)[..., :3]
    if c >= 4:
        faces[..., 3] = image.reshape(6, w, w, c)[..., 3]
    return np.clip(np.nan_to_num(faces, nan=0.0, posinf=0.0, neginf=0.0), 0.0, None)


def gl_functions(ctx: moderngl.Context):
    """fn(name, restype, *argtypes) -> a ctypes function for a GL entry point moderngl does not
    wrap, from the context's own loader (EGL or GLX)."""
    loader = getattr(getattr(ctx.mglo, "_context", None), "load_opengl_function", None)
    if loader is None:  # a context moderngl did not create through glcontext
        lib = ctypes.CDLL(ctypes.util.find_library("GL") or "libGL.so.1")
        loader = lambda name: ctypes.cast(getattr(lib, name), ctypes.c_void_p).value  # noqa: E731

    def fn(name, restype, *args):
        address = loader(name)
        if not address:
            raise GlintError(f"OpenGL function {name} is missing; glint needs OpenGL 4.3")
        return ctypes.CFUNCTYPE(restype, *args)(address)

    return fn


class _GL:
    """The GL entry points moderngl does not wrap that the cube maps need."""

    def __init__(self, ctx: moderngl.Context):
        fn = gl_functions(ctx)
        u, i, p = ctypes.c_uint, ctypes.c_int, ctypes.c_void_p

        self.GenTextures = fn("glGenTextures", None, i, ctypes.POINTER(u))
        self.DeleteTextures = fn("glDeleteTextures", None, i, ctypes.POINTER(u))
        self.BindTexture = fn("glBindTexture", None, u, u)
        self.ActiveTexture = fn("glActiveTexture", None, u)
        self.TexImage3D = fn("glTexImage3D", None, u, i, i, i, i, i, i, u, u, p)
        self.TexParameteri = fn("glTexParameteri", None, u, u, i)
        self.GenerateMipmap = fn("glGenerateMipmap", None, u)
        self.PixelStorei = fn("glPixelStorei", None, u, i)
        self.BindBuffer = fn("glBindBuffer", None, u, u)
        self.GetIntegerv = fn("glGetIntegerv", None, u, ctypes.POINTER(i))
        self.Enable = fn("glEnable", None, u)


@dataclass
class CubeClass:
    """All cube maps of one face size: one GL cube-map array, a layer per object."""
    size: int
    dtype: str          # "f2" or "f4"
    objects: list       # manifest object index of each layer
    glo: int = 0

    @property
    def levels(self) -> int:
        return int(np.log2(self.size)) + 1


class CubeMaps:
    def __init__(self, ctx: moderngl.Context, bake):
        self.ctx = ctx
        objects = bake.manifest["objects"]
        table = np.zeros(max(len(objects), 1), CUBE_OBJECT_DTYPE)
        table["info"][:, 0] = -1
        planes: list[np.ndarray] = []
        faces: dict[int, np.ndarray] = {}
        for i, entry in enumerate(objects):
            cube = entry.get("cubemap")
            if not cube:
                continue
            faces[i] = read_cubemap(Path(bake.path) / cube["file"])
            table[i]["centre"][:3] = _finite(cube.get("centre", np.mean(entry["bounds"], axis=0)))
            rows = _planes(cube.get("bounding_planes") or [])
            table[i]["info"][2:] = (len(planes), len(rows))
            planes.extend(rows)
        sizes = sorted({f.shape[1] for f in faces.values()})
        self.classes = [CubeClass(s, "f2", [i for i, f in faces.items() if f.shape[1] == s]) for s in sizes]
        for k, cls in enumerate(self.classes):
            for layer, i in enumerate(cls.objects):
                table[i]["info"][:2] = (k, layer)
        self.table = table
        self.object_buffer = ctx.buffer(table.tobytes())
        plane_rows = np.array(planes, PLANE_DTYPE) if planes else np.zeros(1, PLANE_DTYPE)
        self.plane_buffer = ctx.buffer(plane_rows.tobytes())
        self.count = len(faces)
        self._gl = _GL(ctx) if faces else None
        for cls in self.classes:
            self._upload(cls, [faces[i] for i in cls.objects])

    # -- GL ---------------------------------------------------------------------------------------
    def _upload(self, cls: CubeClass, maps: list[np.ndarray]) -> None:
        gl = self._gl
        data = np.stack(maps).reshape(len(maps) * 6, cls.size, cls.size, 4)  # layer-face = layer * 6 + face
        cls.dtype = "f2" if float(data.max(initial=0.0)) <= HALF_MAX else "f4"
        pixels = np.ascontiguousarray(data, np.float16 if cls.dtype == "f2" else np.float32)
        name = ctypes.c_uint(0)
        gl.GenTextures(1, ctypes.byref(name))
        cls.glo = name.value
        unpack = ctypes.c_int(0)
        gl.GetIntegerv(GL_PIXEL_UNPACK_BUFFER_BINDING, ctypes.byref(unpack))
        gl.BindBuffer(GL_PIXEL_UNPACK_BUFFER, 0)  # read the pixels from client memory
        gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1)
        gl.ActiveTexture(GL_TEXTURE0 + self.ctx.default_texture_unit)
        gl.BindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, cls.glo)
        gl.TexImage3D(GL_TEXTURE_CUBE_MAP_ARRAY, 0, GL_RGBA16F if cls.dtype == "f2" else GL_RGBA32F,
                      cls.size, cls.size, len(maps) * 6, 0, GL_RGBA,
                      GL_HALF_FLOAT if cls.dtype == "f2" else GL_FLOAT, pixels.ctypes.data)
        for key, value in ((GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR), (GL_TEXTURE_MAG_FILTER, GL_LINEAR),
                           (GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE), (GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE),
                           (GL_TEXTURE_WRAP_R, GL_CLAMP_TO_EDGE)):
            gl.TexParameteri(GL_TEXTURE_CUBE_MAP_ARRAY, key, value)
        gl.GenerateMipmap(GL_TEXTURE_CUBE_MAP_ARRAY)
        gl.BindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, 0)
        gl.BindBuffer(GL_PIXEL_UNPACK_BUFFER, unpack.value)

    def defines(self, first_unit: int) -> dict:
        """For shaders/cubemaps.glsl: CUBE_CLASSES, the length of its sampler array (at least 1),
        and CUBE_FIRST_UNIT, the texture unit of class 0 (class k is on first_unit + k)."""
        return {"CUBE_CLASSES": max(len(self.classes), 1), "CUBE_FIRST_UNIT": int(first_unit)}

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
        for k, cls in enumerate(self.classes):
            gl.ActiveTexture(GL_TEXTURE0 + first_unit + k)
            gl.BindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, cls.glo)
        gl.ActiveTexture(GL_TEXTURE0 + self.ctx.default_texture_unit)  # where moderngl expects it
        if program is not None and "cube_face_size" in program:  # an array (also of length 1): raw bytes
            program["cube_face_size"].write(np.array([c.size for c in self.classes], np.float32).tobytes())
        return self.count

    def bind_buffers(self) -> None:
        self.object_buffer.bind_to_storage_buffer(CUBE_OBJECT_BINDING)
        self.plane_buffer.bind_to_storage_buffer(BOUNDING_PLANE_BINDING)

    def has_cubemap(self, obj: int) -> bool:
        return 0 <= obj < len(self.table) and int(self.table[obj]["info"][0]) >= 0

    def describe(self) -> list[dict]:
        return [{"size": c.size, "layers": len(c.objects), "format": "RGBA16F" if c.dtype == "f2" else "RGBA32F",
                 "mip_levels": c.levels} for c in self.classes]

    def release(self) -> None:
        if self._gl is not None:
            for cls in self.classes:
                if cls.glo:
                    self._gl.DeleteTextures(1, ctypes.byref(ctypes.c_uint(cls.glo)))
                    cls.glo = 0
        self.object_buffer.release()
        self.plane_buffer.release()


def _finite(v) -> np.ndarray:
    return np.nan_to_num(np.asarray(v, np.float64).reshape(3), nan=0.0, posinf=0.0, neginf=0.0)


def _planes(entries: list) -> list:
    """Bounding planes as PLANE_DTYPE rows; ones with a zero or non-finite normal are dropped."""
    rows = []
    for plane in entries[:MAX_PLANES]:
        point, normal = _finite(plane["point"]), _finite(plane["normal"])
        length = float(np.linalg.norm(normal))
        if not length > 1e-12:
            continue
        row = np.zeros((), PLANE_DTYPE)
        row["point"][:3], row["normal"][:3] = point, normal / length
        rows.append(row)
    return rows
