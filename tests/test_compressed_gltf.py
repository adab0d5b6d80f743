"""Draco- and meshopt-compressed glTF read like the uncompressed file (bake/gltf_accessors.py).

The compressed files are made here from the uncompressed ones (scenes/gltf_writer.py and
conftest.write_room): `draco()` encodes each primitive with DracoPy as KHR_draco_mesh_compression
describes (the accessors lose their bufferView; the extension maps semantics to Draco attribute
unique ids), `meshopt_file()` re-encodes every bufferView with the meshopt package as
EXT_meshopt_compression describes (the original data moves to a fallback buffer with no data).

Deliberate bugs these catch (each tried in bake/gltf_accessors.py, each failed the tests named):
- Draco POSITION and NORMAL ids swapped in the lookup: the matches, reordered, swapped-ids and
  room-bake tests.
- the Draco bufferView's byteOffset ignored (decoding from the buffer's start): the same four
  (one line "the Draco data cannot be decoded").
- Draco faces taken in reverse order: test_draco_matches_uncompressed (the indices differ).
- DracoPy's exception not caught: test_corrupt_draco_is_one_line (a bare FileTypeException).
- meshopt's `filter` not passed to the decoder: test_meshopt_matches_uncompressed[filters].
- meshopt's row size taken from the bufferView's byteStride (+4) instead of the extension's,
  meshopt's `mode` ignored (all read as ATTRIBUTES), the extension's byteOffset ignored: every
  test_meshopt_matches_uncompressed case.
- a `fallback` buffer without data refused: every meshopt test.
Not caught: the primitive's mode kept instead of set to TRIANGLES (the files here say mode 4).
"""
from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import FAST, write_room

from glint.bake.gltf_container import read_gltf
from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.core.bake_dir import Bake
from glint.core.errors import GlintError
from glint.core.image_io import read_image
from glint.scenes.gltf_writer import GltfWriter
from glint.services import bake_scene

DracoPy = pytest.importorskip("DracoPy")
meshopt = pytest.importorskip("meshopt")

# Quantisation bits used below: Blender's Draco export defaults (position 14, normal 10, texcoord 12).
POS_BITS, NRM_BITS, UV_BITS = 14, 10, 12
_COMPONENTS = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def _accessor(doc, index) -> np.ndarray:
    """A tightly packed accessor of the writer's files (no stride, no sparse)."""
    a = doc.json["accessors"][index]
    v = doc.json["bufferViews"][a["bufferView"]]
    start = v.get("byteOffset", 0) + a.get("byteOffset", 0)
    dtype = np.dtype(_COMPONENTS[a["componentType"]])
    n = a["count"] * _WIDTH[a["type"]]
    return np.frombuffer(doc.buffers[v["buffer"]], dtype, n, start).reshape(a["count"], -1)


def _write_gltf(path, tree, data: bytes, buffers=None):
    tree["buffers"] = buffers or [{"byteLength": len(data), "uri": path.with_suffix(".bin").name}]
    path.with_suffix(".bin").write_bytes(data)
    path.write_text(json.dumps(tree))
    return path


