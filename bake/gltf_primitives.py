"""glTF mesh primitives -> glint `Object`s in world space.

Reads a primitive's indices (triangles, strips and fans as triangle lists, glTF 3.7.2.1) and its
POSITION, NORMAL, TANGENT, COLOR_0 and TEXCOORD_n accessors (bake/gltf_accessors.py), places them by
the node's world matrix (normals by its cofactor matrix, winding reversed where it mirrors, glTF
3.7.4), reads the uvs with the set and transform its material names (bake/gltf_materials.py), drops
zero-area triangles, computes flat normals where there are none and keeps only the vertices used.
Each Object gets a unique name: the node's, then ".1", ".2", ... for the next ones.
"""
from __future__ import annotations

from functools import partial

import numpy as np

from glint.bake.gltf_accessors import Accessors
from glint.bake.gltf_container import GltfDocument
from glint.bake.gltf_materials import MaterialReader
from glint.bake.validate import add_warning, check_finite_positions, degenerate_triangles, repair_normals
from glint.core.errors import WarningKind
from glint.core.geometry import face_cross
from glint.core.scene import Object, Scene

_MODES = {0: "points", 1: "lines", 2: "line loop", 3: "line strip", 4: "triangles",
          5: "triangle strip", 6: "triangle fan"}

# Warnings that repeat per object: one summary line each (glint.core.errors.WarningKind), so a
# scene with hundreds of meshes stays readable.
NOT_TRIANGLES = WarningKind("{n} objects are points or lines, not triangles; skipped")
NON_FINITE_UVS = WarningKind("{n} objects have non-finite texture coordinates, set to 0")
ZERO_AREA = WarningKind("{n} objects have zero-area triangles "
                        "(dropped {dropped:,} of their {triangles:,} triangles)")
NO_AREA = WarningKind("{n} objects have no triangles with area and were skipped")
NO_NORMALS = WarningKind("{n} objects have no normals; using flat face normals")
ZERO_NORMALS = WarningKind("{n} objects have zero-length normals ({normals:,} in all), "
                           "replaced by the face normal")
VERTEX_ALPHA = WarningKind("{n} objects have vertex colours (COLOR_0) with alpha below 1; the alpha "
                           "is not supported, ignored")
NO_UVS = WarningKind("{n} objects have a textured material but not the texture coordinates "
                     "it names; the texel at (0, 0) is used everywhere")


