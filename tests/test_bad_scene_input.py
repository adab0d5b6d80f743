"""Bad scene input: one GlintError naming the problem, never a bare exception."""
import json
import struct

import numpy as np
import pytest

from glint.bake.gltf_loader import load_scene
from glint.core.errors import GlintError
from glint.scenes.gltf_writer import GltfWriter

QUAD_P = np.array([[0, 0, 0], [1, 0, 0], [1, 0, -1], [0, 0, -1]], float)
QUAD_I = np.array([[0, 1, 2], [0, 2, 3]])
QUAD_N = np.tile([0.0, 1.0, 0.0], (4, 1))


def good(light=True, positions=QUAD_P, name="Floor") -> GltfWriter:
    w = GltfWriter()
    m = w.add_material("Mat")
    w.add_node(name, mesh=w.add_mesh("FloorMesh", positions, QUAD_I, m, normals=QUAD_N))
    if light:
        w.add_node("Bulb", light=w.add_light("Bulb", "point"), translation=(0, 2, 0))
    return w


def error(path) -> str:
    with pytest.raises(GlintError) as info:
        load_scene(path)
    message = str(info.value)
    assert "\n" not in message  # one line
    return message


def edit_json(path, fn):
    doc = json.loads(path.read_text())
    fn(doc)
    path.write_text(json.dumps(doc))


def test_missing_file(tmp_path):
    msg = error(tmp_path / "nothing.glb")
    assert "nothing.glb" in msg and "no such file" in msg


def test_bad_json_names_line(tmp_path):
    path = tmp_path / "broken.gltf"
    path.write_text('{\n  "asset": {"version": "2.0"},\n  "nodes": [\n}\n')
    msg = error(path)
    assert "broken.gltf" in msg and "invalid JSON" in msg and "line 4" in msg


def test_truncated_glb(tmp_path):
    path = tmp_path / "scene.glb"
    good().write(path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) - 40])
    msg = error(path)
    assert "truncated" in msg and "scene.glb" in msg


def test_not_a_glb(tmp_path):
    path = tmp_path / "scene.glb"
    path.write_bytes(b"PK\x03\x04 this is a zip file")
    assert "not a binary glTF" in error(path)


def test_missing_buffer_file(tmp_path):
    path = tmp_path / "scene.gltf"
    good().write(path)
    (tmp_path / "scene.bin").unlink()
    msg = error(path)
    assert "buffer 0" in msg and "scene.bin" in msg and "missing" in msg


def test_short_buffer_file(tmp_path):
    path = tmp_path / "scene.gltf"
    good().write(path)
    (tmp_path / "scene.bin").write_bytes(b"\0" * 10)
    assert "buffer 0 is truncated" in error(path)


def assert_mentions(message: str, parts: list[str]) -> None:
    for part in parts:
        assert part in message, (part, message)


@pytest.mark.parametrize("edit, expected", [
    (lambda d: d["accessors"][0].update(count=1000), ["accessor 0", "POSITION", "bufferView"]),  # past its view
    (lambda d: d["accessors"][0].update(componentType=1234), ["componentType 1234"]),
    (lambda d: d["nodes"][0].update(mesh=7), ["mesh 7, which does not exist"]),
    (lambda d: d["meshes"][0]["primitives"][0].update(mode=1), ["no triangle meshes"]),  # lines only
    (lambda d: d.update(extensionsRequired=["EXT_mesh_gpu_instancing"],
                        extensionsUsed=["EXT_mesh_gpu_instancing"]), ["EXT_mesh_gpu_instancing", "requires"]),
], ids=["accessor-past-end", "bad-component-type", "missing-mesh", "lines-only", "required-extension"])
def test_broken_gltf_is_one_line_naming_what_is_wrong(tmp_path, edit, expected):
    path = tmp_path / "scene.gltf"
    good().write(path)
    edit_json(path, edit)
    assert_mentions(error(path), expected)


def test_index_out_of_range(tmp_path):
    path = tmp_path / "scene.gltf"
    good().write(path)

    def widen(d):  # the index accessor reads the POSITION floats as indices
        prim = d["meshes"][0]["primitives"][0]
        d["accessors"][prim["indices"]]["bufferView"] = d["accessors"][0]["bufferView"]
        d["accessors"][prim["indices"]]["count"] = 6
    edit_json(path, widen)
    msg = error(path)
    assert "'Floor'" in msg and "out of range" in msg


def test_no_triangle_meshes(tmp_path):
    w = GltfWriter()
    w.add_node("Bulb", light=w.add_light("Bulb", "point"))
    path = tmp_path / "empty.glb"
    w.write(path)
    assert "no triangle meshes" in error(path)


def test_nan_vertex_names_object(tmp_path):
    p = QUAD_P.copy()
    p[2, 1] = np.nan
    path = tmp_path / "scene.glb"
    good(positions=p, name="Bad chair").write(path)
    msg = error(path)
    assert "'Bad chair'" in msg and "NaN" in msg


def test_inf_in_node_transform_names_object(tmp_path):
    path = tmp_path / "scene.gltf"
    good(name="Lamp shade").write(path)
    edit_json(path, lambda d: d["nodes"][0].update(scale=[1e308, 1e308, 1e308]) or
              d["nodes"][0].update(translation=[1e308, 0, 0]))
    # 1e308 * 1 + 1e308 overflows to inf in world space
    msg = error(path)
    assert "'Lamp shade'" in msg


def test_no_light_names_the_three_ways(tmp_path):
    path = tmp_path / "dark.glb"
    good(light=False).write(path)
    msg = error(path)
    assert "no light" in msg
    assert "emissive" in msg and "KHR_lights_punctual" in msg and "[sky]" in msg
    assert "dark.glint.toml" in msg


@pytest.mark.parametrize("sidecar, expected", [
    ('[bake]\nquality = "draft"\nsamples = \n', ["scene.glint.toml", "line 3"]),  # bad TOML: file and line
    ('[sky]\nradiance = "blue"\n', ["scene.glint.toml", "[sky] radiance"]),  # wrong type
    ('[objects."Floor"]\nrole = "shiny"\n', ["role must be one of diffuse, curved, planar, transmissive, not 'shiny'", "planar", "scene.glint.toml"]),
    ('[materials."Mat"]\nlobes = [ { kind = "refract", mx = 0.1 } ]\n', ["lobes[0] kind", "refract"]),
    ('[sky]\nmap = "nowhere.exr"\n', ["[sky] map", "nowhere.exr"]),  # missing sky map
], ids=["bad-toml", "wrong-type", "unknown-role", "bad-lobe", "missing-sky-map"])
def test_bad_sidecar_is_one_line_naming_what_is_wrong(tmp_path, sidecar, expected):
    path = tmp_path / "scene.glb"
    good().write(path)
    (tmp_path / "scene.glint.toml").write_text(sidecar)
    assert_mentions(error(path), expected)


def test_glb_with_chunk_length_past_end(tmp_path):
    path = tmp_path / "scene.glb"
    good().write(path)
    data = bytearray(path.read_bytes())
    jlen = struct.unpack_from("<I", data, 12)[0]
    struct.pack_into("<I", data, 20 + jlen, 10 ** 6)  # BIN chunk claims 1 MB
    path.write_bytes(bytes(data))
    assert "truncated .glb" in error(path)
