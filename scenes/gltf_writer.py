"""A small glTF 2.0 writer: enough for the built-in scenes and for test fixtures.

Dependency-free on purpose (numpy, json, struct, zlib): the output must be
byte-for-byte reproducible so `scenes/generate.py` can be checked against the
committed files, which rules out anything whose output drifts between versions.
Textures are encoded with the tiny PNG encoder below for the same reason
(`png_level=0` stores them uncompressed, independent of the zlib build).

Usage::

    w = GltfWriter()
    m = w.add_material("White", base_color=(0.8, 0.8, 0.8, 1))
    mesh = w.add_mesh("Quad", positions, indices, m, normals=normals)
    w.add_node("Quad", mesh=mesh, translation=(0, 1, 0))
    w.write("scene.glb")

Only what glint reads is covered: one triangle primitive per mesh, float32
vertex attributes, uint32 indices, metallic-roughness materials with an
optional embedded base-colour PNG, perspective cameras, KHR_lights_punctual.
"""
from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path

import numpy as np

# glTF enums (spec section 3.6.2 / 5.x)
_FLOAT = 5126
_UNSIGNED_INT = 5125
_ARRAY_BUFFER = 34962
_ELEMENT_ARRAY_BUFFER = 34963
_TRIANGLES = 4
_LINEAR = 9729
_LINEAR_MIPMAP_LINEAR = 9987
_REPEAT = 10497

_GLB_MAGIC = 0x46546C67  # "glTF"
_CHUNK_JSON = 0x4E4F534A  # "JSON"
_CHUNK_BIN = 0x004E4942  # "BIN\0"


def _zlib_stored(data: bytes) -> bytes:
    """A zlib stream of uncompressed (stored) deflate blocks: the same bytes from any zlib."""
    out = bytearray(b"\x78\x01")
    step = 65535
    for start in range(0, max(len(data), 1), step):
        block = data[start:start + step]
        final = 1 if start + step >= len(data) else 0
        out += struct.pack("<BHH", final, len(block), len(block) ^ 0xFFFF) + block
    return bytes(out + struct.pack(">I", zlib.adler32(data) & 0xFFFFFFFF))


def encode_png(image: np.ndarray, level: int = 9) -> bytes:
    """(H, W, 3|4) uint8 -> PNG bytes (8-bit RGB/RGBA, filter type 0).

    `level` is the zlib level; 0 writes stored blocks by hand, so the bytes do
    not depend on the zlib build (used for the committed built-in scenes).
    """
    img = np.ascontiguousarray(image)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] not in (3, 4):
        raise ValueError(f"texture must be an (H, W, 3|4) uint8 array, got {img.dtype} {img.shape}")
    h, w, c = img.shape
    raw = np.concatenate([np.zeros((h, 1), np.uint8), img.reshape(h, w * c)], axis=1).tobytes()

    def chunk(tag: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + tag + data
                + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF))

    colour_type = 2 if c == 3 else 6
    ihdr = struct.pack(">IIBBBBB", w, h, 8, colour_type, 0, 0, 0)
    idat = _zlib_stored(raw) if level == 0 else zlib.compress(raw, level)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat)
            + chunk(b"IEND", b""))


def _floats(values) -> list[float]:
    return [float(v) for v in np.asarray(values, dtype=np.float64).ravel()]


def quad(center, u, v) -> tuple[np.ndarray, np.ndarray]:
    """(positions (4, 3), indices (2, 3)): two CCW triangles spanning center +- u +- v, front face
    along cross(u, v)."""
    c, u, v = map(np.asarray, (center, u, v))
    return np.array([c - u - v, c + u - v, c + u + v, c - u + v], float), np.array([[0, 1, 2], [0, 2, 3]])