class PrimitiveReader:
    """The primitives of one glTF document, each read into an Object."""

    def __init__(self, doc: GltfDocument, accessors: Accessors, materials: MaterialReader,
                 warnings: list[str]):
        self.doc, self.accessors, self.materials = doc, accessors, materials
        self.warn = partial(add_warning, warnings)
        self._names: set[str] = set()

    def _unique(self, name: str) -> str:
        out, k = name, 0
        while out in self._names:
            k += 1
            out = f"{name}.{k}"
        self._names.add(out)
        return out

    def read(self, scene: Scene, prim: dict, world: np.ndarray, node_name: str,
             what: str) -> Object | None:
        """The Object of one primitive of node `node_name` (`what`: which primitive, for messages)
        under the node's world matrix, or None (with a warning) where it has no triangles."""
        prim = self.accessors.draco(prim, node_name, what)
        mode = prim.get("mode", 4)
        attrs = prim.get("attributes", {})
        if mode not in (4, 5, 6):
            self.warn(f"{self.doc.source}: object '{node_name}' {what} is {_MODES.get(mode, mode)}, "
                      "not triangles; skipped", NOT_TRIANGLES, node_name,
                      detail=_MODES.get(mode, str(mode)), ignored=["points and lines"])
            return None
        if "POSITION" not in attrs:
            raise self.doc.bad(f"object '{node_name}' {what} has no POSITION attribute")
        local = self.accessors.read(attrs["POSITION"], f"'{node_name}' POSITION").astype(np.float64)
        if local.shape[1] != 3:
            raise self.doc.bad(f"object '{node_name}' POSITION accessor is not VEC3")
        n = len(local)
        if "indices" in prim:
            flat = self.accessors.read(prim["indices"], f"'{node_name}' indices").reshape(-1)
            if flat.dtype.kind not in "iu":
                raise self.doc.bad(f"object '{node_name}' {what}: indices are not integers")
            flat = flat.astype(np.int64)
        else:
            flat = np.arange(n, dtype=np.int64)
        if flat.size and (flat.min() < 0 or flat.max() >= n):
            raise self.doc.bad(f"object '{node_name}' {what}: index {int(flat.max())} is out of "
                           f"range for {n} vertices")
        if mode == 4 and len(flat) % 3:
            raise self.doc.bad(f"object '{node_name}' {what}: {len(flat)} indices is not a "
                           "multiple of 3")
        indices = _triangles(flat, mode)
        name = self._unique(node_name)

        linear = world[:3, :3]
        with np.errstate(over="ignore", invalid="ignore"):  # overflow is reported just below
            positions = local @ linear.T + world[:3, 3]
        check_finite_positions(name, positions, self.doc.source)
        if np.linalg.det(linear) < 0:  # mirrored: keep counter-clockwise front faces
            indices = indices[:, [0, 2, 1]]

        normals = uvs = colors = None
        if "COLOR_0" in attrs:
            # glTF 3.7.2.1: COLOR_0 (VEC3 or VEC4, linear) multiplies the base colour.
            raw = self.accessors.read(attrs["COLOR_0"], f"'{node_name}' COLOR_0")
            if len(raw) != n or raw.shape[1] not in (3, 4):
                raise self.doc.bad(f"object '{node_name}' COLOR_0 is not VEC3 or VEC4 of one per POSITION")
            colors = np.clip(np.nan_to_num(raw[:, :3].astype(np.float64), nan=0.0, posinf=1.0,
                                           neginf=0.0), 0.0, 1.0)
            if raw.shape[1] == 4 and float(np.nanmin(raw[:, 3], initial=1.0)) < 1.0:
                self.warn(f"{self.doc.source}: object '{name}' has vertex colour alpha below 1 "
                          "(COLOR_0), not supported; ignored", VERTEX_ALPHA, name,
                          ignored=["COLOR_0 alpha"])
        if "NORMAL" in attrs:
            normals = self.accessors.read(attrs["NORMAL"], f"'{node_name}' NORMAL")
            if normals.shape[1] != 3:
                raise self.doc.bad(f"object '{node_name}' NORMAL accessor is not VEC3")
            if len(normals) != n:
                raise self.doc.bad(f"object '{node_name}' NORMAL count differs from POSITION")
            # Inverse transpose up to a positive factor: cofactor * sign(det).
            normals = normals @ (_cofactor(linear) * np.sign(np.linalg.det(linear) or 1.0)).T
        tangents = self._tangents(attrs, linear, n, node_name, name) if normals is not None else None
        # The base colour's texture coordinate set (glTF textureInfo.texCoord), with its
        # KHR_texture_transform applied, so the bake and the viewer read `uvs` as they are.
        material = prim.get("material")
        texcoord, matrix = self.materials.uv_set(material)
        uv_name = f"TEXCOORD_{texcoord}"
        if uv_name in attrs:
            uvs = self.accessors.read(attrs[uv_name], f"'{node_name}' {uv_name}")
            if uvs.shape[1] != 2:
                raise self.doc.bad(f"object '{node_name}' {uv_name} accessor is not VEC2")
            if len(uvs) != n:
                raise self.doc.bad(f"object '{node_name}' {uv_name} count differs from POSITION")
            uvs = uvs.astype(np.float64)
            if not np.all(np.isfinite(uvs)):
                self.warn(f"{self.doc.source}: object '{name}': non-finite texture coordinates "
                          "set to 0", NON_FINITE_UVS, name)
                uvs = np.nan_to_num(uvs, nan=0.0, posinf=0.0, neginf=0.0)
            if matrix is not None:
                uvs = uvs @ matrix[:2, :2].T + matrix[:2, 2]

        bad = degenerate_triangles(positions, indices)
        if bad.any():
            if not bad.all():  # one left with none is reported once, as skipped, just below
                self.warn(f"{self.doc.source}: object '{name}': dropped {int(bad.sum())} zero-area "
                          f"triangle(s) of {len(indices)}", ZERO_AREA, name,
                          detail=str(int(bad.sum())),
                          counts={"dropped": int(bad.sum()), "triangles": len(indices)})
            indices = indices[~bad]
        if len(indices) == 0:
            self.warn(f"{self.doc.source}: object '{name}' has no triangles with area; skipped",
                      NO_AREA, name)
            return None

        if normals is None:
            # glTF: without normals, clients compute flat normals (split every vertex).
            self.warn(f"{self.doc.source}: object '{name}' has no normals; using flat face normals",
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
                self.warn(f"{self.doc.source}: object '{name}': {replaced} zero-length normal(s) "
                          "replaced by the face normal", ZERO_NORMALS, name, detail=str(replaced),
                          counts={"normals": replaced})
        material = prim.get("material")
        if material is None:
            material = self.materials.default(scene)
        else:
            material = self.doc.index(material, len(self.doc.table("materials")),
                                   f"object '{node_name}' {what}", "material")
            textured = scene.materials[material]
            if uvs is None and any(t is not None for t in (
                    textured.kd_texture, textured.emission_texture, textured.metallic_roughness_texture,
                    textured.normal_texture,
                    textured.anisotropy_texture)):
                self.warn(f"{self.doc.source}: object '{name}' has a textured material but no "
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
        raw = self.accessors.read(attrs["TANGENT"], f"'{node_name}' TANGENT")
        if len(raw) != n or raw.shape[1] != 4:
            raise self.doc.bad(f"object '{node_name}' TANGENT is not VEC4 of one per POSITION")
        raw = np.nan_to_num(raw.astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
        xyz = raw[:, :3] @ linear.T
        length = np.linalg.norm(xyz, axis=1, keepdims=True)
        xyz = np.where(length > 1e-12, xyz / np.maximum(length, 1e-12), 0.0)
        w = np.where(raw[:, 3] < 0, -1.0, 1.0) * (-1.0 if np.linalg.det(linear) < 0 else 1.0)
        return np.concatenate([xyz, w[:, None]], axis=1)


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


def _cofactor(m: np.ndarray) -> np.ndarray:
    """det(m) * inv(m).T, defined for singular m too (columns: cross products)."""
    c0, c1, c2 = m[:, 0], m[:, 1], m[:, 2]
    return np.stack([np.cross(c1, c2), np.cross(c2, c0), np.cross(c0, c1)], axis=1)
