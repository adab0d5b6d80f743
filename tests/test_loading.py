"""bake/gltf_loader.py, bake/material_mapping.py, bake/sidecar.py: glTF + sidecar -> Scene.

Fixtures are written with scenes/gltf_writer.py; expected values come from
trimesh (an independent glTF reader), from hand-built matrices, from published
sRGB values, or from the glTF / KHR spec definitions written out by hand.
"""
import json
import math

import numpy as np
import pytest
import trimesh

from glint.bake.gltf_loader import load_scene
from glint.bake.gltf_fit_table import fit_table
from glint.bake.material_mapping import GltfPbr, map_pbr
from glint.scenes.gltf_writer import GltfWriter

QUAD_P = np.array([[0, 0, 0], [1, 0, 0], [1, 0, -1], [0, 0, -1]], float)  # y = 0, 1 m^2
QUAD_I = np.array([[0, 1, 2], [0, 2, 3]])  # counter-clockwise seen from +Y
QUAD_N = np.tile([0.0, 1.0, 0.0], (4, 1))
QUAD_UV = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
S = math.sqrt(0.5)


def lit(w: GltfWriter) -> GltfWriter:
    """Add a point light so the scene is valid."""
    w.add_node("Bulb", light=w.add_light("Bulb", "point", intensity=683.0), translation=(0, 3, 0))
    return w


def quad_writer(**material) -> GltfWriter:
    w = GltfWriter()
    m = w.add_material("Mat", **material)
    w.add_node("Quad", mesh=w.add_mesh("QuadMesh", QUAD_P, QUAD_I, m, normals=QUAD_N, uvs=QUAD_UV))
    return lit(w)


def write(w: GltfWriter, tmp_path, name="scene.glb", sidecar=None):
    path = tmp_path / name
    w.write(path)
    if sidecar is not None:
        (tmp_path / (path.stem + ".glint.toml")).write_text(sidecar)
    return path


def edit_json(path, fn):
    doc = json.loads(path.read_text())
    fn(doc)
    path.write_text(json.dumps(doc))


def obj(scene, name):
    return next(o for o in scene.objects if o.name == name)


def face_normals(o):
    p = o.positions[o.indices]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


# ----------------------------------------------------------------------------- geometry


def test_node_transforms_match_trimesh_and_hand_matrices(tmp_path):
    """Rotated + non-uniformly scaled + mirrored node, nested under a translated parent."""
    w = GltfWriter()
    m = w.add_material("Mat")
    tilted = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 1]], float)  # plane normal (0, -1, 1)/sqrt2
    tn = np.tile([0, -S, S], (3, 1))
    mesh = w.add_mesh("Tri", tilted, [[0, 1, 2]], m, normals=tn)
    # child: 90 degrees about +Z, scale (-1, 3, 0.5) (mirror), translation (1, 2, 3)
    child = w.add_node("Child", mesh=mesh, translation=(1, 2, 3), rotation=(0, 0, S, S),
                       scale=(-1, 3, 0.5))
    parent_m = np.eye(4)
    parent_m[:3, 3] = (10, 0, 0)
    w.add_node("Parent", matrix=parent_m, children=[child])
    path = write(lit(w), tmp_path)
    scene = load_scene(path)
    o = obj(scene, "Child")

    # Hand-built: T_parent @ T @ R @ S
    rz = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], float)
    linear = rz @ np.diag([-1, 3, 0.5])
    expected = tilted @ linear.T + np.array([11, 2, 3])
    np.testing.assert_allclose(o.positions, expected, atol=1e-6)

    # trimesh, an independent reader, agrees on the world positions.
    tm = trimesh.load(path, force="scene")
    nodes = [n for n in tm.graph.nodes_geometry if tm.graph[n][1] is not None]
    transform, geom = tm.graph[nodes[0]]
    ref = trimesh.transform_points(tm.geometry[geom].vertices, transform)
    np.testing.assert_allclose(np.sort(o.positions, axis=0), np.sort(ref, axis=0), atol=1e-5)

    # Normals stay perpendicular to the transformed surface (inverse transpose), unit length,
    # and the mirrored winding still makes them agree with the geometric face normal.
    edge1, edge2 = expected[1] - expected[0], expected[2] - expected[0]
    np.testing.assert_allclose(o.normals @ edge1, 0, atol=1e-6)
    np.testing.assert_allclose(o.normals @ edge2, 0, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(o.normals, axis=1), 1, atol=1e-6)
    assert np.all(face_normals(o) @ o.normals[0] > 0.999)
    want = np.linalg.inv(linear).T @ np.array([0, -S, S])
    np.testing.assert_allclose(o.normals[0], want / np.linalg.norm(want), atol=1e-6)


