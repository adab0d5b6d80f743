"""glTF 2.0 (.gltf + .bin, or .glb) + optional sidecar -> `glint.core.scene.Scene`.

The file is read here, not with `trimesh.load`: trimesh keeps only the first
camera (and drops the camera node's subtree), loses which glTF material and
primitive each geometry came from, skips KHR_lights_punctual, and reports
broken files with assertion errors. glint needs all of that exactly, and one
clear message per broken file. trimesh's reader (trimesh/exchange/gltf) was the
reference for the accessor decoding below.

Conventions:
- One `Object` per (node, triangle primitive), in world space: positions by the
  node's world matrix, normals by its inverse transpose (the cofactor matrix),
  winding reversed where the matrix mirrors (negative determinant, glTF 3.7.4).
  Object.name is the node's name (else its mesh's, else "node<i>"), made unique
  with ".1", ".2", ... across primitives and repeated names.
- Missing normals are computed flat (one normal per face, vertices split), as
  the glTF spec requires of clients; zero-length or non-finite normals are
  replaced by the (area-weighted) face normal. Degenerate triangles are dropped.
- Object.uvs is the base colour texture's set (textureInfo.texCoord, default TEXCOORD_0; else
  the first of the emissive, metallic-roughness, normal and anisotropy textures')
  with its KHR_texture_transform applied: (0, 0) is the top-left of the image, and
  Material.kd_texture row 0 is the image's top row, so texel = (v * H, u * W).
- Object.tangents: glTF TANGENT in world space (w flipped under a mirroring matrix), or None.
- Primitives without a material get "default": a grey (kd 0.8) diffuse material.
- KHR_lights_punctual: intensity is candela (point, spot) or lux (directional);
  with `[lights] units = "photometric"` (default) it is divided by 683 lm/W to
  W/sr and W/m^2. Lights shine along the node's -Z; `range` is ignored with a
  warning (the inverse-square law applies everywhere).
- The base colour texture's glTF sampler (wrapS, wrapT, magFilter NEAREST) is kept in
  Material.kd_wrap / kd_nearest; minFilter is not read.
- COLOR_0 (RGB) is Object.colors; its alpha is warned about as not supported.
- What is not supported (skins, morph targets, animations, ...) is warned about, with a kind where it
  repeats per object or material, and counted in Scene.ignored_features.
- Cameras: every perspective camera on a node (eye = node origin, forward = -Z,
  up = +Y, in world space); orthographic cameras are skipped with a warning.
  The sidecar's [cameras] follow the glTF's.
"""
from __future__ import annotations

import base64
import json
import struct
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import UnidentifiedImageError

from glint.bake.edits import edited_sidecar
from glint.bake.gltf_schema import check_types
from glint.bake.material_mapping import MATERIAL_EXTENSIONS, apply_override, material_from_gltf
from glint.bake.roles import assign_roles
from glint.bake.sidecar import read_sidecar
from glint.bake.texture_image import (
    MAX_DECODE_PIXELS,
    MAX_TEXTURE_PIXELS,
    MAX_TEXTURE_SIDE,
    ImageRefused,
    decode_texture,
)
from glint.bake.validate import (
    add_warning,
    check_finite_positions,
    degenerate_triangles,
    repair_normals,
    validate_scene,
)
from glint.core.errors import GlintError, WarningKind, one_line, summarised
from glint.core.geometry import face_cross
from glint.core.scene import Camera, DirectionalLight, Material, Object, PointLight, Scene, SpotLight

LUMENS_PER_WATT = 683.0  # luminous efficacy that defines the candela
# Compressed geometry is decoded where it is read: KHR_draco_mesh_compression per primitive
# (_SceneBuilder._draco, DracoPy), EXT/KHR_meshopt_compression per bufferView (_view_bytes, meshopt).
MESHOPT = ("EXT_meshopt_compression", "KHR_meshopt_compression")
SUPPORTED_EXTENSIONS = frozenset(("KHR_lights_punctual", "KHR_mesh_quantization", "KHR_texture_transform",
                                  "KHR_draco_mesh_compression") + MESHOPT + MATERIAL_EXTENSIONS)

_CHUNK_JSON, _CHUNK_BIN = 0x4E4F534A, 0x004E4942
_COMPONENTS = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_NORMALIZE = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}
_TYPES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_SINGULAR = {"accessors": "accessor", "bufferViews": "bufferView", "meshes": "mesh",
             "materials": "material", "textures": "texture", "images": "image",
             "cameras": "camera", "nodes": "node"}
_MODES = {0: "points", 1: "lines", 2: "line loop", 3: "line strip", 4: "triangles",
          5: "triangle strip", 6: "triangle fan"}

# Warnings that repeat per object, material, light or camera: one summary line each
# (glint.core.errors.WarningKind), so a scene with hundreds of meshes stays readable.
NOT_TRIANGLES = WarningKind("{n} objects are points or lines, not triangles; skipped")
NON_FINITE_UVS = WarningKind("{n} objects have non-finite texture coordinates, set to 0")
ZERO_AREA = WarningKind("{n} objects have zero-area triangles "
                        "(dropped {dropped:,} of their {triangles:,} triangles)")
NO_AREA = WarningKind("{n} objects have no triangles with area and were skipped")
NO_NORMALS = WarningKind("{n} objects have no normals; using flat face normals")
ZERO_NORMALS = WarningKind("{n} objects have zero-length normals ({normals:,} in all), "
                           "replaced by the face normal")
NO_IMAGE = WarningKind("{n} materials' base colour textures have no PNG/JPEG source; ignored")
UNREADABLE = WarningKind("{n} base colour images cannot be read; their materials use "
                         "baseColorFactor only")
LARGE_IMAGE = WarningKind(f"{{n}} images are larger than glint keeps ({MAX_TEXTURE_PIXELS / 1e6:.1f} Mpx, "
                          f"{MAX_TEXTURE_SIDE} a side); downscaled")
HUGE_IMAGE = WarningKind(f"{{n}} images declare more pixels than glint decodes ({MAX_DECODE_PIXELS / 1e6:.0f} Mpx); "
                         "not read, their materials go without them")
SPOT_CONES = WarningKind("{n} spot lights have cone angles outside 0 <= inner < outer <= pi/2; "
                         "clamped")
ORTHOGRAPHIC = WarningKind("{n} cameras are orthographic; only perspective cameras are "
                           "supported, skipped")
VERTEX_ALPHA = WarningKind("{n} objects have vertex colours (COLOR_0) with alpha below 1; the alpha "
                           "is not supported, ignored")
SKINNED = WarningKind("{n} objects are skinned; skins are not supported, shown as stored "
                      "(the bind pose)")
MORPHED = WarningKind("{n} objects have morph target weights, not supported; shown without "
                      "their morph targets")
SHARED_UVS = WarningKind("{n} materials' emissive, metallic-roughness, normal or anisotropy textures "
                         "use another texture coordinate set than their base colour textures; the base "
                         "colour's is used")
NO_UVS = WarningKind("{n} objects have a textured material but not the texture coordinates "
                     "it names; the texel at (0, 0) is used everywhere")
LIGHT_RANGE = WarningKind("{n} lights have a range, not supported; inverse-square falloff "
                          "everywhere")
# An accessor without a bufferView (zeros, with sparse values on them) and a meshopt bufferView's
# decoded data take their size from a count in the JSON, not from bytes in the file, so a corrupt
# count (2**31) would have numpy or meshopt allocate gigabytes before anything else fails. 256 MiB
# is 22 million float32 VEC3 elements: far past any accessor of a scene glint bakes in a day
# (docs/BAKE.md's largest, the staircase, has 1.1 million vertices). Accessors read from a buffer
# are limited by the file's own bytes instead.
MAX_UNBACKED_BYTES = 256 << 20
_WRAP_MODES = {10497: "REPEAT", 33071: "CLAMP_TO_EDGE", 33648: "MIRRORED_REPEAT"}  # glTF 5.26
_NEAREST = 9728


