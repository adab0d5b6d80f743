"""scenes/gltf_writer.py: output read back by trimesh (an independent glTF reader) and as JSON."""
import io
import json
import struct

import numpy as np
import pytest
import trimesh

from glint.scenes.gltf_writer import GltfWriter, encode_png

QUAD_P = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
QUAD_I = np.array([[0, 1, 2], [0, 2, 3]])
QUAD_N = np.tile([0.0, 0.0, 2.0], (4, 1))  # not unit on purpose: the writer normalises
QUAD_UV = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)


def read_glb(path):
    data = path.read_bytes()
    magic, version, length = struct.unpack_from("<III", data, 0)
    assert (magic, version, length) == (0x46546C67, 2, len(data))
    jlen, jtype = struct.unpack_from("<II", data, 12)
    assert jtype == 0x4E4F534A and jlen % 4 == 0
    doc = json.loads(data[20:20 + jlen])
    blen, btype = struct.unpack_from("<II", data, 20 + jlen)
    assert btype == 0x004E4942 and blen % 4 == 0
    assert 28 + jlen + blen == len(data)
    return doc, data[28 + jlen:]


def two_quad_scene():
    w = GltfWriter()
    tex = np.zeros((4, 8, 3), np.uint8)
    tex[:, :4] = (255, 0, 0)
    red = w.add_material("Red", base_color=(1, 0, 0, 1), roughness=0.3, metallic=0.5,
                         base_color_texture=tex, extras={"glint": {"kd": [1, 0, 0]}})
    lamp = w.add_material("Lamp", base_color=(1, 1, 1, 1), emissive=(1, 0.5, 0.25),
                          emissive_strength=20.0, double_sided=True)
    m0 = w.add_mesh("QuadMesh", QUAD_P, QUAD_I, red, normals=QUAD_N, uvs=QUAD_UV)
    m1 = w.add_mesh("LampMesh", QUAD_P, QUAD_I, lamp)
    child = w.add_node("Child", mesh=m0, translation=(0, 0, 1))
    # 90 degrees about +Y: (x, y, z) -> (z, y, -x); parent also scales by 2
    s = np.sqrt(0.5)
    w.add_node("Parent", mesh=m1, rotation=(0, s, 0, s), scale=(2, 2, 2), children=[child])
    mat = np.eye(4)
    mat[:3, 3] = (5, 6, 7)
    w.add_node("Moved", mesh=m0, matrix=mat)
    cam = w.add_camera("Cam", yfov=0.8, znear=0.1, zfar=50, aspect_ratio=1.5)
    w.add_node("CamNode", camera=cam, translation=(0, 1, 3))
    light = w.add_light("Spot", "spot", color=(1, 0.9, 0.8), intensity=100.0,
                        inner_cone_angle=0.2, outer_cone_angle=0.5)
    w.add_node("SpotNode", light=light, translation=(0, 2, 0))
    return w


def world_vertices(scene, node_name):
    transform, geom_name = scene.graph[node_name]
    return trimesh.transform_points(scene.geometry[geom_name].vertices, transform)


def test_glb_structure_and_json(tmp_path):
    path = two_quad_scene().write(tmp_path / "s.glb")
    doc, binary = read_glb(path)
    assert doc["asset"]["version"] == "2.0"
    # Child is referenced by Parent, so only Parent, Moved, CamNode and SpotNode are roots.
    names = [n["name"] for n in doc["nodes"]]
    assert [names[i] for i in doc["scenes"][0]["nodes"]] == ["Parent", "Moved", "CamNode", "SpotNode"]
    assert doc["extensionsUsed"] == ["KHR_lights_punctual", "KHR_materials_emissive_strength"]
    lamp = doc["materials"][1]
    assert lamp["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"] == 20.0
    assert lamp["emissiveFactor"] == [1.0, 0.5, 0.25] and lamp["doubleSided"] is True
    assert "extensions" not in doc["materials"][0]
    assert doc["materials"][0]["extras"] == {"glint": {"kd": [1, 0, 0]}}
    # Column-major matrix: the translation is in elements 12..14.
    assert doc["nodes"][2]["matrix"][12:15] == [5.0, 6.0, 7.0]
    assert doc["cameras"][0]["perspective"] == {"yfov": 0.8, "znear": 0.1, "zfar": 50.0,
                                                "aspectRatio": 1.5}
    light = doc["extensions"]["KHR_lights_punctual"]["lights"][0]
    assert light["type"] == "spot" and light["spot"] == {"innerConeAngle": 0.2, "outerConeAngle": 0.5}
    assert doc["nodes"][4]["extensions"]["KHR_lights_punctual"]["light"] == 0
    # Accessors: POSITION has min/max, every view 4-byte aligned and inside the buffer.
    pos = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
    assert pos["min"] == [0.0, 0.0, 0.0] and pos["max"] == [1.0, 1.0, 0.0]
    for view in doc["bufferViews"]:
        assert view["byteOffset"] % 4 == 0
        assert view["byteOffset"] + view["byteLength"] <= doc["buffers"][0]["byteLength"] <= len(binary)
    # The normal accessor holds unit vectors.
    nacc = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["NORMAL"]]
    view = doc["bufferViews"][nacc["bufferView"]]
    normals = np.frombuffer(binary, np.float32, nacc["count"] * 3, view["byteOffset"]).reshape(-1, 3)
    np.testing.assert_allclose(normals, np.tile([0, 0, 1], (4, 1)))