def test_instanced_mesh_and_repeated_names_get_unique_object_names(tmp_path):
    w = GltfWriter()
    m = w.add_material("Mat")
    mesh = w.add_mesh("QuadMesh", QUAD_P, QUAD_I, m, normals=QUAD_N)
    for x in (0, 2, 4):
        w.add_node("Tile", mesh=mesh, translation=(x, 0, 0))
    scene = load_scene(write(lit(w), tmp_path))
    assert sorted(o.name for o in scene.objects) == ["Tile", "Tile.1", "Tile.2"]
    xs = sorted(o.positions[:, 0].min() for o in scene.objects)
    np.testing.assert_allclose(xs, [0, 2, 4])


def test_multi_primitive_mesh_gives_one_object_per_primitive_with_its_material(tmp_path):
    w = GltfWriter()
    a = w.add_material("A", base_color=(1, 0, 0, 1))
    b = w.add_material("B", base_color=(0, 0, 1, 1))
    w.add_mesh("Part0", QUAD_P, QUAD_I, a, normals=QUAD_N)
    w.add_mesh("Part1", QUAD_P + [0, 1, 0], QUAD_I, b, normals=QUAD_N)
    w.add_node("Shelf", mesh=0)
    path = write(lit(w), tmp_path, "scene.gltf")

    def merge(doc):  # mesh 0 gets both primitives
        doc["meshes"][0]["primitives"].append(doc["meshes"][1]["primitives"][0])
        doc["meshes"].pop()
    edit_json(path, merge)
    scene = load_scene(path)
    assert [o.name for o in scene.objects] == ["Shelf", "Shelf.1"]
    mats = [scene.material_of(o).name for o in scene.objects]
    assert mats == ["A", "B"]
    np.testing.assert_allclose(scene.objects[1].positions[:, 1], 1.0)
    kd = scene.material_of(scene.objects[1]).kd  # blue, plus the rough dielectric's dropped lobe (grey)
    assert kd[2] > 0.9 and kd[0] == kd[1] < 0.05


def test_gltf_with_external_bin_equals_glb(tmp_path):
    w = quad_writer(base_color=(0.5, 0.25, 0.125, 1))
    a = load_scene(write(w, tmp_path, "scene.glb"))
    b = load_scene(write(w, tmp_path, "other.gltf"))
    assert (tmp_path / "other.bin").exists()
    assert json.loads((tmp_path / "other.gltf").read_text())["buffers"][0]["uri"] == "other.bin"
    for oa, ob in zip(a.objects, b.objects):
        np.testing.assert_array_equal(oa.positions, ob.positions)
        np.testing.assert_array_equal(oa.indices, ob.indices)
        np.testing.assert_array_equal(oa.uvs, ob.uvs)
    np.testing.assert_array_equal(a.materials[0].kd, b.materials[0].kd)
    np.testing.assert_allclose(a.materials[0].kd, [0.5, 0.25, 0.125], atol=0.02)
    assert a.name == "scene" and b.name == "other"