@dataclass
class GltfDocument:
    """The JSON of a glTF file and its buffers' bytes."""

    path: Path
    json: dict
    buffers: list[bytes] = field(default_factory=list)

    @property
    def source(self) -> str:
        return self.path.name


# --------------------------------------------------------------------------- public


def load_scene(path: Path, edits: list = ()) -> Scene:
    """Read a .glb/.gltf and its sidecar `<stem>.glint.toml` into a checked Scene; `edits`:
    `KEY=VALUE` assignments applied on top of the sidecar (bake/edits.py, `--set`)."""
    path = Path(path)
    # Repeated warnings are summarised when loading ends, or fails (the error comes last).
    with summarised() as record:
        doc = _guarded(path, read_gltf, path)
        side, texts = edited_sidecar(path, edits) if edits else (read_sidecar(path), ())
        scene = _guarded(path, lambda: _SceneBuilder(doc, side).build())
        scene.edits = texts
        scene.ignored_features = record.ignored_features()
    return scene


def _guarded(path: Path, fn, *args):
    """Run fn; a structure the explicit checks did not foresee still gives one line."""
    try:
        return fn(*args)
    except GlintError:
        raise
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as err:
        raise GlintError(f"{path.name}: malformed glTF ({type(err).__name__}: {err})") from err


def read_gltf(path: Path) -> GltfDocument:
    """Parse the container (.glb chunks or .gltf JSON) and load every buffer."""
    path = Path(path)
    if not path.exists():
        raise GlintError(f"{path}: no such file")
    if not path.is_file():
        raise GlintError(f"{path}: not a file")
    data = path.read_bytes()
    name = path.name
    binary = None
    if data[:4] == b"glTF":
        text, binary = _split_glb(data, name)
    elif path.suffix.lower() == ".glb":
        raise GlintError(f"{name}: not a binary glTF file (it does not start with 'glTF')")
    else:
        text = data
    try:
        tree = json.loads(text.decode("utf-8-sig"))
    except UnicodeDecodeError:
        raise GlintError(f"{name}: malformed glTF: the JSON is not UTF-8 text") from None
    except json.JSONDecodeError as err:
        raise GlintError(f"{name}: malformed glTF: invalid JSON at line {err.lineno}, "
                         f"column {err.colno}: {err.msg}") from None
    if not isinstance(tree, dict):
        raise GlintError(f"{name}: malformed glTF: the JSON is not an object")
    asset = tree.get("asset")
    version = str(asset.get("version", "2.0")) if isinstance(asset, dict) else "2.0"
    if not version.startswith("2"):
        raise GlintError(f"{name}: glTF version {version} is not supported (need 2.0)")
    check_types(tree, name)
    doc = GltfDocument(path=path, json=tree)
    for i, buf in enumerate(_list(tree, "buffers", name)):
        doc.buffers.append(_buffer_bytes(buf, i, path, binary))
    return doc


