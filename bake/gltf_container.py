"""The glTF container: a .glb's chunks or a .gltf's JSON, and every buffer's bytes -> `GltfDocument`.

Reads the file and what its buffers name (the .glb's BIN chunk, `data:` URIs, files beside it); the
JSON's types are checked (bake/gltf_schema.py) before anything else reads it. `GltfDocument` also
holds the lookups the rest of the loader shares: a table entry by index (`item`, `index`) and the one
"malformed glTF" error line (`bad`), and `numbers`, finite numbers from the JSON or that line.
"""
from __future__ import annotations

import base64
import json
import struct
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from glint.bake.gltf_schema import check_types
from glint.core.errors import GlintError

# EXT/KHR_meshopt_compression: a buffer may be a fallback without data (_buffer_bytes); the
# compressed bufferViews are decoded in bake/gltf_accessors.py.
MESHOPT = ("EXT_meshopt_compression", "KHR_meshopt_compression")

_CHUNK_JSON, _CHUNK_BIN = 0x4E4F534A, 0x004E4942
_SINGULAR = {"accessors": "accessor", "bufferViews": "bufferView", "meshes": "mesh",
             "materials": "material", "textures": "texture", "images": "image",
             "cameras": "camera", "nodes": "node"}


@dataclass
class GltfDocument:
    """The JSON of a glTF file and its buffers' bytes."""

    path: Path
    json: dict
    buffers: list[bytes] = field(default_factory=list)

    @property
    def source(self) -> str:
        return self.path.name

    def table(self, key: str) -> list:
        """The JSON's top-level list `key` (empty when absent)."""
        return json_list(self.json, key, self.source)

    def bad(self, message: str) -> GlintError:
        return GlintError(f"{self.source}: malformed glTF: {message}")

    def item(self, key: str, index, what: str) -> dict:
        """Entry `index` of the table `key`; `what` (the referrer) names it in the error."""
        items = self.table(key)
        if not isinstance(index, int) or not 0 <= index < len(items):
            raise self.bad(f"{what} refers to {_SINGULAR.get(key, key)} {index}, "
                           "which does not exist")
        return items[index]

    def index(self, value, size: int, what: str, kind: str) -> int:
        """`value` if it indexes a table of `size` entries of `kind`, else the one error line."""
        if not isinstance(value, int) or not 0 <= value < size:
            raise self.bad(f"{what} refers to {kind} {value}, which does not exist")
        return value


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
    for i, buf in enumerate(json_list(tree, "buffers", name)):
        doc.buffers.append(_buffer_bytes(buf, i, path, binary))
    return doc


def json_list(tree: dict, key: str, source: str) -> list:
    """tree[key] as a list (empty when absent), or the one error line naming `source`."""
    value = tree.get(key, [])
    if not isinstance(value, list):
        raise GlintError(f"{source}: malformed glTF: '{key}' must be a list")
    return value


def numbers(values, n: int, where: str, minimum: float | None = None) -> np.ndarray:
    """n finite numbers (>= minimum) from glTF JSON, or a one-line error."""
    ok = isinstance(values, list) and len(values) == n and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
        and (minimum is None or v >= minimum) for v in values)
    if not ok:
        bound = "" if minimum is None else f" >= {minimum:g}"
        raise GlintError(f"{where} must be {n} finite number(s){bound}, not {values!r}")
    return np.asarray(values, np.float64)


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