def test_texcoords_and_base_colour_texture_linearised(tmp_path):
    tex = np.zeros((2, 3, 4), np.uint8)
    tex[0, :, :3] = (255, 128, 0)  # top row
    tex[1, :, :3] = (188, 188, 188)
    tex[..., 3] = 255
    scene = load_scene(write(quad_writer(base_color_texture=tex), tmp_path))
    o = scene.objects[0]
    np.testing.assert_allclose(o.uvs, QUAD_UV)
    kt = scene.materials[0].kd_texture
    assert kt.shape == (2, 3, 3) and kt.dtype == np.float32
    # Published sRGB -> linear values: 255 -> 1, 128 -> 0.21586, 188 -> 0.50289
    np.testing.assert_allclose(kt[0, 0], [1.0, 0.215861, 0.0], atol=1e-5)
    np.testing.assert_allclose(kt[1, 2], [0.502886] * 3, atol=1e-5)


def test_triangle_strip_and_fan_are_triangulated_counter_clockwise(tmp_path):
    path = write(quad_writer(), tmp_path, "scene.gltf")

    def strip(doc):  # vertices 0,1,3,2 as a strip = the same quad
        prim = doc["meshes"][0]["primitives"][0]
        prim["mode"] = 5
        idx = doc["accessors"][prim["indices"]]
        view = doc["bufferViews"][idx["bufferView"]]
        doc["buffers"][0]["uri"] = "strip.bin"
        data = bytearray((tmp_path / "scene.bin").read_bytes())
        data[view["byteOffset"]:view["byteOffset"] + 16] = np.array([0, 1, 3, 2], "<u4").tobytes()
        (tmp_path / "strip.bin").write_bytes(bytes(data))
        idx["count"] = 4
    edit_json(path, strip)
    o = load_scene(path).objects[0]
    assert len(o.indices) == 2
    assert np.all(face_normals(o) @ [0, 1, 0] > 0.999)
    assert o.area == pytest.approx(1.0)


# ----------------------------------------------------------------------------- repairs


def test_missing_normals_are_flat_and_zero_normals_replaced(tmp_path):
    w = GltfWriter()
    m = w.add_material("Mat")
    # a roof: two faces sharing an edge, no normals in the file
    roof = np.array([[0, 0, 0], [1, 0, 0], [1, 1, -1], [0, 1, -1], [1, 0, -2], [0, 0, -2]], float)
    roof_i = [[0, 1, 2], [0, 2, 3], [3, 2, 4], [3, 4, 5]]
    w.add_node("Roof", mesh=w.add_mesh("Roof", roof, roof_i, m))
    zero = QUAD_N.copy()
    zero[1] = 0
    w.add_node("Quad", mesh=w.add_mesh("Quad", QUAD_P, QUAD_I, m, normals=zero))
    scene = load_scene(write(lit(w), tmp_path))
    r = obj(scene, "Roof")
    # Flat: every vertex normal equals its own face's normal (vertices split per face).
    np.testing.assert_allclose(r.normals[r.indices[:, 0]], face_normals(r), atol=1e-6)
    np.testing.assert_allclose(r.normals[0], [0, S, S], atol=1e-6)
    np.testing.assert_allclose(r.normals[-1], [0, S, -S], atol=1e-6)
    q = obj(scene, "Quad")
    np.testing.assert_allclose(q.normals, np.tile([0, 1, 0], (4, 1)), atol=1e-6)
    assert any("'Roof' has no normals" in m for m in scene.warnings)
    assert any("'Quad': 1 zero-length normal" in m for m in scene.warnings)


def test_zero_normal_on_shared_vertex_gets_area_weighted_face_normal():
    from glint.bake.validate import repair_normals

    # vertex 0 is shared by a 2 m^2 triangle facing +Z and a 0.5 m^2 triangle facing +X
    p = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0, 0, -1], [0, 1, 0]], float)
    idx = np.array([[0, 1, 2], [0, 3, 4]])
    n = np.array([[0, 0, 0], [0, 0, 2], [0, 0, 1], [1, 0, 0], [1, 0, 0]], float)
    out, replaced = repair_normals(n, p, idx)
    assert replaced == 1
    want = np.array([0.5, 0, 2.0]) / np.hypot(0.5, 2.0)
    np.testing.assert_allclose(out[0], want, atol=1e-6)
    np.testing.assert_allclose(out[1], [0, 0, 1])  # non-unit normals are normalised