def node_world_matrices(tree: dict, source: str = "glTF") -> dict[int, list[np.ndarray]]:
    """Node index -> world matrices (4x4, one per path from the scene's roots)."""
    nodes = tree.get("nodes", [])
    scenes = tree.get("scenes")
    if scenes:
        scene_index = tree.get("scene", 0)
        if not 0 <= scene_index < len(scenes):
            raise GlintError(f"{source}: malformed glTF: scene {scene_index} does not exist")
        roots = list(scenes[scene_index].get("nodes", []))
    else:  # no scenes: every node that is nobody's child is a root
        children = {c for n in nodes for c in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    out: dict[int, list[np.ndarray]] = {}

    def visit(index: int, parent: np.ndarray, path: tuple):
        if not isinstance(index, int) or not 0 <= index < len(nodes):
            raise GlintError(f"{source}: malformed glTF: node {index} does not exist")
        if index in path:
            raise GlintError(f"{source}: malformed glTF: node {index} is its own ancestor")
        world = parent @ local_matrix(nodes[index], f"{source}: node {index}")
        out.setdefault(index, []).append(world)
        for child in nodes[index].get("children", []):
            visit(child, world, path + (index,))

    for root in roots:
        visit(root, np.eye(4), ())
    return out


def local_matrix(node: dict, where: str = "node") -> np.ndarray:
    """A node's local 4x4 matrix: `matrix` (column-major) or T * R * S."""
    if "matrix" in node:
        m = np.asarray(node["matrix"], np.float64)
        if m.shape != (16,):
            raise GlintError(f"{where}: malformed glTF: matrix must have 16 numbers")
        return m.reshape(4, 4).T
    t = np.asarray(node.get("translation", [0, 0, 0]), np.float64)
    q = np.asarray(node.get("rotation", [0, 0, 0, 1]), np.float64)
    s = np.asarray(node.get("scale", [1, 1, 1]), np.float64)
    if t.shape != (3,) or q.shape != (4,) or s.shape != (3,):
        raise GlintError(f"{where}: malformed glTF: translation/rotation/scale have wrong length")
    m = np.eye(4)
    m[:3, :3] = quaternion_matrix(q) * s  # R @ diag(s)
    m[:3, 3] = t
    return m


def quaternion_matrix(q) -> np.ndarray:
    """Rotation matrix of a glTF (x, y, z, w) quaternion (normalised first).

    Not pyrr.matrix33.create_from_quaternion: equal within 1e-15, but different in the last bit
    for 92 % of random quaternions, which would change every baked vertex position's bytes."""
    q = np.asarray(q, np.float64)
    norm = np.linalg.norm(q)
    x, y, z, w = q / norm if norm > 0 else (0.0, 0.0, 0.0, 1.0)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB transfer function, inverted (IEC 61966-2-1)."""
    c = np.asarray(c, np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


# --------------------------------------------------------------------------- container


def _split_glb(data: bytes, name: str) -> tuple[bytes, bytes | None]:
    """GLB = 12-byte header + JSON chunk + optional BIN chunk (glTF 2.0 section 4.4)."""
    if len(data) < 20:
        raise GlintError(f"{name}: truncated .glb: only {len(data)} bytes")
    _, version, length = struct.unpack_from("<III", data, 0)
    if version != 2:
        raise GlintError(f"{name}: .glb container version {version} is not supported (need 2)")
    if length > len(data):
        raise GlintError(f"{name}: truncated .glb: the header says {length} bytes, "
                         f"the file has {len(data)}")
    text, binary, offset = None, None, 12
    while offset + 8 <= length:
        chunk_length, chunk_type = struct.unpack_from("<II", data, offset)
        start, end = offset + 8, offset + 8 + chunk_length
        if end > length:
            raise GlintError(f"{name}: truncated .glb: a chunk runs past the end of the file "
                             f"(bytes {start}..{end} of {length})")
        if text is None:
            if chunk_type != _CHUNK_JSON:
                raise GlintError(f"{name}: malformed .glb: the first chunk is not JSON")
            text = data[start:end]
        elif chunk_type == _CHUNK_BIN and binary is None:
            binary = data[start:end]
        offset = end
    if text is None:
        raise GlintError(f"{name}: malformed .glb: no JSON chunk")
    return text, binary


def _buffer_bytes(buf: dict, i: int, path: Path, binary: bytes | None) -> bytes:
    name = path.name
    length = buf.get("byteLength")
    if not isinstance(length, int) or length < 0:
        raise GlintError(f"{name}: malformed glTF: buffer {i} has no valid byteLength")
    uri = buf.get("uri")
    fallback = any((buf.get("extensions") or {}).get(e, {}).get("fallback") for e in MESHOPT)
    if uri is None and fallback and (binary is None or i != 0):
        # EXT_meshopt_compression: a fallback buffer may have no data; only the compressed
        # bufferViews (whose extension names another buffer) refer to it, and are decoded.
        return b""
    if uri is None:
        if binary is None or i != 0:
            raise GlintError(f"{name}: malformed glTF: buffer {i} has no uri and there is "
                             f"no binary chunk for it")
        data = binary
    elif uri.startswith("data:"):
        try:
            data = base64.b64decode(uri.split(",", 1)[1], validate=False)
        except (IndexError, ValueError):
            raise GlintError(f"{name}: malformed glTF: buffer {i} has a bad data: URI") from None
    else:
        file = path.parent / urllib.parse.unquote(uri)
        if not file.is_file():
            raise GlintError(f"{name}: buffer {i} file '{uri}' is missing (looked for {file})")
        data = file.read_bytes()
    if len(data) < length:
        raise GlintError(f"{name}: buffer {i} is truncated: {len(data)} bytes, "
                         f"byteLength says {length}")
    return data[:length]


def _list(tree: dict, key: str, source: str) -> list:
    value = tree.get(key, [])
    if not isinstance(value, list):
        raise GlintError(f"{source}: malformed glTF: '{key}' must be a list")
    return value


# --------------------------------------------------------------------------- scene


class _SceneBuilder:
    def __init__(self, doc: GltfDocument, side):
        self.doc, self.side, self.tree = doc, side, doc.json
        self.source = doc.source
        self.warnings: list[str] = []
        self._accessors: dict[int, np.ndarray] = {}
        self._decoded: dict[int, bytes] = {}  # meshopt-compressed bufferViews, decoded
        # image -> pixels as stored; (image, srgb) -> pixels as a material reads them
        self._images: dict = {}
        self._names: set[str] = set()

    def build(self) -> Scene:
        doc, side = self.doc, self.side
        scene = Scene(name=doc.path.stem, source=doc.path, sidecar=side.path,
                      bake_settings=dict(side.bake), sky=side.sky,
                      camera_paths=list(side.camera_paths))
        self._check_extensions()
        animations = len(_list(self.tree, "animations", self.source))
        if animations:
            self.warn(f"{self.source}: {animations} animation(s) not played; the scene is shown "
                      "as stored", ignored={"animations": animations})
        worlds = node_world_matrices(self.tree, self.source)
        scene.materials = self._materials()
        aliases = self._objects(scene, worlds)
        self._lights(scene, worlds)
        self._cameras(scene, worlds)
        self._check_material_names()
        assign_roles(scene, self._role_overrides(scene, aliases))
        options = self._object_options(scene, aliases)
        for obj in scene.objects:
            obj.options = options.get(obj.name, {})
        scene.warnings = list(side.warnings) + self.warnings
        validate_scene(scene)
        return scene

    def warn(self, message: str, kind: WarningKind | None = None, subject: str | None = None,
             **how) -> None:
        add_warning(self.warnings, message, kind, subject, **how)

    def bad(self, message: str) -> GlintError:
        return GlintError(f"{self.source}: malformed glTF: {message}")

    def item(self, key: str, index, what: str) -> dict:
        items = _list(self.tree, key, self.source)
        if not isinstance(index, int) or not 0 <= index < len(items):
            raise self.bad(f"{what} refers to {_SINGULAR.get(key, key)} {index}, "
                           "which does not exist")
        return items[index]

    # ---- extensions

    def _check_extensions(self):
        required = set(self.tree.get("extensionsRequired", [])) - SUPPORTED_EXTENSIONS
        if required:
            raise GlintError(f"{self.source}: requires glTF extension(s) "
                             f"{', '.join(sorted(required))} that glint does not support; "
                             "export again without them")
        used = set(self.tree.get("extensionsUsed", [])) - SUPPORTED_EXTENSIONS
        if used:
            self.warn(f"{self.source}: glTF extension(s) {', '.join(sorted(used))} not "
                      f"supported, ignored",
                      ignored={ext: max(_uses(self.tree, ext), 1) for ext in sorted(used)})

    # ---- accessors

    def accessor(self, index, what: str) -> np.ndarray:
        """(count, components) array: float64 for float/normalised data, else integers."""
        if index in self._accessors:
            return self._accessors[index]
        a = self.item("accessors", index, what)
        where = f"accessor {index} ({what})"
        ctype, atype, count = a.get("componentType"), a.get("type"), a.get("count")
        if ctype not in _COMPONENTS or atype not in _TYPES:
            raise self.bad(f"{where} has componentType {ctype!r} / type {atype!r}")
        if not isinstance(count, int) or count < 0:
            raise self.bad(f"{where} has an invalid count {count!r}")
        ncomp = _TYPES[atype]
        if "bufferView" in a:
            data = self._read_view(a["bufferView"], a.get("byteOffset", 0), count, ctype,
                                   ncomp, where)
        else:  # all zeros unless sparse values replace some
            size = count * ncomp * np.dtype(_COMPONENTS[ctype]).itemsize
            if size > MAX_UNBACKED_BYTES:
                raise self.bad(f"{where} has no bufferView and a count of {count:,}: {_mib(size)} of zeros, "
                               f"more than glint makes without data in the file ({_mib(MAX_UNBACKED_BYTES)})")
            data = np.zeros((count, ncomp), _COMPONENTS[ctype])
        if "sparse" in a:
            sp = a["sparse"]
            n, si, sv = sp.get("count"), sp.get("indices", {}), sp.get("values", {})
            if not isinstance(n, int) or n < 0:
                raise self.bad(f"{where} has an invalid sparse count")
            idx = self._read_view(si.get("bufferView"), si.get("byteOffset", 0), n,
                                  si.get("componentType"), 1, f"{where} sparse indices")
            val = self._read_view(sv.get("bufferView"), sv.get("byteOffset", 0), n, ctype,
                                  ncomp, f"{where} sparse values")
            idx = idx.reshape(-1).astype(np.int64)
            if idx.size and (idx.min() < 0 or idx.max() >= count):
                raise self.bad(f"{where} has sparse indices out of range")
            data = data.copy()
            data[idx] = val
        if a.get("normalized") and ctype in _NORMALIZE:
            data = np.maximum(data / _NORMALIZE[ctype], -1.0)
        elif ctype == 5126:
            data = data.astype(np.float64)
        self._accessors[index] = data
        return data

    def _read_view(self, view_index, start, count: int, ctype, ncomp: int,
                   where: str) -> np.ndarray:
        """`count` elements of `ncomp` components from a bufferView, honouring byteStride."""
        if ctype not in _COMPONENTS:
            raise self.bad(f"{where} has componentType {ctype!r}")
        view = self.item("bufferViews", view_index, where)
        buffer, v0, vlen = self._view_bytes(view_index, view)
        dtype = np.dtype(_COMPONENTS[ctype])
        elem = dtype.itemsize * ncomp
        stride = view.get("byteStride") or elem
        need = 0 if count == 0 else start + (count - 1) * stride + elem
        if not isinstance(start, int) or start < 0 or stride < elem or need > vlen:
            raise self.bad(f"{where} needs {need} bytes of bufferView {view_index}, "
                           f"which has {vlen}")
        if count == 0:
            return np.zeros((0, ncomp), dtype)
        raw = np.frombuffer(buffer, np.uint8, count=vlen, offset=v0)
        rows = np.lib.stride_tricks.as_strided(raw[start:], (count, elem), (stride, 1))
        return np.ascontiguousarray(rows).view(dtype).reshape(count, ncomp)

    def _view_bytes(self, view_index: int, view: dict) -> tuple[bytes, int, int]:
        """(buffer, byteOffset, byteLength) of a bufferView, decoded first where compressed."""
        ext = next(((e, view["extensions"][e]) for e in MESHOPT
                    if e in (view.get("extensions") or {})), None)
        if ext is None:
            return self._slice(view, f"bufferView {view_index}")
        if view_index not in self._decoded:
            self._decoded[view_index] = self._meshopt(view_index, view, *ext)
        data = self._decoded[view_index]
        return data, 0, len(data)

    def _slice(self, view: dict, what: str) -> tuple[bytes, int, int]:
        buffer = self.doc.buffers[self._index(view.get("buffer"), len(self.doc.buffers),
                                              what, "buffer")]
        v0, vlen = view.get("byteOffset", 0), view.get("byteLength", -1)
        if not (isinstance(v0, int) and isinstance(vlen, int) and 0 <= v0 and 0 <= vlen
                and v0 + vlen <= len(buffer)):
            raise self.bad(f"{what} (bytes {v0}+{vlen}) lies outside its "
                           f"buffer of {len(buffer)} bytes")
        return buffer, v0, vlen

    def _meshopt(self, view_index: int, view: dict, name: str, ext: dict) -> bytes:
        """EXT_meshopt_compression / KHR_meshopt_compression: the bufferView's bytes, decoded.

        The extension names the compressed bytes (buffer, byteOffset, byteLength) and what they
        decode to: `count` elements of `byteStride` bytes, with a `mode` (ATTRIBUTES, TRIANGLES,
        INDICES) and an optional `filter` (NONE, OCTAHEDRAL, QUATERNION, EXPONENTIAL; COLOR in
        KHR_). The decoded data then stands for the whole bufferView (the spec: byteLength of the
        view is count * byteStride)."""
        where = f"bufferView {view_index} ({name})"
        try:
            import meshopt
        except ImportError:
            raise GlintError(f"{self.source}: {where} is meshopt-compressed; reading it needs the "
                             "Python package meshopt (pip install meshopt)") from None
        buffer, v0, vlen = self._slice(ext, where)
        count, stride = ext.get("count"), ext.get("byteStride")
        mode, filt = ext.get("mode"), ext.get("filter", "NONE")
        if not (isinstance(count, int) and count >= 0 and isinstance(stride, int) and stride > 0
                and mode in ("ATTRIBUTES", "TRIANGLES", "INDICES")):
            raise self.bad(f"{where} has count {count!r}, byteStride {stride!r}, mode {mode!r}")
        if count * stride > MAX_UNBACKED_BYTES:
            raise self.bad(f"{where} decodes to {count:,} elements of {stride} bytes ({_mib(count * stride)}), "
                           f"more than glint decodes for one bufferView ({_mib(MAX_UNBACKED_BYTES)})")
        try:
            rows = meshopt.decode_gltf_buffer(bytes(buffer[v0:v0 + vlen]), count, stride, mode,
                                              None if filt == "NONE" else filt)
        except (ValueError, RuntimeError) as err:
            raise GlintError(f"{self.source}: {where} cannot be decoded ({err}); the file is "
                             "corrupt or truncated") from None
        return np.ascontiguousarray(rows).tobytes()

    def _draco(self, prim: dict, node_name: str, what: str) -> dict:
        """KHR_draco_mesh_compression: decode the primitive's Draco bufferView into the accessors.

        The extension's `attributes` map each semantic (POSITION, NORMAL, TEXCOORD_0, ...) to the
        Draco attribute's unique id; the primitive's own `attributes` and `indices` accessors keep
        count, type and normalisation, and have no bufferView (spec). The decoded arrays go into
        the accessor cache, so the rest of the loader reads them like any accessor. Draco stores
        triangle lists, so the primitive is read as mode 4 (TRIANGLES)."""
        ext = (prim.get("extensions") or {}).get("KHR_draco_mesh_compression")
        if ext is None:
            return prim
        where = f"object '{node_name}' {what} (KHR_draco_mesh_compression)"
        try:
            import DracoPy
        except ImportError:
            raise GlintError(f"{self.source}: {where} needs the Python package DracoPy "
                             "(pip install DracoPy)") from None
        view_index = ext.get("bufferView")
        buffer, v0, vlen = self._view_bytes(view_index, self.item("bufferViews", view_index, where))
        try:
            mesh = DracoPy.decode(bytes(buffer[v0:v0 + vlen]))
        except Exception as err:  # DracoPy raises FileTypeException, ValueError, ... (not documented)
            raise GlintError(f"{self.source}: {where}: the Draco data cannot be decoded "
                             f"({type(err).__name__}: {err}); the file is corrupt or truncated") from None
        faces = getattr(mesh, "faces", None)
        if faces is None or len(faces) == 0:
            raise GlintError(f"{self.source}: {where}: the Draco data holds no triangles")
        attrs = prim.get("attributes") or {}
        for semantic, uid in (ext.get("attributes") or {}).items():
            if semantic not in attrs:
                continue
            index = attrs[semantic]
            a = self.item("accessors", index, where)
            got = mesh.get_attribute_by_unique_id(uid) if isinstance(uid, int) else None
            if got is None:
                raise self.bad(f"{where}: {semantic} refers to Draco attribute {uid!r}, which the "
                               "Draco data does not have")
            data = np.asarray(got["data"])
            data = data.reshape(len(data), -1)
            if len(data) != a.get("count") or data.shape[1] != _TYPES.get(a.get("type")):
                raise self.bad(f"{where}: {semantic} decodes to {data.shape[0]} x {data.shape[1]} "
                               f"values; accessor {index} says {a.get('count')} x {a.get('type')}")
            if data.dtype.kind in "iu" and a.get("normalized") and a.get("componentType") in _NORMALIZE:
                data = np.maximum(data / _NORMALIZE[a["componentType"]], -1.0)
            elif data.dtype.kind == "f":
                data = data.astype(np.float64)
            self._accessors[index] = data
        key = prim.get("indices", ("draco", view_index))
        self._accessors[key] = np.asarray(faces, np.int64).reshape(-1, 1)
        return {**prim, "indices": key, "mode": 4}

    def _index(self, value, size: int, what: str, kind: str) -> int:
        if not isinstance(value, int) or not 0 <= value < size:
            raise self.bad(f"{what} refers to {kind} {value}, which does not exist")
        return value

    # ---- materials and textures

    def _materials(self) -> list[Material]:
        side = self.side
        out, names = [], set()
        self._uv_sets: dict[int, tuple[int, np.ndarray | None]] = {}
        self._samplers: dict[int, tuple[tuple[str, str], bool]] = {}
        for i, gm in enumerate(_list(self.tree, "materials", self.source)):
            name = gm.get("name") or f"material{i}"
            names.add(name)
            rgba = self._base_color_texture(gm, name, i)
            emissive = self._shared_uv_texture(gm.get("emissiveTexture"), "emissiveTexture", name, i)
            # Metallic-roughness (glTF 3.9.2), normal (3.9.3) and anisotropy textures are linear data.
            metallic_roughness = self._shared_uv_texture(
                gm.get("pbrMetallicRoughness", {}).get("metallicRoughnessTexture"),
                "metallicRoughnessTexture", name, i, srgb=False)
            normal = self._shared_uv_texture(gm.get("normalTexture"), "normalTexture", name, i, srgb=False)
            anisotropy = self._shared_uv_texture(
                gm.get("extensions", {}).get("KHR_materials_anisotropy", {}).get("anisotropyTexture"),
                "anisotropyTexture", name, i, srgb=False)
            wrap, nearest = self._samplers.get(i, (("REPEAT", "REPEAT"), False))
            out.append(material_from_gltf(
                gm, name, kd_texture=None if rgba is None else np.ascontiguousarray(rgba[..., :3]),
                emission_texture=None if emissive is None else np.ascontiguousarray(emissive[..., :3]),
                alpha_texture=None if rgba is None else np.ascontiguousarray(rgba[..., 3]),
                metallic_roughness_texture=metallic_roughness,
                normal_texture=None if normal is None else np.ascontiguousarray(normal[..., :3]),
                anisotropy_texture=None if anisotropy is None else np.ascontiguousarray(anisotropy[..., :3]),
                diffuse_roughness=side.diffuse_roughness, override=side.materials.get(name),
                warnings=self.warnings, source=self.source))
            # The base colour's sampler; not in material_from_gltf, which sees no textures' JSON.
            out[-1].kd_wrap, out[-1].kd_nearest = wrap, nearest
        self._default_material = None
        self._material_names = names
        return out

    def _default(self, scene: Scene) -> int:
        """Index of the material for primitives without one (added on first use)."""
        if self._default_material is None:
            mat = Material(name="default")
            override = self.side.materials.get("default")
            if override:
                apply_override(mat, override)
            self._material_names.add("default")
            scene.materials.append(mat)
            self._default_material = len(scene.materials) - 1
        return self._default_material

    def _base_color_texture(self, gm: dict, name: str, index: int) -> np.ndarray | None:
        """(H, W, 4) float32: linear RGB and alpha, or None. Records in self._uv_sets[index] the
        texture coordinate set and KHR_texture_transform matrix its primitives' uvs get."""
        info = gm.get("pbrMetallicRoughness", {}).get("baseColorTexture")
        if info is None:
            return None
        where = f"{self.source}: material '{name}'"
        texcoord, matrix = _uv_set(info, where)
        self._uv_sets[index] = (texcoord, matrix)
        tex = self.item("textures", info.get("index"), f"material '{name}' baseColorTexture")
        self._samplers[index] = self._sampler(tex)
        return self._texture_image(tex, "base colour", name, where)

    def _shared_uv_texture(self, info, key: str, name: str, index: int,
                           srgb: bool = True) -> np.ndarray | None:
        """(H, W, 4) float32 of a material texture that shares the object's one uv set: the
        emissiveTexture (glTF 3.9.3: sRGB, multiplies emissiveFactor), the metallicRoughnessTexture,
        the normalTexture and the anisotropyTexture (linear: `srgb` False), or None. It is looked
        up with the base colour's uv set and sampler, the one set an object keeps; when it names
        another set (or transform), that is warned and the base colour's is used. Without a base colour texture
        the first of these textures gives the object its set and sampler."""
        if not isinstance(info, dict):
            return None
        where = f"{self.source}: material '{name}'"
        texcoord, matrix = _uv_set(info, where)
        tex = self.item("textures", info.get("index"), f"material '{name}' {key}")
        if index not in self._uv_sets:
            self._uv_sets[index] = (texcoord, matrix)
            self._samplers[index] = self._sampler(tex)
        else:
            base_set, base_matrix = self._uv_sets[index]
            if base_set != texcoord or not np.array_equal(
                    np.eye(3) if base_matrix is None else base_matrix,
                    np.eye(3) if matrix is None else matrix):
                self.warn(f"{where}: {key} uses another texture coordinate set or "
                          "transform than the base colour texture; the base colour's is used",
                          SHARED_UVS, name)
        return self._texture_image(tex, key, name, where, srgb)

    def _texture_image(self, tex: dict, what: str, name: str, where: str,
                       srgb: bool = True) -> np.ndarray | None:
        """The decoded image of a glTF texture, or None with a warning; `srgb`: the colour is
        sRGB-encoded and decoded to linear (alpha is always linear). Each image is decoded once, and
        converted once per encoding, however many materials use it."""
        source = tex.get("source")
        if source is None:
            self.warn(f"{where}: {what} texture has no PNG/JPEG source; ignored",
                      NO_IMAGE, name, ignored=["textures without a PNG/JPEG source"])
            return None
        if (source, srgb) not in self._images:
            if source not in self._images:
                self._images[source] = self._decode_image(source, where)
            rgba = self._images[source]
            if rgba is not None and srgb:
                # Colour is sRGB-encoded, alpha is linear (glTF 3.9.2 baseColorTexture).
                rgba = np.concatenate([srgb_to_linear(rgba[..., :3]), rgba[..., 3:]], axis=-1)
            self._images[source, srgb] = rgba
        return self._images[source, srgb]

    def _sampler(self, tex: dict) -> tuple[tuple[str, str], bool]:
        """The texture's glTF sampler: ((wrapS, wrapT), magFilter is NEAREST). glTF 5.26: without
        a sampler, or without a wrap, REPEAT; without magFilter, the client's choice (LINEAR).
        minFilter is not read (the viewer mip-maps)."""
        samplers = self.tree.get("samplers", [])
        sampler = {}
        if isinstance(tex.get("sampler"), int) and 0 <= tex["sampler"] < len(samplers):
            # A broken sampler reference is not worth stopping for: the defaults.
            sampler = samplers[tex["sampler"]] if isinstance(samplers[tex["sampler"]], dict) else {}
        wrap = tuple(_WRAP_MODES.get(sampler.get(k), "REPEAT") for k in ("wrapS", "wrapT"))
        return wrap, sampler.get("magFilter") == _NEAREST

    def _decode_image(self, index: int, where: str) -> np.ndarray | None:
        """(H, W, 4) float32 of image `index`, within bake/texture_image.py's limits (a warning when
        shrunk), or None with a warning when it cannot be read or declares too many pixels to decode."""
        image = self.item("images", index, f"{where} texture")
        name = _image_name(image, index)
        try:
            if "bufferView" in image:
                view = self.item("bufferViews", image["bufferView"], f"image {index}")
                buffer = self.doc.buffers[self._index(view.get("buffer"), len(self.doc.buffers),
                                                      f"image {index}", "buffer")]
                start = view.get("byteOffset", 0)
                data = buffer[start:start + view["byteLength"]]
            else:
                uri = image["uri"]
                if uri.startswith("data:"):
                    data = base64.b64decode(uri.split(",", 1)[1])
                else:
                    file = self.doc.path.parent / urllib.parse.unquote(uri)
                    if not file.is_file():  # nor a device (/dev/zero) or a folder
                        raise FileNotFoundError(f"no file {file}")
                    data = file.read_bytes()
            rgba, declared, kept = decode_texture(data)
        except ImageRefused as refused:
            w, h = refused.size
            self.warn(f"{where}: image '{name}' declares {w}x{h} pixels, more than glint decodes "
                      f"({MAX_DECODE_PIXELS / 1e6:.0f} Mpx); not read, the material goes without it",
                      HUGE_IMAGE, name, detail=f"{w}x{h}", ignored=["images too large to decode"])
            return None
        except Exception as err:  # any unreadable image: warn and fall back to the factor
            reason = ("not an image Pillow reads" if isinstance(err, UnidentifiedImageError)
                      else f"{type(err).__name__}: {one_line(err)}")
            self.warn(f"{where}: cannot read base colour texture (image {index}: {reason}); "
                      "using baseColorFactor only", UNREADABLE, name,
                      ignored=["unreadable base colour images"])
            return None
        if kept != declared:
            self.warn(f"{where}: image '{name}' is {declared[0]}x{declared[1]} pixels, more than glint keeps "
                      f"({MAX_TEXTURE_PIXELS / 1e6:.1f} Mpx, {MAX_TEXTURE_SIDE} a side); downscaled to "
                      f"{kept[0]}x{kept[1]}", LARGE_IMAGE, name,
                      detail=f"{declared[0]}x{declared[1]} -> {kept[0]}x{kept[1]}")
        return rgba

    # ---- geometry

    def _objects(self, scene: Scene, worlds) -> dict[str, tuple[str, str]]:
        """Fill scene.objects; return object name -> (node name, mesh name) for the sidecar."""
        aliases = {}
        for node_index, node, mesh in self._nodes_with("mesh", "meshes", worlds):
            node_name = node.get("name") or mesh.get("name") or f"node{node_index}"
            mesh_name = mesh.get("name") or f"mesh{node['mesh']}"
            if "skin" in node:
                self.warn(f"{self.source}: object '{node_name}' is skinned; skins are not "
                          "supported, shown as stored (the bind pose)", SKINNED, node_name,
                          ignored=["skins"])
            weights = node.get("weights", mesh.get("weights", []))
            if any(w != 0 for w in weights) and any(p.get("targets") for p in mesh.get("primitives", [])):
                self.warn(f"{self.source}: object '{node_name}' has morph target weights, not "
                          "supported; shown without its morph targets", MORPHED, node_name,
                          ignored=["morph targets"])
            for world in worlds[node_index]:
                for p, prim in enumerate(mesh.get("primitives", [])):
                    obj = self._primitive(scene, prim, world, node_name,
                                          f"mesh '{mesh_name}' primitive {p}")
                    if obj is not None:
                        scene.objects.append(obj)
                        aliases[obj.name] = (node_name, mesh_name)
        return aliases

    def _nodes_with(self, key: str, table: str, worlds):
        """(node index, node, the item of `table` it refers to by `key`) for each node in the scene
        (`worlds`: node index -> world matrices) that has `key`, in node order."""
        nodes = _list(self.tree, "nodes", self.source)
        for node_index in sorted(worlds):
            node = nodes[node_index]
            if key in node:
                yield node_index, node, self.item(table, node[key], f"node {node_index}")

    def _unique(self, name: str) -> str:
        out, k = name, 0
        while out in self._names:
            k += 1
            out = f"{name}.{k}"
        self._names.add(out)
        return out

    def _primitive(self, scene: Scene, prim: dict, world: np.ndarray, node_name: str,
                   what: str) -> Object | None:
        prim = self._draco(prim, node_name, what)
        mode = prim.get("mode", 4)
        attrs = prim.get("attributes", {})
        if mode not in (4, 5, 6):
            self.warn(f"{self.source}: object '{node_name}' {what} is {_MODES.get(mode, mode)}, "
                      "not triangles; skipped", NOT_TRIANGLES, node_name,
                      detail=_MODES.get(mode, str(mode)), ignored=["points and lines"])
            return None
        if "POSITION" not in attrs:
            raise self.bad(f"object '{node_name}' {what} has no POSITION attribute")
        local = self.accessor(attrs["POSITION"], f"'{node_name}' POSITION").astype(np.float64)
        if local.shape[1] != 3:
            raise self.bad(f"object '{node_name}' POSITION accessor is not VEC3")
        n = len(local)
        if "indices" in prim:
            flat = self.accessor(prim["indices"], f"'{node_name}' indices").reshape(-1)
            if flat.dtype.kind not in "iu":
                raise self.bad(f"object '{node_name}' {what}: indices are not integers")
            flat = flat.astype(np.int64)
        else:
            flat = np.arange(n, dtype=np.int64)
        if flat.size and (flat.min() < 0 or flat.max() >= n):
            raise self.bad(f"object '{node_name}' {what}: index {int(flat.max())} is out of "
                           f"range for {n} vertices")
        if mode == 4 and len(flat) % 3:
            raise self.bad(f"object '{node_name}' {what}: {len(flat)} indices is not a "
                           "multiple of 3")
        indices = _triangles(flat, mode)
        name = self._unique(node_name)

        linear = world[:3, :3]
        with np.errstate(over="ignore", invalid="ignore"):  # overflow is reported just below
            positions = local @ linear.T + world[:3, 3]
        check_finite_positions(name, positions, self.source)
        if np.linalg.det(linear) < 0:  # mirrored: keep counter-clockwise front faces
            indices = indices[:, [0, 2, 1]]

        normals = uvs = colors = None
        if "COLOR_0" in attrs:
            # glTF 3.7.2.1: COLOR_0 (VEC3 or VEC4, linear) multiplies the base colour.
            raw = self.accessor(attrs["COLOR_0"], f"'{node_name}' COLOR_0")
            if len(raw) != n or raw.shape[1] not in (3, 4):
                raise self.bad(f"object '{node_name}' COLOR_0 is not VEC3 or VEC4 of one per POSITION")
            colors = np.clip(np.nan_to_num(raw[:, :3].astype(np.float64), nan=0.0, posinf=1.0,
                                           neginf=0.0), 0.0, 1.0)
            if raw.shape[1] == 4 and float(np.nanmin(raw[:, 3], initial=1.0)) < 1.0:
                self.warn(f"{self.source}: object '{name}' has vertex colour alpha below 1 "
                          "(COLOR_0), not supported; ignored", VERTEX_ALPHA, name,
                          ignored=["COLOR_0 alpha"])
        if "NORMAL" in attrs:
            normals = self.accessor(attrs["NORMAL"], f"'{node_name}' NORMAL")
            if normals.shape[1] != 3:
                raise self.bad(f"object '{node_name}' NORMAL accessor is not VEC3")
            if len(normals) != n:
                raise self.bad(f"object '{node_name}' NORMAL count differs from POSITION")
            # Inverse transpose up to a positive factor: cofactor * sign(det).
            normals = normals @ (_cofactor(linear) * np.sign(np.linalg.det(linear) or 1.0)).T
        tangents = self._tangents(attrs, linear, n, node_name, name) if normals is not None else None
        # The base colour's texture coordinate set (glTF textureInfo.texCoord), with its
        # KHR_texture_transform applied, so the bake and the viewer read `uvs` as they are.
        material = prim.get("material")
        texcoord, matrix = self._uv_sets.get(material, (0, None)) if isinstance(material, int) \
            else (0, None)
        uv_name = f"TEXCOORD_{texcoord}"
        if uv_name in attrs:
            uvs = self.accessor(attrs[uv_name], f"'{node_name}' {uv_name}")
            if uvs.shape[1] != 2:
                raise self.bad(f"object '{node_name}' {uv_name} accessor is not VEC2")
            if len(uvs) != n:
                raise self.bad(f"object '{node_name}' {uv_name} count differs from POSITION")
            uvs = uvs.astype(np.float64)
            if not np.all(np.isfinite(uvs)):
                self.warn(f"{self.source}: object '{name}': non-finite texture coordinates "
                          "set to 0", NON_FINITE_UVS, name)
                uvs = np.nan_to_num(uvs, nan=0.0, posinf=0.0, neginf=0.0)
            if matrix is not None:
                uvs = uvs @ matrix[:2, :2].T + matrix[:2, 2]

        bad = degenerate_triangles(positions, indices)
        if bad.any():
            if not bad.all():  # one left with none is reported once, as skipped, just below
                self.warn(f"{self.source}: object '{name}': dropped {int(bad.sum())} zero-area "
                          f"triangle(s) of {len(indices)}", ZERO_AREA, name,
                          detail=str(int(bad.sum())),
                          counts={"dropped": int(bad.sum()), "triangles": len(indices)})
            indices = indices[~bad]
        if len(indices) == 0:
            self.warn(f"{self.source}: object '{name}' has no triangles with area; skipped",
                      NO_AREA, name)
            return None

        if normals is None:
            # glTF: without normals, clients compute flat normals (split every vertex).
            self.warn(f"{self.source}: object '{name}' has no normals; using flat face normals",
                      NO_NORMALS, name)
            positions, uvs = positions[indices].reshape(-1, 3), (
                None if uvs is None else uvs[indices].reshape(-1, 2))
            colors = None if colors is None else colors[indices].reshape(-1, 3)
            cross = face_cross(positions, np.arange(len(positions)).reshape(-1, 3))
            normals = np.repeat(cross / np.linalg.norm(cross, axis=1, keepdims=True), 3, axis=0)
            indices = np.arange(len(positions), dtype=np.int64).reshape(-1, 3)
        else:
            # Keep only referenced vertices (primitives may share one big vertex buffer).
            used, inverse = np.unique(indices, return_inverse=True)
            positions, normals = positions[used], normals[used]
            tangents = None if tangents is None else tangents[used]
            uvs = None if uvs is None else uvs[used]
            colors = None if colors is None else colors[used]
            indices = inverse.reshape(-1, 3).astype(np.int64)
            normals, replaced = repair_normals(normals, positions, indices)
            if replaced:
                self.warn(f"{self.source}: object '{name}': {replaced} zero-length normal(s) "
                          "replaced by the face normal", ZERO_NORMALS, name, detail=str(replaced),
                          counts={"normals": replaced})
        material = prim.get("material")
        if material is None:
            material = self._default(scene)
        else:
            material = self._index(material, len(_list(self.tree, "materials", self.source)),
                                   f"object '{node_name}' {what}", "material")
            textured = scene.materials[material]
            if uvs is None and any(t is not None for t in (
                    textured.kd_texture, textured.emission_texture, textured.metallic_roughness_texture,
                    textured.normal_texture,
                    textured.anisotropy_texture)):
                self.warn(f"{self.source}: object '{name}' has a textured material but no "
                          f"{uv_name}; its texel at (0, 0) is used everywhere", NO_UVS, name,
                          detail=uv_name)
        return Object(name=name, positions=positions, normals=np.asarray(normals, np.float32),
                      indices=indices, material=material,
                      uvs=None if uvs is None else uvs.astype(np.float32),
                      colors=None if colors is None else colors.astype(np.float32),
                      tangents=None if tangents is None else tangents.astype(np.float32))

    def _tangents(self, attrs: dict, linear: np.ndarray, n: int, node_name: str,
                  name: str) -> np.ndarray | None:
        """glTF TANGENT (VEC4: xyz tangent, w = +-1 bitangent sign) in world space, or None: xyz
        is a direction in the surface, so it takes the node's matrix; a mirroring matrix
        (negative determinant) reverses the bitangent against the transformed normal, so w flips.
        Unusable tangents (zero length, non-finite) are set to 0, which the viewer replaces by
        its own (viewer/tangent_frames.py `tangents`)."""
        if "TANGENT" not in attrs:
            return None
        raw = self.accessor(attrs["TANGENT"], f"'{node_name}' TANGENT")
        if len(raw) != n or raw.shape[1] != 4:
            raise self.bad(f"object '{node_name}' TANGENT is not VEC4 of one per POSITION")
        raw = np.nan_to_num(raw.astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
        xyz = raw[:, :3] @ linear.T
        length = np.linalg.norm(xyz, axis=1, keepdims=True)
        xyz = np.where(length > 1e-12, xyz / np.maximum(length, 1e-12), 0.0)
        w = np.where(raw[:, 3] < 0, -1.0, 1.0) * (-1.0 if np.linalg.det(linear) < 0 else 1.0)
        return np.concatenate([xyz, w[:, None]], axis=1)

    # ---- lights and cameras

    def _lights(self, scene: Scene, worlds) -> None:
        ext = self.tree.get("extensions", {}).get("KHR_lights_punctual", {})
        lights = ext.get("lights", [])
        scale = 1.0 / LUMENS_PER_WATT if self.side.units == "photometric" else 1.0
        nodes = _list(self.tree, "nodes", self.source)
        for node_index in sorted(worlds):
            ref = nodes[node_index].get("extensions", {}).get("KHR_lights_punctual")
            if ref is None:
                continue
            li = self._index(ref.get("light"), len(lights), f"node {node_index}",
                             "KHR_lights_punctual light")
            light = lights[li]
            name = light.get("name") or nodes[node_index].get("name") or f"light{li}"
            where = f"{self.source}: light '{name}'"
            if "range" in light:
                self.warn(f"{where}: range not supported; inverse-square falloff everywhere",
                          LIGHT_RANGE, name, ignored=["light range"])
            color = _numbers(light.get("color", [1, 1, 1]), 3, f"{where} color", minimum=0.0)
            intensity = _numbers([light.get("intensity", 1.0)], 1, f"{where} intensity",
                                 minimum=0.0)
            power = (color * intensity * scale).astype(np.float32)
            kind = light.get("type")
            for world in worlds[node_index]:
                position = world[:3, 3].copy()
                if not np.all(np.isfinite(world)):
                    raise GlintError(f"{where}: its node transform is not finite")
                direction = _unit(world[:3, :3] @ [0.0, 0.0, -1.0])
                if kind == "point":
                    scene.point_lights.append(PointLight(position, power, name))
                elif kind == "spot":
                    spot = light.get("spot", {})
                    inner, outer = _numbers([spot.get("innerConeAngle", 0.0),
                                             spot.get("outerConeAngle", np.pi / 4)], 2,
                                            f"{where} cone angles")
                    if not 0 <= inner < outer <= np.pi / 2:
                        self.warn(f"{self.source}: spot light '{name}': cone angles "
                                  f"{inner}, {outer} need 0 <= inner < outer <= pi/2; clamped",
                                  SPOT_CONES, name)
                        outer = float(np.clip(outer, 1e-4, np.pi / 2))
                        inner = float(np.clip(inner, 0.0, outer * (1 - 1e-6)))
                    scene.spot_lights.append(SpotLight(position, direction, power, inner,
                                                       outer, name))
                elif kind == "directional":
                    scene.directional_lights.append(DirectionalLight(direction, power, name))
                else:
                    raise self.bad(f"light '{name}' has unknown type {kind!r}")

    def _cameras(self, scene: Scene, worlds) -> None:
        for node_index, node, cam in self._nodes_with("camera", "cameras", worlds):
            name = node.get("name") or cam.get("name") or f"camera{node['camera']}"
            if cam.get("type") != "perspective":
                self.warn(f"{self.source}: camera '{name}' is {cam.get('type')}; only "
                          "perspective cameras are supported, skipped", ORTHOGRAPHIC, name,
                          ignored=[f"{cam.get('type')} cameras"])
                continue
            p = cam.get("perspective", {})
            where = f"{self.source}: camera '{name}'"
            if "yfov" not in p:
                raise self.bad(f"camera '{name}' has no yfov")
            yfov, znear = _numbers([p["yfov"], p.get("znear", 0.01)], 2, f"{where} yfov/znear",
                                   minimum=1e-9)
            zfar = float(_numbers([p.get("zfar", 1000.0)], 1, f"{where} zfar", minimum=znear)[0])
            aspect = p.get("aspectRatio")
            if aspect is not None:
                aspect = float(_numbers([aspect], 1, f"{where} aspectRatio", minimum=1e-9)[0])
            for world in worlds[node_index]:
                if not np.all(np.isfinite(world)):
                    raise GlintError(f"{where}: its node transform is not finite")
                forward = _unit(world[:3, :3] @ [0.0, 0.0, -1.0])
                up = world[:3, :3] @ [0.0, 1.0, 0.0]
                up = _unit(up - forward * np.dot(up, forward))
                if abs(np.linalg.norm(forward) - 1) > 1e-6 or abs(np.linalg.norm(up) - 1) > 1e-6:
                    raise GlintError(f"{where}: its node transform is singular (zero scale)")
                scene.cameras.append(Camera(
                    name=self._camera_name(scene, name), eye=world[:3, 3].copy(),
                    forward=forward, up=up, yfov=float(yfov), aspect=aspect,
                    znear=float(znear), zfar=zfar))
        for cam in self.side.cameras:
            if any(c.name == cam.name for c in scene.cameras):
                self.warn(f"{self.side.path.name}: camera '{cam.name}' has the name of a "
                          "glTF camera; both are kept")
            scene.cameras.append(cam)

    @staticmethod
    def _camera_name(scene: Scene, name: str) -> str:
        taken = {c.name for c in scene.cameras}
        out, k = name, 0
        while out in taken:
            k += 1
            out = f"{name}.{k}"
        return out

    # ---- sidecar roles

    def _role_overrides(self, scene: Scene, aliases) -> dict[str, str]:
        """[objects."NAME"] matches an object name, else a node name, else a mesh name."""
        out = {}
        for key, role in self.side.objects.items():
            out.update({h: role for h in self._matching(scene, aliases, key)})
        return out

    def _object_options(self, scene: Scene, aliases) -> dict[str, dict]:
        """[objects."NAME"] cube-map settings (bake/sidecar.py) by object name, matched as roles are."""
        out = {}
        for key, options in self.side.object_options.items():
            hits = self._matching(scene, aliases, key, warn=key not in self.side.objects)
            out.update({h: dict(options) for h in hits})
        return out

    def _matching(self, scene: Scene, aliases, key: str, warn: bool = True) -> list[str]:
        hits = [o.name for o in scene.objects if o.name == key]
        hits = hits or [o.name for o in scene.objects if aliases[o.name][0] == key]
        hits = hits or [o.name for o in scene.objects if aliases[o.name][1] == key]
        if not hits and ("objects", key) in self.side.set_names:
            raise GlintError(f"{self.side.set_names['objects', key]}: no object, node or mesh is called {key!r}")
        if not hits and warn:  # once per table
            self.warn(f"{self.side.path.name}: [objects.\"{key}\"]: no object, node or "
                      "mesh has that name")
        return hits

    def _check_material_names(self) -> None:
        for key in self.side.materials:
            if key not in self._material_names and ("materials", key) in self.side.set_names:
                names = sorted(self._material_names)
                known = ", ".join(repr(n) for n in names[:6]) + (", ..." if len(names) > 6 else "")
                raise GlintError(f"{self.side.set_names['materials', key]}: no material is called {key!r} "
                                 f"(the scene has {known})")
            if key not in self._material_names:
                self.warn(f"{self.side.path.name}: [materials.\"{key}\"]: no material has "
                          "that name")


def _triangles(flat: np.ndarray, mode: int) -> np.ndarray:
    """Index list of a triangles / strip / fan primitive -> (M, 3) counter-clockwise."""
    if mode == 4:
        return flat.reshape(-1, 3)
    k = np.arange(max(len(flat) - 2, 0))
    if mode == 5:  # strip: every other triangle is wound the other way
        even = (k % 2) == 0
        a = np.where(even, flat[k], flat[k + 1])
        b = np.where(even, flat[k + 1], flat[k])
        return np.stack([a, b, flat[k + 2]], axis=1)
    return np.stack([np.full_like(k, flat[0]) if len(k) else k, flat[k + 1], flat[k + 2]],
                    axis=1)


def _numbers(values, n: int, where: str, minimum: float | None = None) -> np.ndarray:
    """n finite numbers (>= minimum) from glTF JSON, or a one-line error."""
    ok = isinstance(values, list) and len(values) == n and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
        and (minimum is None or v >= minimum) for v in values)
    if not ok:
        bound = "" if minimum is None else f" >= {minimum:g}"
        raise GlintError(f"{where} must be {n} finite number(s){bound}, not {values!r}")
    return np.asarray(values, np.float64)


def _uv_set(info: dict, where: str) -> tuple[int, np.ndarray | None]:
    """(texture coordinate set, KHR_texture_transform matrix or None) of a glTF textureInfo; the
    extension's own texCoord overrides the textureInfo's (KHR_texture_transform)."""
    texcoord, matrix = _texcoord(info.get("texCoord", 0)), None
    transform = info.get("extensions", {}).get("KHR_texture_transform")
    if isinstance(transform, dict):
        texcoord = _texcoord(transform.get("texCoord", texcoord))
        matrix = texture_transform_matrix(transform, where)
    return texcoord, matrix


def _texcoord(value) -> int:
    """A textureInfo texCoord (a set index >= 0); anything else reads set 0."""
    return value if isinstance(value, int) and not isinstance(value, bool) and value >= 0 else 0


def texture_transform_matrix(ext: dict, where: str = "KHR_texture_transform") -> np.ndarray:
    """The 3x3 matrix of KHR_texture_transform: uv' = (T R S) (u, v, 1).

    T translates by `offset`, S scales by `scale`, and R rotates by `rotation` radians,
    counter-clockwise in the image (v grows downwards): u' = cos u + sin v,
    v' = -sin u + cos v. That is the extension's example: offset (0, 1), rotation pi/2,
    scale 0.5 reads "only the lower left quadrant of the source image, rotated clockwise
    90 degrees" (KHR_texture_transform README, Example JSON).
    """
    offset = _numbers(ext.get("offset", [0.0, 0.0]), 2, f"{where} KHR_texture_transform offset")
    scale = _numbers(ext.get("scale", [1.0, 1.0]), 2, f"{where} KHR_texture_transform scale")
    rotation = float(_numbers([ext.get("rotation", 0.0)], 1,
                              f"{where} KHR_texture_transform rotation")[0])
    c, s = np.cos(rotation), np.sin(rotation)
    t = np.array([[1.0, 0.0, offset[0]], [0.0, 1.0, offset[1]], [0.0, 0.0, 1.0]])
    r = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    return t @ r @ np.diag([scale[0], scale[1], 1.0])


def _mib(size: int) -> str:
    """A byte count for a message: '24,576 MiB'."""
    return f"{size / (1 << 20):,.0f} MiB"


def _image_name(image: dict, index: int) -> str:
    """How a summary names an image: its name, else its file (not a data: URI), else its index."""
    uri = image.get("uri", "")
    return image.get("name") or (uri if uri and not uri.startswith("data:") else f"image {index}")


def _uses(tree, extension: str) -> int:
    """How many `extensions` tables of the glTF JSON name `extension` (materials, nodes, ...)."""
    if isinstance(tree, list):
        return sum(_uses(v, extension) for v in tree)
    if not isinstance(tree, dict):
        return 0
    here = isinstance(tree.get("extensions"), dict) and extension in tree["extensions"]
    return int(here) + sum(_uses(v, extension) for v in tree.values())


def _cofactor(m: np.ndarray) -> np.ndarray:
    """det(m) * inv(m).T, defined for singular m too (columns: cross products)."""
    c0, c1, c2 = m[:, 0], m[:, 1], m[:, 2]
    return np.stack([np.cross(c1, c2), np.cross(c2, c0), np.cross(c0, c1)], axis=1)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, np.float64)
    n = np.linalg.norm(v)
    return v / n if n > 0 else v
