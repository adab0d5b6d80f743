"""Per-object cube maps on the GPU (section 4.4.1): the incident light of a curved or
transmissive object, as seen from its bounding-box centre, plus its bounding planes.

    cubes = CubeMaps(ctx, bake)     # every manifest object with a `cubemap` entry
    cubes.defines()                 # {"CUBE_CLASSES": k}: shaders/cubemaps.glsl's sampler array
    cubes.bind(program, first_unit) # cube-map arrays on texture units, face sizes as uniforms
    cubes.bind_buffers()            # per-object table and bounding planes (storage buffers)

Cube maps differ in size (the bake picks one per object), and a cube-map *array*
needs one size, so they are grouped into size classes: one `samplerCubeArray`
per distinct face size (several where one size has more maps than an array has
layers), an object's map is one layer of its class. Per object a
storage buffer row (`CUBE_OBJECT_DTYPE`) says where: class (-1: no cube map),
layer, and its bounding planes' range; the planes (point, unit normal) follow in
a second buffer. Objects without a cube map (diffuse, planar) cost nothing.

Every class has a full MIP chain (GL's glGenerateMipmap: 2 x 2 box filter per
level), GL_LINEAR_MIPMAP_LINEAR, and GL_TEXTURE_CUBE_MAP_SEAMLESS is on, so the
filtered look-ups of Eq. 4.14-4.17 blend across face edges. Texels are RGBA16F,
or RGBA32F for a class where a value does not fit in half float (a very bright
emitter must not turn into Inf; docs/ARCHITECTURE.md, "Numerics"). Alpha is the bake's
distance from the centre; the shaders read only rgb.

moderngl (5.13) has no cube-map arrays, so the few GL calls they need go through
ctypes to the context's own function pointers (viewer/gl.py).

The file layout (`read_cubemap`) is the bake's (bake/cubemap.py): one OpenEXR
per object, the six faces stacked vertically in GL order +X, -X, +Y, -Y, +Z, -Z,
each face S x S with its first row at GL's t = 0 and its first column at s = 0
(the order glTexImage3D takes), so a look-up `texture(cube, dir)` returns the
radiance seen along dir.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import moderngl
import numpy as np

from glint.core.constants import HALF_MAX
from glint.core.errors import GlintError
from glint.core.geometry import oriented_box
from glint.core.image_io import read_image
from glint.viewer.gl import GL, GL_TEXTURE_CUBE_MAP_SEAMLESS
from glint.viewer.gl_bindings import BOUNDING_PLANE_BINDING, CUBE_OBJECT_BINDING

FACES = ("+x", "-x", "+y", "-y", "+z", "-z")  # GL's face order (GL_TEXTURE_CUBE_MAP_POSITIVE_X + k)
MAX_PLANES = 16  # per object; more are ignored (each is a ray-plane test per sample)

# Per object (std430): xyz projection centre, w unused; class (-1: none), layer, first plane, plane count;
# a glass solid's (shaders/volume.glsl) half extents of its oriented box (core/geometry.py oriented_box)
# and thickness (w), its absorption sigma_a (rgb, 1/m) and ior (a; 0: not a solid), and the box's
# axes (xyz of the three rows) with its centre (their w).
CUBE_OBJECT_DTYPE = np.dtype([("centre", "<f4", 4), ("info", "<i4", 4), ("extent", "<f4", 4), ("volume", "<f4", 4),
                              ("box", "<f4", (3, 4))])
PLANE_DTYPE = np.dtype([("point", "<f4", 4), ("normal", "<f4", 4)])


def read_cubemap(path: str | Path) -> np.ndarray:
    """The one reader of the bake's cube-map files: (6, S, S, 4) float32 in GL face order, each
    face's row 0 at t = 0 (see the module docstring); alpha = 1 where the file has none.
    Non-finite or negative radiance becomes 0."""
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
            volume = _material_volume(bake.manifest, entry)
            if volume:  # a glass solid: bake/pipeline.py's `volume` entry of its material
                centre, axes, half = oriented_box(
                    np.nan_to_num(np.asarray(bake.meshes[i]["positions"], np.float64), posinf=0.0, neginf=0.0))
                table[i]["extent"][:3] = half
                table[i]["box"][:, :3] = axes
                table[i]["box"][:, 3] = centre
                table[i]["extent"][3] = max(_finite_scalar(volume.get("thickness", 0.0)), 0.0)
                table[i]["volume"][:3] = np.clip(_finite(volume.get("absorption", (0, 0, 0))), 0.0, HALF_MAX)
                table[i]["volume"][3] = max(_finite_scalar(volume.get("ior", 1.5)), 1.0)
            rows = _planes(cube.get("bounding_planes") or [])
            table[i]["info"][2:] = (len(planes), len(rows))
            planes.extend(rows)
        sizes = sorted({f.shape[1] for f in faces.values()})
        # A cube-map array holds at most GL_MAX_ARRAY_TEXTURE_LAYERS / 6 maps (341 on llvmpipe):
        # a size with more objects gets several classes.
        per_class = max(int(ctx.info.get("GL_MAX_ARRAY_TEXTURE_LAYERS", 2048)) // 6, 1)
        self.classes = [CubeClass(s, "f2", same[k:k + per_class]) for s in sizes
                        for same in [[i for i, f in faces.items() if f.shape[1] == s]]
                        for k in range(0, len(same), per_class)]
        for k, cls in enumerate(self.classes):
            for layer, i in enumerate(cls.objects):
                table[i]["info"][:2] = (k, layer)
        self.table = table
        self.object_buffer = ctx.buffer(table.tobytes())
        plane_rows = np.array(planes, PLANE_DTYPE) if planes else np.zeros(1, PLANE_DTYPE)
        self.plane_buffer = ctx.buffer(plane_rows.tobytes())
        self.count = len(faces)
        self._gl = GL(ctx) if faces else None
        for cls in self.classes:
            self._upload(cls, [faces[i] for i in cls.objects])

    # -- GL ---------------------------------------------------------------------------------------
    def _upload(self, cls: CubeClass, maps: list[np.ndarray]) -> None:
        data = np.stack(maps).reshape(len(maps) * 6, cls.size, cls.size, 4)  # layer-face = layer * 6 + face
        cls.dtype = "f2" if float(data.max(initial=0.0)) <= HALF_MAX else "f4"
        pixels = np.ascontiguousarray(data, np.float16 if cls.dtype == "f2" else np.float32)
        cls.glo = self._gl.upload_cube_array(
            pixels, f"the cube maps of face size {cls.size} ({len(maps)} objects, "
                    f"{'RGBA16F' if cls.dtype == 'f2' else 'RGBA32F'}, {pixels.nbytes * 4 / 3 / 2**20:.0f} MiB)")

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
        return [{"size": c.size, "layers": len(c.objects), "format": "RGBA16F" if c.dtype == "f2" else "RGBA32F",
                 "mip_levels": c.levels} for c in self.classes]

    def release(self) -> None:
        if self._gl is not None:
            self._gl.delete_textures([cls.glo for cls in self.classes])
            for cls in self.classes:
                cls.glo = 0
        self.object_buffer.release()
        self.plane_buffer.release()


def _material_volume(manifest: dict, entry: dict) -> dict | None:
    materials = manifest.get("materials") or []
    k = int(entry.get("material", -1))
    return materials[k].get("volume") if 0 <= k < len(materials) else None


def _finite(v) -> np.ndarray:
    return np.nan_to_num(np.asarray(v, np.float64).reshape(3), nan=0.0, posinf=0.0, neginf=0.0)


def _finite_scalar(v) -> float:
    return float(np.nan_to_num(np.float64(v), nan=0.0, posinf=0.0, neginf=0.0))


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