def test_degenerate_triangles_dropped_and_counted(tmp_path, capsys):
    w = GltfWriter()
    m = w.add_material("Mat")
    p = np.vstack([QUAD_P, [[0.5, 0, 0]]])  # vertex 4 on the edge 0-1
    idx = np.vstack([QUAD_I, [[0, 1, 4], [2, 2, 3]]])  # collinear + repeated corner
    w.add_node("Quad", mesh=w.add_mesh("Quad", p, idx, m, normals=np.tile([0, 1, 0], (5, 1))))
    scene = load_scene(write(lit(w), tmp_path))
    o = scene.objects[0]
    assert len(o.indices) == 2 and len(o.positions) == 4  # unused vertex 4 removed
    assert o.area == pytest.approx(1.0)
    assert any("dropped 2 zero-area triangle(s) of 4" in m for m in scene.warnings)
    assert "dropped 2 zero-area" in capsys.readouterr().err


def test_line_primitives_skipped_with_warning(tmp_path):
    path = write(quad_writer(), tmp_path, "scene.gltf")

    def add_lines(doc):
        prim = dict(doc["meshes"][0]["primitives"][0], mode=1)
        prim.pop("indices")
        doc["meshes"].append({"name": "Wire", "primitives": [prim]})
        doc["nodes"].append({"name": "Wire", "mesh": 1})
        doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)
    edit_json(path, add_lines)
    scene = load_scene(path)
    assert [o.name for o in scene.objects] == ["Quad"]
    assert any("'Wire'" in m and "lines" in m and "skipped" in m for m in scene.warnings)


def test_unsupported_optional_extension_warns(tmp_path):
    path = write(quad_writer(), tmp_path, "scene.gltf")
    edit_json(path, lambda d: d["extensionsUsed"].append("KHR_materials_sheen"))
    scene = load_scene(path)
    assert any("KHR_materials_sheen" in m for m in scene.warnings)


# ----------------------------------------------------------------------------- cameras, lights


def test_all_cameras_world_frame(tmp_path):
    w = quad_writer()
    c0 = w.add_camera("Front", yfov=0.8, znear=0.1, zfar=50, aspect_ratio=1.5)
    c1 = w.add_camera("Side", yfov=1.0)
    w.add_node("FrontCam", camera=c0, translation=(0, 1.6, 3))
    # 90 degrees about +Y: -Z (view) -> -X
    w.add_node("SideCam", camera=c1, translation=(4, 1, 0), rotation=(0, S, 0, S))
    # under a parent turned 180 degrees about +Y, scaled 2: -Z -> +Z, origin (0,0,2)->(0,0,-4)
    c2 = w.add_camera("Back", yfov=0.5)
    child = w.add_node("BackCam", camera=c2, translation=(0, 0, 2))
    w.add_node("Rig", rotation=(0, 1, 0, 0), scale=(2, 2, 2), children=[child])
    scene = load_scene(write(w, tmp_path))
    cams = {c.name: c for c in scene.cameras}
    assert set(cams) == {"FrontCam", "SideCam", "BackCam"}
    f = cams["FrontCam"]
    np.testing.assert_allclose(f.eye, [0, 1.6, 3])
    np.testing.assert_allclose(f.forward, [0, 0, -1], atol=1e-9)
    np.testing.assert_allclose(f.up, [0, 1, 0], atol=1e-9)
    assert (f.yfov, f.aspect, f.znear, f.zfar) == (0.8, 1.5, 0.1, 50.0)
    s = cams["SideCam"]
    np.testing.assert_allclose(s.forward, [-1, 0, 0], atol=1e-9)
    np.testing.assert_allclose(s.up, [0, 1, 0], atol=1e-9)
    b = cams["BackCam"]
    np.testing.assert_allclose(b.eye, [0, 0, -4], atol=1e-9)
    np.testing.assert_allclose(b.forward, [0, 0, 1], atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(b.up), 1)