def draco(src, dst, *, preserve_order=True, swap_ids=False):
    """`src` with every primitive Draco-compressed (KHR_draco_mesh_compression), as .gltf."""
    doc = read_gltf(src)
    tree, data = doc.json, bytearray(doc.buffers[0])
    for mesh in tree["meshes"]:
        for prim in mesh["primitives"]:
            attrs = prim["attributes"]
            get = {k: _accessor(doc, attrs[k]).astype(np.float64) for k in attrs}
            faces = _accessor(doc, prim["indices"]).reshape(-1, 3)
            blob = DracoPy.encode(get["POSITION"], faces, quantization_bits=POS_BITS,
                                  normals=get.get("NORMAL"), normal_quantization_bits=NRM_BITS,
                                  tex_coord=get.get("TEXCOORD_0"), tex_coord_quantization_bits=UV_BITS,
                                  preserve_order=preserve_order)
            # The ids DracoPy gave each attribute (Draco AttributeType 0 position, 1 normal, 3 uv).
            ids = {a["attribute_type"]: a["unique_id"] for a in DracoPy.decode(blob).attributes}
            ext = {k: ids[t] for k, t in (("POSITION", 0), ("NORMAL", 1), ("TEXCOORD_0", 3)) if k in attrs}
            if swap_ids:
                ext["POSITION"], ext["NORMAL"] = ext["NORMAL"], ext["POSITION"]
            data.extend(b"\0" * (-len(data) % 4))
            tree["bufferViews"].append({"buffer": 0, "byteOffset": len(data), "byteLength": len(blob)})
            data.extend(blob)
            prim["extensions"] = {"KHR_draco_mesh_compression": {
                "bufferView": len(tree["bufferViews"]) - 1, "attributes": ext}}
            n = len(DracoPy.decode(blob).points)  # the decoded count (deduplicated unless preserved)
            for index in [*attrs.values(), prim["indices"]]:  # spec: no bufferView, count decoded
                a = tree["accessors"][index]
                a.pop("bufferView")
                if index != prim["indices"]:
                    a["count"] = n
                    a.pop("min", None), a.pop("max", None)
    tree["extensionsUsed"] = sorted({*tree.get("extensionsUsed", []), "KHR_draco_mesh_compression"})
    tree["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    return _write_gltf(dst, tree, bytes(data))


def same_triangles(q, p, tol) -> bool:
    """q's triangles are p's, whatever the vertex order and each triangle's first corner: each of
    q's vertices is matched to p's nearest in (position, uv) (the seam repeats positions), within
    `tol`, then the triangles compare as index triples turned to start at their smallest index."""
    from scipy.spatial import cKDTree

    dist, match = cKDTree(np.hstack([p.positions, p.uvs])).query(np.hstack([q.positions, q.uvs]))
    assert dist.max() <= tol, dist.max()

    def rolled(tri):
        first = tri.argmin(axis=1)
        return {tuple(np.roll(t, -f)) for t, f in zip(tri.tolist(), first)}
    return rolled(match[q.indices]) == rolled(p.indices)


def sphere_scene(path):
    """A smooth UV sphere (normals and uvs vary everywhere) and a lit quad."""
    lat, lon = np.meshgrid(np.linspace(0.1, np.pi - 0.1, 9), np.linspace(0, 2 * np.pi, 13), indexing="ij")
    n = np.stack([np.sin(lat) * np.cos(lon), np.cos(lat), np.sin(lat) * np.sin(lon)], -1).reshape(-1, 3)
    uv = np.stack([lon / (2 * np.pi), lat / np.pi], -1).reshape(-1, 2)
    i = np.arange(9 * 13).reshape(9, 13)
    a, b, c, d = i[:-1, :-1], i[:-1, 1:], i[1:, 1:], i[1:, :-1]
    faces = np.concatenate([np.stack([a, b, c], -1), np.stack([a, c, d], -1)]).reshape(-1, 3)
    w = GltfWriter()
    m = w.add_material("Mat")
    w.add_node("Ball", mesh=w.add_mesh("Ball", 0.7 * n + [0, 1, 0], faces, m, normals=n, uvs=uv))
    quad = np.array([[-2, 0, 2], [2, 0, 2], [2, 0, -2], [-2, 0, -2]], float)
    w.add_node("Floor", mesh=w.add_mesh("Floor", quad, [[0, 1, 2], [0, 2, 3]], m,
                                        normals=np.tile([0, 1.0, 0], (4, 1)), uvs=quad[:, [0, 2]] / 4))
    w.add_node("Bulb", light=w.add_light("Bulb", "point", intensity=100.0), translation=(0, 3, 0))
    return w.write(path)


def _tolerances(obj):
    """Largest error Draco's quantisation allows: half a step of the bits over the range.

    Positions and uvs: range / (2^bits - 1) per step (the range is the largest extent of the
    primitive's bounding box, in the primitive's own frame; these nodes have no transform).
    Normals: octahedral coordinates in [-1, 1] quantised to steps of 2 / (2^bits - 1); half a
    step in two coordinates, unfolded and normalised (the octahedron's points lie >= 1/sqrt(3)
    from the centre), moves a component by up to about 1.5 steps (1.37 seen here): 2 allowed."""
    extent = np.ptp(obj.positions, axis=0).max()
    return (extent / (2 ** POS_BITS - 1) / 2 + 1e-6, 2 * 2 / (2 ** NRM_BITS - 1) + 1e-6,
            np.ptp(obj.uvs, axis=0).max() / (2 ** UV_BITS - 1) / 2 + 1e-6)


def test_draco_matches_uncompressed(tmp_path):
    """Positions, normals, uvs and indices within Draco's quantisation of the plain file."""
    plain = load_scene(sphere_scene(tmp_path / "ball.glb"))
    packed = load_scene(draco(tmp_path / "ball.glb", tmp_path / "ball_draco.gltf"))
    assert [o.name for o in packed.objects] == [o.name for o in plain.objects]
    for p, q in zip(plain.objects, packed.objects):
        pos, nrm, uv = _tolerances(p)
        np.testing.assert_array_equal(q.indices, p.indices)  # preserve_order: same vertices
        assert np.abs(q.positions - p.positions).max() <= pos, p.name
        assert np.abs(q.normals - p.normals).max() <= nrm, p.name
        assert np.abs(q.uvs - p.uvs).max() <= uv, p.name
    assert packed.ignored_features == plain.ignored_features == {}


def test_draco_reordered_vertices_same_triangles(tmp_path):
    """Without preserve_order Draco renumbers vertices and faces (as exporters do): the same
    triangles come back. Catches indices read as a strip or with a stale accessor cache."""
    plain = load_scene(sphere_scene(tmp_path / "ball.glb"))
    packed = load_scene(draco(tmp_path / "ball.glb", tmp_path / "ball_draco.gltf", preserve_order=False))
    for p, q in zip(plain.objects, packed.objects):
        pos, _, uv = _tolerances(p)
        assert len(q.indices) == len(p.indices)
        assert same_triangles(q, p, np.sqrt(5) * max(pos, uv)), p.name  # 5-d distance


def test_draco_swapped_ids_differ(tmp_path):
    """The semantic -> unique id map is what is honoured (a loader that guessed by Draco
    attribute type would read the swapped file as if it were right)."""
    plain = load_scene(sphere_scene(tmp_path / "ball.glb"))
    swapped = load_scene(draco(tmp_path / "ball.glb", tmp_path / "x.gltf", swap_ids=True))
    ball = swapped.objects[0]
    assert np.abs(ball.positions - plain.objects[0].positions).max() > 0.1


def lightmap_stats(out):
    """Texel counts of the bake's statistics and the mean of its valid light-map texels."""
    stats = json.loads((out / "manifest.json").read_text())["statistics"]["lightmaps"]
    b = Bake(out)
    pages = [read_image(out / page) for page in b.manifest["lightmaps"]]
    valid = np.concatenate([p[..., :3][p[..., 3] > 0] for p in pages])
    return stats, valid.mean()


@pytest.mark.slow
def test_draco_room_bakes_like_the_plain_room(tmp_path):
    """write_room Draco-compressed (vertices renumbered, 14-bit positions: < 0.1 mm in a 2 m room)
    bakes to the same texel counts and the same mean light-map value within the noise of 8
    samples per texel (the plain room baked with two seeds differs by about 1 %)."""
    room = write_room(tmp_path / "room.glb")
    packed = draco(room, tmp_path / "room_draco.gltf", preserve_order=False)
    results = []
    for path in (room, packed):
        scene = load_scene(path)
        out = tmp_path / (path.stem + ".bake")
        bake_scene(scene, resolve_settings(scene.bake_settings, **FAST), out, progress=False)
        results.append(lightmap_stats(out))
    (a, mean_a), (b, mean_b) = results
    assert b["texels"] == a["texels"]
    assert abs(b["invalid_texels"] - a["invalid_texels"]) <= 0.02 * a["texels"]
    assert mean_a > 0 and abs(mean_b - mean_a) <= 0.03 * mean_a, (mean_a, mean_b)


def test_corrupt_draco_is_one_line(tmp_path):
    """A truncated Draco buffer: one GlintError line naming the object and the extension."""
    path = draco(sphere_scene(tmp_path / "ball.glb"), tmp_path / "ball_draco.gltf")
    tree = json.loads(path.read_text())
    view = tree["bufferViews"][tree["meshes"][0]["primitives"][0]["extensions"]
                               ["KHR_draco_mesh_compression"]["bufferView"]]
    view["byteLength"] = 12  # the header only
    path.write_text(json.dumps(tree))
    with pytest.raises(GlintError) as info:
        load_scene(path)
    message = str(info.value)
    assert "\n" not in message and "'Ball'" in message and "Draco" in message, message


# --------------------------------------------------------------------------- meshopt

OCT_BITS, EXP_BITS = 8, 16


def meshopt_file(src, dst, *, filters=False, name="EXT_meshopt_compression"):
    """`src` with every bufferView meshopt-compressed, as .gltf: the compressed bytes in buffer 1,
    buffer 0 a `fallback` buffer with no data (what gltfpack -c writes). With `filters`, normals
    are stored OCTAHEDRAL (4 signed bytes, KHR_mesh_quantization), positions EXPONENTIAL, and
    indices in INDICES mode instead of TRIANGLES."""
    doc = read_gltf(src)
    tree = doc.json
    version = 1 if name == "KHR_meshopt_compression" else 0
    packed, fallback = bytearray(), len(doc.buffers[0])
    used = {}  # bufferView -> (accessor index, semantic)
    for mesh in tree["meshes"]:
        for prim in mesh["primitives"]:
            used.update({tree["accessors"][i]["bufferView"]: (i, k) for k, i in prim["attributes"].items()})
            used[tree["accessors"][prim["indices"]]["bufferView"]] = (prim["indices"], "indices")
    for view_index, (index, semantic) in sorted(used.items()):
        a, view = tree["accessors"][index], tree["bufferViews"][view_index]
        rows = _accessor(doc, index)
        filt = "NONE"
        if semantic == "indices":
            mode = "INDICES" if filters else "TRIANGLES"
            data = rows.astype(np.uint32).reshape(-1)
            stride = 4
        else:
            mode, data = "ATTRIBUTES", np.ascontiguousarray(rows, np.float32)
            if filters and semantic == "NORMAL":
                filt = "OCTAHEDRAL"
                data = meshopt.encode_filter_oct(np.hstack([rows, np.ones((len(rows), 1))]), 4, OCT_BITS)
                a.update(componentType=5120, normalized=True)
                a.pop("min", None), a.pop("max", None)
                view["byteStride"] = 4
                view["byteOffset"], view["byteLength"] = fallback, 4 * len(rows)  # new room
                fallback += 4 * len(rows)
            elif filters and semantic == "POSITION":
                filt = "EXPONENTIAL"
                data = meshopt.encode_filter_exp(rows, EXP_BITS)
            stride = data.reshape(len(rows), -1).view(np.uint8).shape[1]
        blob = meshopt.encode_gltf_buffer(data.reshape(len(rows), -1) if mode == "ATTRIBUTES" else data,
                                          mode, version)
        packed.extend(b"\0" * (-len(packed) % 4))
        ext = {"buffer": 1, "byteOffset": len(packed), "byteLength": len(blob), "byteStride": stride,
               "count": int(data.size if mode != "ATTRIBUTES" else len(rows)), "mode": mode}
        if filt != "NONE":
            ext["filter"] = filt
        view.setdefault("extensions", {})[name] = ext
        packed.extend(blob)
    tree["extensionsUsed"] = sorted({*tree.get("extensionsUsed", []), name, "KHR_mesh_quantization"})
    tree["extensionsRequired"] = [name, "KHR_mesh_quantization"]
    buffers = [{"byteLength": fallback, "extensions": {name: {"fallback": True}}},
               {"byteLength": len(packed), "uri": dst.with_suffix(".bin").name}]
    return _write_gltf(dst, tree, bytes(packed), buffers)


@pytest.mark.parametrize("filters, name", [(False, "EXT_meshopt_compression"), (True, "EXT_meshopt_compression"),
                                           (False, "KHR_meshopt_compression")],
                         ids=["plain", "filters", "khr"])
def test_meshopt_matches_uncompressed(tmp_path, filters, name):
    """Unfiltered meshopt is lossless (same arrays, and triangles, which TRIANGLES mode may
    rotate); with filters, positions within EXPONENTIAL's 16-bit mantissa (2^-15 of the
    largest component of each vertex) and normals within OCTAHEDRAL's 8 bits (steps of 1/127 in
    two coordinates, normalised: 2 steps allowed, like Draco's above)."""
    plain = load_scene(sphere_scene(tmp_path / "ball.glb"))
    packed = load_scene(meshopt_file(tmp_path / "ball.glb", tmp_path / "ball_mo.gltf", filters=filters, name=name))
    assert [o.name for o in packed.objects] == [o.name for o in plain.objects]
    for p, q in zip(plain.objects, packed.objects):
        assert same_triangles(q, p, 1e-6 if not filters else 1e-3), p.name
        np.testing.assert_array_equal(q.uvs, p.uvs)
        if not filters:
            np.testing.assert_array_equal(q.positions, p.positions)
            np.testing.assert_array_equal(q.normals, p.normals)
            continue
        exp_tol = np.abs(p.positions).max(axis=1, keepdims=True) * 2.0 ** (1 - EXP_BITS)
        assert np.all(np.abs(q.positions - p.positions) <= exp_tol + 1e-7), p.name
        assert np.abs(q.normals - p.normals).max() <= 2 * 1 / (2 ** (OCT_BITS - 1) - 1), p.name


def test_corrupt_meshopt_is_one_line(tmp_path):
    """Compressed bytes cut short: one GlintError line naming the bufferView and the extension."""
    path = meshopt_file(sphere_scene(tmp_path / "ball.glb"), tmp_path / "ball_mo.gltf")
    tree = json.loads(path.read_text())
    tree["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["byteLength"] = 20
    path.write_text(json.dumps(tree))
    with pytest.raises(GlintError) as info:
        load_scene(path)
    message = str(info.value)
    assert "\n" not in message and "bufferView 0" in message and "EXT_meshopt_compression" in message, message