def test_trimesh_reads_geometry_transforms_and_materials(tmp_path):
    path = two_quad_scene().write(tmp_path / "s.glb")
    scene = trimesh.load(path, force="scene")
    # Parent: rotate 90 deg about Y then scale 2: (x, y, z) -> 2 * (z, y, -x)
    expect_parent = 2 * np.stack([QUAD_P[:, 2], QUAD_P[:, 1], -QUAD_P[:, 0]], axis=1)
    np.testing.assert_allclose(world_vertices(scene, "Parent"), expect_parent, atol=1e-6)
    # Child: translated by (0, 0, 1) in Parent's frame, so z=1 -> world x=+2.
    expect_child = 2 * np.stack([QUAD_P[:, 2] + 1, QUAD_P[:, 1], -QUAD_P[:, 0]], axis=1)
    np.testing.assert_allclose(world_vertices(scene, "Child"), expect_child, atol=1e-6)
    np.testing.assert_allclose(world_vertices(scene, "Moved"), QUAD_P + (5, 6, 7), atol=1e-6)
    _, gname = scene.graph["Child"]
    geom = scene.geometry[gname]
    np.testing.assert_array_equal(geom.faces, QUAD_I)
    np.testing.assert_allclose(geom.vertex_normals, np.tile([0, 0, 1], (4, 1)), atol=1e-6)
    mat = geom.visual.material
    assert mat.name == "Red"
    assert mat.roughnessFactor == pytest.approx(0.3) and mat.metallicFactor == pytest.approx(0.5)
    # glTF's v runs down the image; trimesh flips it to OpenGL's v-up on load.
    np.testing.assert_allclose(geom.visual.uv, np.c_[QUAD_UV[:, 0], 1 - QUAD_UV[:, 1]])
    tex = np.asarray(mat.baseColorTexture.convert("RGB"))
    assert tex.shape == (4, 8, 3)
    assert (tex[:, :4] == (255, 0, 0)).all() and (tex[:, 4:] == 0).all()
    lamp = scene.geometry[scene.graph["Parent"][1]].visual.material
    np.testing.assert_allclose(lamp.emissiveFactor, [1, 0.5, 0.25])
    assert lamp.doubleSided
    # trimesh renames a camera's node after the camera
    np.testing.assert_allclose(scene.camera_transform[:3, 3], [0, 1, 3])
    assert np.degrees(0.8) == pytest.approx(scene.camera.fov[1])


def test_gltf_with_sibling_bin_matches_glb(tmp_path):
    w = two_quad_scene()
    w.write(tmp_path / "a.gltf")
    w.write(tmp_path / "a.glb")
    doc = json.loads((tmp_path / "a.gltf").read_text())
    assert doc["buffers"][0]["uri"] == "a.bin" and (tmp_path / "a.bin").exists()
    a = trimesh.load(tmp_path / "a.gltf", force="scene")
    b = trimesh.load(tmp_path / "a.glb", force="scene")
    for name in ("Parent", "Child", "Moved"):
        np.testing.assert_allclose(world_vertices(a, name), world_vertices(b, name))


def test_png_encoder_round_trips_through_pil():
    from PIL import Image

    rng = np.random.default_rng(1)
    for channels, level, shape in ((3, 9, (5, 7)), (4, 9, (5, 7)), (3, 0, (5, 7)),
                                   (4, 0, (150, 130))):  # > 64 KiB: several stored blocks
        img = rng.integers(0, 256, shape + (channels,), dtype=np.uint8)
        back = np.asarray(Image.open(io.BytesIO(encode_png(img, level))))
        np.testing.assert_array_equal(back, img)


def test_output_is_deterministic(tmp_path):
    two_quad_scene().write(tmp_path / "x.glb")
    two_quad_scene().write(tmp_path / "y.glb")
    assert (tmp_path / "x.glb").read_bytes() == (tmp_path / "y.glb").read_bytes()


def test_bad_arguments():
    w = GltfWriter()
    with pytest.raises(ValueError):
        w.add_mesh("bad", QUAD_P, [[0, 1, 4]], None)
    with pytest.raises(ValueError):
        w.add_light("l", "area")
    with pytest.raises(ValueError):
        w.add_node("n", translation=(0, 0, 0), matrix=np.eye(4))