def test_punctual_lights_photometric_units(tmp_path):
    w = GltfWriter()
    m = w.add_material("Mat")
    w.add_node("Quad", mesh=w.add_mesh("Q", QUAD_P, QUAD_I, m, normals=QUAD_N))
    w.add_node("P", light=w.add_light("Point", "point", color=(1, 0.5, 0.25), intensity=1366.0),
               translation=(1, 2, 3))
    w.add_node("Sp", light=w.add_light("Spot", "spot", intensity=683.0, inner_cone_angle=0.2,
                                       outer_cone_angle=0.6), translation=(0, 3, 0),
               rotation=(-S, 0, 0, S))  # -90 degrees about X: -Z -> -Y
    w.add_node("Sd", light=w.add_light("SpotDefault", "spot", intensity=68.3))
    w.add_node("Sun", light=w.add_light("Sun", "directional", intensity=100000.0),
               rotation=(0, S, 0, S))  # -Z -> -X
    scene = load_scene(write(w, tmp_path))
    (p,) = scene.point_lights
    np.testing.assert_allclose(p.position, [1, 2, 3])
    np.testing.assert_allclose(p.intensity, [2, 1, 0.5], rtol=1e-6)  # cd / 683 = W/sr
    spot, default = scene.spot_lights
    np.testing.assert_allclose(spot.direction, [0, -1, 0], atol=1e-9)
    np.testing.assert_allclose(spot.intensity, [1, 1, 1], rtol=1e-6)
    assert (spot.inner_cone, spot.outer_cone) == (0.2, 0.6)
    assert (default.inner_cone, default.outer_cone) == (0.0, pytest.approx(math.pi / 4))
    np.testing.assert_allclose(default.direction, [0, 0, -1])
    np.testing.assert_allclose(default.intensity, [0.1] * 3, rtol=1e-6)
    (sun,) = scene.directional_lights
    np.testing.assert_allclose(sun.direction, [-1, 0, 0], atol=1e-9)
    np.testing.assert_allclose(sun.irradiance, [100000 / 683] * 3, rtol=1e-6)  # lux / 683 = W/m^2


def test_radiometric_units_from_sidecar(tmp_path):
    w = quad_writer()
    scene = load_scene(write(w, tmp_path, sidecar='[lights]\nunits = "radiometric"\n'))
    np.testing.assert_allclose(scene.point_lights[0].intensity, [683.0] * 3)


# ----------------------------------------------------------------------------- materials


def test_emissive_strength_is_linear_radiance(tmp_path):
    w = GltfWriter()
    lamp = w.add_material("Lamp", emissive=(1, 0.5, 0.25), emissive_strength=20.0)
    w.add_node("Lamp", mesh=w.add_mesh("L", QUAD_P, QUAD_I, lamp, normals=QUAD_N))
    scene = load_scene(write(w, tmp_path))  # the emitter is the only light: valid
    np.testing.assert_allclose(scene.materials[0].emission, [20, 10, 5])
    assert scene.emitters[0].name == "Lamp"


