"""glTF accessors -> numpy arrays: bufferViews (with byteStride), sparse accessors, normalised integers,
and the compressed geometry decoded where it is read: EXT/KHR_meshopt_compression per bufferView
(`_meshopt`, the package meshopt) and KHR_draco_mesh_compression per primitive (`Accessors.draco`,
DracoPy).

`Accessors.read` gives an accessor's (count, components) array, float64 for float and normalised
data (glTF 3.6.2), else integers; each accessor is read once per document.
"""
from __future__ import annotations

import numpy as np

from glint.bake.gltf_container import MESHOPT, GltfDocument
from glint.core.errors import GlintError

_COMPONENTS = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_NORMALIZE = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}
_TYPES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
# An accessor without a bufferView (zeros, with sparse values on them) and a meshopt bufferView's
# decoded data take their size from a count in the JSON, not from bytes in the file, so a corrupt
# count (2**31) would have numpy or meshopt allocate gigabytes before anything else fails. 256 MiB
# is 22 million float32 VEC3 elements: far past any accessor of a scene glint bakes in a day
# (docs/BAKE.md's largest, the staircase, has 1.1 million vertices). Accessors read from a buffer
# are limited by the file's own bytes instead.
MAX_UNBACKED_BYTES = 256 << 20


class Accessors:
    """The accessors of one glTF document, read and decoded on first use."""

    def __init__(self, doc: GltfDocument):
        self.doc = doc
        self._cache: dict = {}  # accessor index (or a Draco primitive's key) -> array
        self._decoded: dict[int, bytes] = {}  # meshopt-compressed bufferViews, decoded

    def read(self, index, what: str) -> np.ndarray:
        """(count, components) array: float64 for float/normalised data, else integers."""
        if index in self._cache:
            return self._cache[index]
        a = self.doc.item("accessors", index, what)
        where = f"accessor {index} ({what})"
        ctype, atype, count = a.get("componentType"), a.get("type"), a.get("count")
        if ctype not in _COMPONENTS or atype not in _TYPES:
            raise self.doc.bad(f"{where} has componentType {ctype!r} / type {atype!r}")
        if not isinstance(count, int) or count < 0:
            raise self.doc.bad(f"{where} has an invalid count {count!r}")
        ncomp = _TYPES[atype]
        if "bufferView" in a:
            data = self._read_view(a["bufferView"], a.get("byteOffset", 0), count, ctype,
                                   ncomp, where)
        else:  # all zeros unless sparse values replace some
            size = count * ncomp * np.dtype(_COMPONENTS[ctype]).itemsize
            if size > MAX_UNBACKED_BYTES:
                raise self.doc.bad(f"{where} has no bufferView and a count of {count:,}: {_mib(size)} of zeros, "
                               f"more than glint makes without data in the file ({_mib(MAX_UNBACKED_BYTES)})")
            data = np.zeros((count, ncomp), _COMPONENTS[ctype])
        if "sparse" in a:
            sp = a["sparse"]
            n, si, sv = sp.get("count"), sp.get("indices", {}), sp.get("values", {})
            if not isinstance(n, int) or n < 0:
                raise self.doc.bad(f"{where} has an invalid sparse count")
            idx = self._read_view(si.get("bufferView"), si.get("byteOffset", 0), n,
                                  si.get("componentType"), 1, f"{where} sparse indices")
            val = self._read_view(sv.get("bufferView"), sv.get("byteOffset", 0), n, ctype,
                                  ncomp, f"{where} sparse values")
            idx = idx.reshape(-1).astype(np.int64)
            if idx.size and (idx.min() < 0 or idx.max() >= count):
                raise self.doc.bad(f"{where} has sparse indices out of range")
            data = data.copy()
            data[idx] = val
        if a.get("normalized") and ctype in _NORMALIZE:
            data = np.maximum(data / _NORMALIZE[ctype], -1.0)
        elif ctype == 5126:
            data = data.astype(np.float64)
        self._cache[index] = data
        return data

    def _read_view(self, view_index, start, count: int, ctype, ncomp: int,
                   where: str) -> np.ndarray:
        """`count` elements of `ncomp` components from a bufferView, honouring byteStride."""
        if ctype not in _COMPONENTS:
            raise self.doc.bad(f"{where} has componentType {ctype!r}")
        view = self.doc.item("bufferViews", view_index, where)
        buffer, v0, vlen = self._view_bytes(view_index, view)
        dtype = np.dtype(_COMPONENTS[ctype])
        elem = dtype.itemsize * ncomp
        stride = view.get("byteStride") or elem
        need = 0 if count == 0 else start + (count - 1) * stride + elem
        if not isinstance(start, int) or start < 0 or stride < elem or need > vlen:
            raise self.doc.bad(f"{where} needs {need} bytes of bufferView {view_index}, "
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
        buffer = self.doc.buffers[self.doc.index(view.get("buffer"), len(self.doc.buffers),
                                              what, "buffer")]
        v0, vlen = view.get("byteOffset", 0), view.get("byteLength", -1)
        if not (isinstance(v0, int) and isinstance(vlen, int) and 0 <= v0 and 0 <= vlen
                and v0 + vlen <= len(buffer)):
            raise self.doc.bad(f"{what} (bytes {v0}+{vlen}) lies outside its "
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
            raise GlintError(f"{self.doc.source}: {where} is meshopt-compressed; reading it needs the "
                             "Python package meshopt (pip install meshopt)") from None
        buffer, v0, vlen = self._slice(ext, where)
        count, stride = ext.get("count"), ext.get("byteStride")
        mode, filt = ext.get("mode"), ext.get("filter", "NONE")
        if not (isinstance(count, int) and count >= 0 and isinstance(stride, int) and stride > 0
                and mode in ("ATTRIBUTES", "TRIANGLES", "INDICES")):
            raise self.doc.bad(f"{where} has count {count!r}, byteStride {stride!r}, mode {mode!r}")
        if count * stride > MAX_UNBACKED_BYTES:
            raise self.doc.bad(f"{where} decodes to {count:,} elements of {stride} bytes ({_mib(count * stride)}), "
                           f"more than glint decodes for one bufferView ({_mib(MAX_UNBACKED_BYTES)})")
        try:
            rows = meshopt.decode_gltf_buffer(bytes(buffer[v0:v0 + vlen]), count, stride, mode,
                                              None if filt == "NONE" else filt)
        except (ValueError, RuntimeError) as err:
            raise GlintError(f"{self.doc.source}: {where} cannot be decoded ({err}); the file is "
                             "corrupt or truncated") from None
        return np.ascontiguousarray(rows).tobytes()

    def draco(self, prim: dict, node_name: str, what: str) -> dict:
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
            raise GlintError(f"{self.doc.source}: {where} needs the Python package DracoPy "
                             "(pip install DracoPy)") from None
        view_index = ext.get("bufferView")
        buffer, v0, vlen = self._view_bytes(view_index, self.doc.item("bufferViews", view_index, where))
        try:
            mesh = DracoPy.decode(bytes(buffer[v0:v0 + vlen]))
        except Exception as err:  # DracoPy raises FileTypeException, ValueError, ... (not documented)
            raise GlintError(f"{self.doc.source}: {where}: the Draco data cannot be decoded "
                             f"({type(err).__name__}: {err}); the file is corrupt or truncated") from None
        faces = getattr(mesh, "faces", None)
        if faces is None or len(faces) == 0:
            raise GlintError(f"{self.doc.source}: {where}: the Draco data holds no triangles")
        attrs = prim.get("attributes") or {}
        for semantic, uid in (ext.get("attributes") or {}).items():
            if semantic not in attrs:
                continue
            index = attrs[semantic]
            a = self.doc.item("accessors", index, where)
            got = mesh.get_attribute_by_unique_id(uid) if isinstance(uid, int) else None
            if got is None:
                raise self.doc.bad(f"{where}: {semantic} refers to Draco attribute {uid!r}, which the "
                               "Draco data does not have")
            data = np.asarray(got["data"])
            data = data.reshape(len(data), -1)
            if len(data) != a.get("count") or data.shape[1] != _TYPES.get(a.get("type")):
                raise self.doc.bad(f"{where}: {semantic} decodes to {data.shape[0]} x {data.shape[1]} "
                               f"values; accessor {index} says {a.get('count')} x {a.get('type')}")
            if data.dtype.kind in "iu" and a.get("normalized") and a.get("componentType") in _NORMALIZE:
                data = np.maximum(data / _NORMALIZE[a["componentType"]], -1.0)
            elif data.dtype.kind == "f":
                data = data.astype(np.float64)
            self._cache[index] = data
        key = prim.get("indices", ("draco", view_index))
        self._cache[key] = np.asarray(faces, np.int64).reshape(-1, 1)
        return {**prim, "indices": key, "mode": 4}


def _mib(size: int) -> str:
    """A byte count for a message: '24,576 MiB'."""
    return f"{size / (1 << 20):,.0f} MiB"