def room_faces(half: float, height: float, wall: int, floor: int) -> dict:
    """The six faces of a closed room 2 half wide and deep and `height` high, standing on y = 0,
    front faces inwards, for `GltfWriter.add_quads`: Floor, Ceiling, Back (-z), Front, Left (-x), Right."""
    s, h = float(half), float(height) / 2
    return {"Floor": ((0, 0, 0), (s, 0, 0), (0, 0, -s), floor), "Ceiling": ((0, 2 * h, 0), (s, 0, 0), (0, 0, s), wall),
            "Back": ((0, h, -s), (s, 0, 0), (0, h, 0), wall), "Front": ((0, h, s), (-s, 0, 0), (0, h, 0), wall),
            "Left": ((-s, h, 0), (0, 0, -s), (0, h, 0), wall), "Right": ((s, h, 0), (0, 0, s), (0, h, 0), wall)}


class GltfWriter:
    """Collects materials, meshes, cameras, lights and nodes; `write` emits .glb or .gltf."""

    def __init__(self, generator: str = "glint scenes/gltf_writer.py", png_level: int = 9):
        self.generator = generator
        self.png_level = png_level
        self._bin = bytearray()
        self.buffer_views: list[dict] = []
        self.accessors: list[dict] = []
        self.materials: list[dict] = []
        self.meshes: list[dict] = []
        self.cameras: list[dict] = []
        self.lights: list[dict] = []
        self.nodes: list[dict] = []
        self.images: list[dict] = []
        self.textures: list[dict] = []
        self.samplers: list[dict] = []
        self.extensions_used: set[str] = set()

    # -- binary data -----------------------------------------------------------------------
    def _add_view(self, data: bytes, target: int | None = None) -> int:
        # Every view starts 4-byte aligned: accessor component types need it (spec 3.6.2.4).
        self._bin.extend(b"\0" * (-len(self._bin) % 4))
        view = {"buffer": 0, "byteOffset": len(self._bin), "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        self._bin.extend(data)
        self.buffer_views.append(view)
        return len(self.buffer_views) - 1

    def _add_accessor(self, array: np.ndarray, kind: str, target: int, min_max: bool) -> int:
        if kind == "SCALAR":
            data = np.ascontiguousarray(array, dtype=np.uint32).ravel()
            comp = _UNSIGNED_INT
        else:
            width = {"VEC2": 2, "VEC3": 3, "VEC4": 4}[kind]
            data = np.ascontiguousarray(array, dtype=np.float32).reshape(-1, width)
            comp = _FLOAT
        acc = {"bufferView": self._add_view(data.astype("<" + data.dtype.str[1:]).tobytes(), target),
               "componentType": comp, "count": int(len(data)), "type": kind}
        if min_max:
            if comp == _FLOAT:
                acc["min"] = _floats(data.min(axis=0))
                acc["max"] = _floats(data.max(axis=0))
            else:
                acc["min"] = [int(data.min())]
                acc["max"] = [int(data.max())]
        self.accessors.append(acc)
        return len(self.accessors) - 1

    # -- scene content ---------------------------------------------------------------------
    def add_texture(self, image: np.ndarray, name: str | None = None, sampler: dict | None = None) -> int:
        """Embed an (H, W, 3|4) uint8 sRGB image as PNG; returns the texture index. `sampler` (a
        glTF sampler object: magFilter, minFilter, wrapS, wrapT) is added for this texture;
        without it the texture shares sampler 0 (linear, mip-mapped, repeating)."""
        if not self.samplers:
            self.samplers.append({"magFilter": _LINEAR, "minFilter": _LINEAR_MIPMAP_LINEAR,
                                  "wrapS": _REPEAT, "wrapT": _REPEAT})
        index = 0
        if sampler is not None:
            self.samplers.append(dict(sampler))
            index = len(self.samplers) - 1
        img = {"bufferView": self._add_view(encode_png(image, self.png_level)),
               "mimeType": "image/png"}
        if name:
            img["name"] = name
        self.images.append(img)
        self.textures.append({"sampler": index, "source": len(self.images) - 1})
        return len(self.textures) - 1

    def add_material(self, name, base_color=(0.8, 0.8, 0.8, 1.0), metallic=0.0, roughness=1.0,
                     emissive=(0, 0, 0), emissive_strength=1.0, double_sided=False,
                     base_color_texture=None, extensions=None, extras=None, alpha_mode=None,
                     alpha_cutoff=None, texcoord=None, texture_transform=None, sampler=None,
                     emissive_texture=None, metallic_roughness_texture=None) -> int:
        """A metallic-roughness material; `base_color` is linear RGB(A).

        `emissive_texture` (an (H, W, 3) uint8 sRGB image) is written as the emissiveTexture,
        with the base colour's texCoord and sampler (glTF 3.9.3: it multiplies emissiveFactor).
        `metallic_roughness_texture` (an (H, W, 3) uint8 image, linear: G roughness, B metallic)
        is written as the metallicRoughnessTexture, with the same texCoord and sampler.

        `texcoord` (the base colour textureInfo's texCoord) and `texture_transform` (its
        KHR_texture_transform object: offset, rotation, scale, texCoord) are written when given;
        `sampler` is the base colour texture's glTF sampler object (`add_texture`).

        `alpha_mode` ("OPAQUE", "MASK", "BLEND") and `alpha_cutoff` are written when given; the
        alpha comes from base_color[3] and an RGBA `base_color_texture`.

        `emissive_strength` != 1 adds KHR_materials_emissive_strength (glTF clamps
        emissiveFactor to [0, 1], so brighter emitters need the extension).
        `extensions` is merged into the material's extensions object (each key is
        recorded in extensionsUsed); `extras` is written as is.
        """
        base = _floats(base_color)
        if len(base) == 3:
            base.append(1.0)
        pbr = {"baseColorFactor": base, "metallicFactor": float(metallic),
               "roughnessFactor": float(roughness)}
        if base_color_texture is not None:
            pbr["baseColorTexture"] = {"index": self.add_texture(np.asarray(base_color_texture),
                                                                 f"{name} base colour", sampler)}
            if texcoord is not None:
                pbr["baseColorTexture"]["texCoord"] = int(texcoord)
            if texture_transform is not None:
                pbr["baseColorTexture"]["extensions"] = {
                    "KHR_texture_transform": dict(texture_transform)}
                self.extensions_used.add("KHR_texture_transform")
        if metallic_roughness_texture is not None:
            pbr["metallicRoughnessTexture"] = {"index": self.add_texture(
                np.asarray(metallic_roughness_texture), f"{name} metallic roughness", sampler)}
            if texcoord is not None:
                pbr["metallicRoughnessTexture"]["texCoord"] = int(texcoord)
        mat = {"name": str(name), "pbrMetallicRoughness": pbr}
        emissive = _floats(emissive)
        if any(emissive):
            mat["emissiveFactor"] = emissive
        if emissive_texture is not None:
            mat["emissiveTexture"] = {"index": self.add_texture(np.asarray(emissive_texture),
                                                                f"{name} emission", sampler)}
            if texcoord is not None:
                mat["emissiveTexture"]["texCoord"] = int(texcoord)
        if double_sided:
            mat["doubleSided"] = True
        if alpha_mode is not None:
            mat["alphaMode"] = str(alpha_mode)
        if alpha_cutoff is not None:
            mat["alphaCutoff"] = float(alpha_cutoff)
        ext = dict(extensions or {})
        if float(emissive_strength) != 1.0:
            ext["KHR_materials_emissive_strength"] = {"emissiveStrength": float(emissive_strength)}
        if ext:
            mat["extensions"] = ext
            self.extensions_used.update(ext)
        if extras is not None:
            mat["extras"] = extras
        self.materials.append(mat)
        return len(self.materials) - 1

    def add_mesh(self, name, positions, indices, material, normals=None, uvs=None,
                 tangents=None, uvs1=None, colors=None) -> int:
        """One mesh with one indexed triangle primitive; indices (M, 3) CCW front faces.

        `uvs` are written as given, in glTF's convention: (0, 0) is the top-left
        corner of the image, v grows downwards (trimesh flips v on load).
        `tangents` (N, 4): xyz unit tangent, w = +-1 bitangent sign (glTF TANGENT).
        `uvs1` (N, 2): a second set, TEXCOORD_1. `colors` (N, 3|4): linear COLOR_0 (float).
        """
        pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        idx = np.asarray(indices, dtype=np.int64).reshape(-1, 3)
        if len(idx) and (idx.min() < 0 or idx.max() >= len(pos)):
            raise ValueError(f"mesh {name!r}: index out of range")
        attrs = {"POSITION": self._add_accessor(pos, "VEC3", _ARRAY_BUFFER, True)}
        if normals is not None:
            nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
            length = np.linalg.norm(nrm, axis=1, keepdims=True)
            # glTF requires unit normals; a zero normal stays zero rather than NaN.
            nrm = np.divide(nrm, length, out=np.zeros_like(nrm), where=length > 0)
            attrs["NORMAL"] = self._add_accessor(nrm, "VEC3", _ARRAY_BUFFER, True)
        if uvs is not None:
            attrs["TEXCOORD_0"] = self._add_accessor(np.asarray(uvs).reshape(-1, 2), "VEC2",
                                                     _ARRAY_BUFFER, True)
        if colors is not None:
            col = np.asarray(colors, dtype=np.float64)
            attrs["COLOR_0"] = self._add_accessor(col.reshape(len(col), -1),
                                                  "VEC4" if col.shape[-1] == 4 else "VEC3",
                                                  _ARRAY_BUFFER, False)
        if uvs1 is not None:
            attrs["TEXCOORD_1"] = self._add_accessor(np.asarray(uvs1).reshape(-1, 2), "VEC2",
                                                     _ARRAY_BUFFER, True)
        if tangents is not None:
            attrs["TANGENT"] = self._add_accessor(np.asarray(tangents).reshape(-1, 4), "VEC4",
                                                  _ARRAY_BUFFER, False)
        prim = {"attributes": attrs,
                "indices": self._add_accessor(idx, "SCALAR", _ELEMENT_ARRAY_BUFFER, True),
                "mode": _TRIANGLES}
        if material is not None:
            prim["material"] = int(material)
        self.meshes.append({"name": str(name), "primitives": [prim]})
        return len(self.meshes) - 1

    def add_camera(self, name, yfov, znear=0.01, zfar=100.0, aspect_ratio=None) -> int:
        """A perspective camera looking down its node's -Z with +Y up; yfov in radians."""
        persp = {"yfov": float(yfov), "znear": float(znear)}
        if zfar is not None:
            persp["zfar"] = float(zfar)
        if aspect_ratio is not None:
            persp["aspectRatio"] = float(aspect_ratio)
        self.cameras.append({"name": str(name), "type": "perspective", "perspective": persp})
        return len(self.cameras) - 1

    def add_light(self, name, type, color=(1, 1, 1), intensity=1.0, range=None,
                  inner_cone_angle=None, outer_cone_angle=None) -> int:
        """KHR_lights_punctual: point/spot in candela, directional in lux; shines along -Z."""
        if type not in ("point", "spot", "directional"):
            raise ValueError(f"light {name!r}: type must be point, spot or directional")
        light = {"name": str(name), "type": type, "color": _floats(color),
                 "intensity": float(intensity)}
        if range is not None:
            light["range"] = float(range)
        if type == "spot":
            spot = {}
            if inner_cone_angle is not None:
                spot["innerConeAngle"] = float(inner_cone_angle)
            if outer_cone_angle is not None:
                spot["outerConeAngle"] = float(outer_cone_angle)
            light["spot"] = spot
        self.lights.append(light)
        self.extensions_used.add("KHR_lights_punctual")
        return len(self.lights) - 1

    def add_quads(self, faces: dict, *, normals: bool = False) -> None:
        """A node and mesh per `name: (center, u, v, material)` (see `quad`); `normals`: write the
        face normal as the vertex normals (else the reader computes them)."""
        for name, (c, u, v, material) in faces.items():
            p, i = quad(c, u, v)
            n = np.cross(u, v)
            self.add_node(name, mesh=self.add_mesh(name, p, i, material,
                                                   normals=np.tile(n / np.linalg.norm(n), (4, 1)) if normals else None))

    def add_node(self, name, mesh=None, camera=None, light=None, translation=None,
                 rotation=None, scale=None, matrix=None, children=(), extras=None) -> int:
        """A node; rotation is an xyzw quaternion, matrix a 4x4 (numpy row-major) array."""
        if matrix is not None and any(v is not None for v in (translation, rotation, scale)):
            raise ValueError(f"node {name!r}: give either matrix or TRS, not both")
        node: dict = {"name": str(name)}
        if mesh is not None:
            node["mesh"] = int(mesh)
        if camera is not None:
            node["camera"] = int(camera)
        if light is not None:
            node["extensions"] = {"KHR_lights_punctual": {"light": int(light)}}
        if translation is not None:
            node["translation"] = _floats(translation)
        if rotation is not None:
            node["rotation"] = _floats(rotation)
        if scale is not None:
            node["scale"] = _floats(scale)
        if matrix is not None:
            # glTF stores matrices column-major: the transpose's rows are the columns.
            node["matrix"] = _floats(np.asarray(matrix, dtype=np.float64).reshape(4, 4).T)
        if len(children):
            node["children"] = [int(c) for c in children]
        if extras is not None:
            node["extras"] = extras
        self.nodes.append(node)
        return len(self.nodes) - 1

    # -- output ----------------------------------------------------------------------------
    def to_json(self, uri: str | None = None) -> dict:
        """The glTF JSON document; `uri` names an external .bin (None: GLB-embedded buffer)."""
        children = {c for n in self.nodes for c in n.get("children", ())}
        roots = [i for i in range(len(self.nodes)) if i not in children]
        doc: dict = {"asset": {"version": "2.0", "generator": self.generator},
                     "scene": 0, "scenes": [{"nodes": roots}], "nodes": self.nodes}
        for key, items in (("meshes", self.meshes), ("materials", self.materials),
                           ("cameras", self.cameras), ("textures", self.textures),
                           ("images", self.images), ("samplers", self.samplers),
                           ("accessors", self.accessors), ("bufferViews", self.buffer_views)):
            if items:
                doc[key] = items
        if self._bin:
            buf = {"byteLength": len(self._bin)}
            if uri is not None:
                buf["uri"] = uri
            doc["buffers"] = [buf]
        if self.lights:
            doc["extensions"] = {"KHR_lights_punctual": {"lights": self.lights}}
        if self.extensions_used:
            doc["extensionsUsed"] = sorted(self.extensions_used)
        return doc

    def write(self, path) -> Path:
        """Write `.glb` (JSON + one BIN chunk) or `.gltf` with a sibling `.bin`."""
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix not in (".glb", ".gltf"):
            raise ValueError(f"{path}: expected a .glb or .gltf file name")
        binary = bytes(self._bin) + b"\0" * (-len(self._bin) % 4)
        if suffix == ".gltf":
            bin_path = path.with_suffix(".bin")
            doc = self.to_json(uri=bin_path.name if binary else None)
            path.write_text(json.dumps(doc, indent=1) + "\n")
            if binary:
                bin_path.write_bytes(binary)
            return path
        text = json.dumps(self.to_json(), separators=(",", ":")).encode()
        text += b" " * (-len(text) % 4)  # the JSON chunk is padded with spaces (spec 4.4.3.1)
        chunks = struct.pack("<II", len(text), _CHUNK_JSON) + text
        if binary:
            chunks += struct.pack("<II", len(binary), _CHUNK_BIN) + binary
        header = struct.pack("<III", _GLB_MAGIC, 2, 12 + len(chunks))
        path.write_bytes(header + chunks)
        return path