def test_mapping_rule_dielectric_metal_rough_glass_anisotropic():
    """The rule of bake/material_mapping.py with the fitted table's values (bake/gltf_fit_table.py;
    that the table follows the glTF BRDF: tests/test_gltf_mapping_albedo.py)."""
    table = fit_table()
    share = table.diffuse_share(0.04)
    # Smooth dielectric: diffuse base x fresnel_mix's share + one white lobe, the table's for f0 0.04.
    kd, lobes, _ = map_pbr(GltfPbr(base_color=(0.5, 0.4, 0.3), metallic=0, roughness=0.15))
    np.testing.assert_allclose(kd, np.array([0.5, 0.4, 0.3]) * share, rtol=1e-6)
    (lobe,) = lobes  # one lobe: a dielectric layer's rows have one
    (fitted,) = table.specular_lobes(0.15, 0.04)
    assert lobe.kind == "reflect" and lobe.ks == pytest.approx((fitted.ks,) * 3)
    assert lobe.r0 == pytest.approx(fitted.r0) and lobe.mx == lobe.my == pytest.approx(fitted.m)
    assert 0.85 * 0.04 <= lobe.r0 <= 1.15 * 0.04 and 0.3 < lobe.alpha < 0.6  # Kurt's alpha: not 0
    # Metal: no diffuse; the table's lobes for f0 = the brightest channel (several at roughness 0.7,
    # narrowest first: together they follow GGX's tail). A coloured metal: each lobe as two lobes of
    # its shape, F = 1 and F = (1 - cos)^5, weighted per channel so that each has Schlick's r0 = f0
    # scaled by its colour. A grey metal: the table's lobes.
    kd, lobes, _ = map_pbr(GltfPbr(base_color=(0.9, 0.6, 0.2), metallic=1, roughness=0.7))
    np.testing.assert_allclose(kd, 0)
    fitted = table.specular_lobes(0.7, 0.9)
    assert len(fitted) > 1 and len(lobes) == 2 * len(fitted)
    for (full, fresnel), lb in zip(zip(lobes[::2], lobes[1::2]), fitted, strict=True):
        r0_c = np.array([lb.r0 * c / 0.9 for c in (0.9, 0.6, 0.2)])
        np.testing.assert_allclose([(full.r0, full.mx, full.alpha), (fresnel.r0, fresnel.mx, fresnel.alpha)],
                                   [(1.0, lb.m, lb.alpha), (0.0, lb.m, lb.alpha)])
        np.testing.assert_allclose(full.ks, lb.ks * r0_c, rtol=1e-6)
        np.testing.assert_allclose(fresnel.ks, lb.ks * (1 - r0_c), rtol=1e-6)
    grey = map_pbr(GltfPbr(base_color=(0.6, 0.6, 0.6), metallic=1, roughness=0.7))[1]
    for lobe, fitted in zip(grey, table.specular_lobes(0.7, 0.6), strict=True):
        assert lobe.ks == pytest.approx((fitted.ks,) * 3) and lobe.r0 == pytest.approx(fitted.r0)
    # Rough dielectric (Blender's default 0.5): no lobe, its albedo joins kd (never past 1); a lower
    # threshold moves the line.
    kd, lobes, _ = map_pbr(GltfPbr(metallic=0, roughness=0.5))
    assert lobes == []
    np.testing.assert_allclose(kd, min(share + table.specular_albedo_at(0.5, 0.04), 1.0), rtol=1e-6)
    kd, _, _ = map_pbr(GltfPbr(base_color=(0.5, 0.5, 0.5), metallic=0, roughness=0.5))
    np.testing.assert_allclose(kd, 0.5 * share + table.specular_albedo_at(0.5, 0.04), rtol=1e-6)
    assert len(map_pbr(GltfPbr(metallic=0, roughness=0.5), diffuse_roughness=0.8)[1]) == len(
        table.specular_lobes(0.5, 0.04)) == 1  # a dielectric layer: one lobe (MULTI_LOBE_F0)
    # Frosted glass, ior 1.33: no diffuse, reflect + transmit lobes; the transmit lobe m = r^2, r0 = f0.
    kd, lobes, _ = map_pbr(GltfPbr(base_color=(1, 1, 1), metallic=0, roughness=0.6,
                                   transmission=1.0, ior=1.33))
    np.testing.assert_allclose(kd, 0)
    r0 = (0.33 / 2.33) ** 2
    reflect = table.specular_lobes(0.6, r0)
    assert [lb.kind for lb in lobes] == ["reflect"] * len(reflect) + ["transmit"]
    assert [lb.r0 for lb in lobes[:-1]] == pytest.approx([lb.r0 for lb in reflect])
    assert lobes[-1].r0 == pytest.approx(r0)
    assert lobes[-1].mx == pytest.approx(0.36) and lobes[-1].ks == (1, 1, 1)
    # Anisotropic brushed metal: mx = m + (1 - m) s^2 along the tangent, my = m (every lobe of the row).
    _, aniso, _ = map_pbr(GltfPbr(metallic=1, roughness=0.3, anisotropy=0.5))
    fitted_lobes = table.specular_lobes(0.3, 1.0)
    assert len(aniso) == len(fitted_lobes)
    for lobe, fitted in zip(aniso, fitted_lobes):
        assert lobe.my == pytest.approx(fitted.m) and lobe.mx == pytest.approx(fitted.m + (1 - fitted.m) * 0.25)
    # Mirror: m at the table's floor; half metal: two lobes weighted by metallic.
    _, lobes, _ = map_pbr(GltfPbr(base_color=(1, 0, 0), metallic=0.5, roughness=0.0))
    # (a red metal: F = 1 for red alone, and (1 - cos)^5 whitening every channel towards grazing)
    assert [lb.r0 for lb in lobes] == [pytest.approx(0.04, rel=0.15), 1.0, 0.0]
    assert lobes[0].ks == pytest.approx((0.5 * table.specular_lobes(0.0, 0.04)[0].ks,) * 3)
    (red,) = table.specular_lobes(0.0, 1.0)
    assert lobes[1].ks == pytest.approx((0.5 * red.ks * red.r0, 0, 0))
    assert lobes[2].ks == pytest.approx((0.5 * red.ks * (1 - red.r0), 0.5 * red.ks, 0.5 * red.ks))
    assert lobes[0].mx == 1e-4


def test_material_extensions_read_from_gltf(tmp_path):
    ext = {"KHR_materials_transmission": {"transmissionFactor": 0.8},
           "KHR_materials_ior": {"ior": 2.0},
           "KHR_materials_anisotropy": {"anisotropyStrength": 1.0, "anisotropyRotation": 0.3},
           "KHR_materials_specular": {"specularFactor": 0.5}}
    w = quad_writer(base_color=(1, 1, 1, 1), roughness=0.1, extensions=ext)
    scene = load_scene(write(w, tmp_path))
    mat = scene.materials[0]
    table = fit_table()  # KHR_materials_specular 0.5: the layer's Fresnel halved, the diffuse share 1 - F / 2
    np.testing.assert_allclose(mat.kd, [0.2 * (1 - 0.5 * (1 - table.diffuse_share(1 / 9)))] * 3, rtol=1e-6)
    refl, trans = mat.lobes
    (fitted,) = table.specular_lobes(0.1, 1 / 9)
    assert refl.ks == pytest.approx((0.5 * fitted.ks,) * 3) and refl.r0 == pytest.approx(fitted.r0)
    assert trans.ks == pytest.approx((0.8, 0.8, 0.8)) and trans.kind == "transmit" and trans.r0 == pytest.approx(1 / 9)
    assert refl.mx == pytest.approx(1.0) and refl.my == pytest.approx(fitted.m)
    assert scene.objects[0].role == "transmissive"
    assert mat.anisotropy_rotation == pytest.approx(0.3)  # read, not warned about
    assert not any("anisotropyRotation" in m for m in scene.warnings)


def test_extras_override_mapping_and_sidecar_overrides_extras(tmp_path):
    extras = {"glint": {"kd": [0.1, 0.2, 0.3],
                        "lobes": [{"kind": "reflect", "ks": [1, 1, 1], "mx": 0.05, "my": 0.2,
                                   "r0": 0.5, "alpha": 0.3}]}}
    w = quad_writer(roughness=1.0, extras=extras)
    scene = load_scene(write(w, tmp_path))
    mat = scene.materials[0]
    np.testing.assert_allclose(mat.kd, [0.1, 0.2, 0.3])
    assert [l.to_dict() for l in mat.lobes] == [{"kind": "reflect", "ks": [1, 1, 1], "mx": 0.05,
                                                 "my": 0.2, "r0": 0.5, "alpha": 0.3}]
    sidecar = '[materials."Mat"]\nkd = 0.5\nemission = [1, 2, 3]\n'
    scene = load_scene(write(w, tmp_path, sidecar=sidecar))
    mat = scene.materials[0]
    np.testing.assert_allclose(mat.kd, [0.5] * 3)  # sidecar wins
    np.testing.assert_allclose(mat.emission, [1, 2, 3])
    assert mat.lobes[0].my == 0.2  # extras still give the lobes the sidecar did not touch


def test_sidecar_diffuse_roughness_threshold(tmp_path):
    w = quad_writer(roughness=0.5, metallic=0.0)
    assert load_scene(write(w, tmp_path)).objects[0].role == "diffuse"
    scene = load_scene(write(w, tmp_path, sidecar="[bake]\ndiffuse_roughness = 0.9\n"))
    assert len(scene.materials[0].lobes) == len(fit_table().specular_lobes(0.5, 0.04)) == 1  # a dielectric layer: one lobe
    assert scene.objects[0].role == "planar"
    assert scene.bake_settings == {"diffuse_roughness": 0.9}


# ----------------------------------------------------------------------------- sidecar


def test_sidecar_sky_cameras_paths_and_bake_settings(tmp_path):
    sidecar = """
[bake]
quality = "draft"
texels_per_metre = 12
[sky]
radiance = [0.6, 0.7, 0.9]
strength = 2.0
[cameras.default]
eye = [0, 1.6, 3]
target = [0, 1.6, 0]
yfov = 60
[camera_paths.tour]
keys = [ { time = 0.0, eye = [0, 1.6, 3], target = [0, 1, 0] },
         { time = 5.0, eye = [2, 1.6, 1], target = [0, 1, 0] } ]
"""
    scene = load_scene(write(quad_writer(), tmp_path, sidecar=sidecar))
    assert scene.sidecar == tmp_path / "scene.glint.toml"
    assert scene.bake_settings == {"quality": "draft", "texels_per_metre": 12}
    np.testing.assert_allclose(scene.sky.radiance, [1.2, 1.4, 1.8], rtol=1e-6)
    (cam,) = scene.cameras
    assert cam.name == "default" and cam.yfov == pytest.approx(math.radians(60))
    np.testing.assert_allclose(cam.forward, [0, 0, -1])
    (tour,) = scene.camera_paths
    assert tour.name == "tour" and [k["time"] for k in tour.keys] == [0.0, 5.0]
    assert tour.keys[1]["eye"] == [2, 1.6, 1]


def test_sidecar_sky_map_read_with_openimageio(tmp_path):
    import OpenImageIO as oiio

    sky = np.zeros((4, 8, 3), np.float32)
    sky[0] = (1, 2, 3)
    out = oiio.ImageOutput.create(str(tmp_path / "sky.exr"))
    out.open(str(tmp_path / "sky.exr"), oiio.ImageSpec(8, 4, 3, oiio.FLOAT))
    out.write_image(sky)
    out.close()
    w = GltfWriter()
    m = w.add_material("Mat")
    w.add_node("Quad", mesh=w.add_mesh("Q", QUAD_P, QUAD_I, m, normals=QUAD_N))
    scene = load_scene(write(w, tmp_path, sidecar='[sky]\nmap = "sky.exr"\nstrength = 0.5\n'))
    assert scene.sky.map.shape == (4, 8, 3) and scene.sky.map.dtype == np.float32
    np.testing.assert_allclose(scene.sky.map[0, 0], [0.5, 1, 1.5])
    np.testing.assert_allclose(scene.sky.map[1:], 0)
    assert scene.has_light  # the sky is the only light


def test_unknown_sidecar_keys_warn_but_load(tmp_path, capsys):
    sidecar = '[bake]\nqualty = "draft"\n[objects."Quad"]\nrole = "curved"\ncolour = 1\n[extra]\n'
    scene = load_scene(write(quad_writer(), tmp_path, sidecar=sidecar))
    err = capsys.readouterr().err
    for key in ("'qualty'", "'colour'", "'extra'"):
        assert key in err
        assert any(key in m for m in scene.warnings)
    assert scene.objects[0].role == "curved"


def test_sidecar_material_name_unknown_warns(tmp_path):
    scene = load_scene(write(quad_writer(), tmp_path, sidecar='[materials."Nope"]\nkd = 0.1\n'))
    assert any("Nope" in m for m in scene.warnings)
