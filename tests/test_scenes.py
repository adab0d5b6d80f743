"""The built-in scenes: cornell-box against Mitsuba 3 itself, living-room's content, the teapot,
and the committed files against a fresh run of scenes/generate.py."""
import json
import math
import struct

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib
from pathlib import Path

import numpy as np
import pytest
import trimesh

from glint.scenes import BUILTIN, builtin_path, teapot
from glint.scenes.generate import generate

SCENES = Path(builtin_path("cornell-box")).parent


def glb_json(path):
    data = Path(path).read_bytes()
    (jlen,) = struct.unpack_from("<I", data, 12)
    return json.loads(data[20:20 + jlen])


def world_meshes(path):
    """{node name: trimesh.Trimesh in world space} for every mesh node."""
    scene = trimesh.load(path, force="scene")
    out = {}
    for node in scene.graph.nodes_geometry:
        transform, geom = scene.graph[node]
        out[node] = scene.geometry[geom].copy().apply_transform(transform)
    return out


def node_world_matrices(doc):
    """{node name: 4x4 world matrix} from the glTF JSON (TRS or matrix, with parents)."""
    def local(n):
        if "matrix" in n:
            return np.array(n["matrix"]).reshape(4, 4).T
        x, y, z, w = n.get("rotation", (0, 0, 0, 1))
        r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        m = np.eye(4)
        m[:3, :3] = r @ np.diag(n.get("scale", (1, 1, 1)))
        m[:3, 3] = n.get("translation", (0, 0, 0))
        return m

    out = {}

    def walk(i, parent):
        m = parent @ local(doc["nodes"][i])
        out[doc["nodes"][i]["name"]] = m
        for c in doc["nodes"][i].get("children", ()):
            walk(c, m)

    for root in doc["scenes"][doc.get("scene", 0)]["nodes"]:
        walk(root, np.eye(4))
    return out


# -- cornell-box == mitsuba.cornell_box() ---------------------------------------------------
@pytest.fixture(scope="module")
def mi():
    import mitsuba
    mitsuba.set_variant("scalar_rgb")
    return mitsuba


@pytest.fixture(scope="module")
def cornell():
    path = builtin_path("cornell-box")
    return path, glb_json(path), world_meshes(path)


SHAPES = ["light", "floor", "ceiling", "back", "green-wall", "red-wall", "small-box", "large-box"]


def test_cornell_geometry_matches_mitsuba(mi, cornell):
    _, _, meshes = cornell
    ref = mi.cornell_box()
    assert sorted(meshes) == sorted(SHAPES)
    for name in SHAPES:
        shape = ref[name]
        ours = meshes[name]
        if shape["type"] == "rectangle":
            # Mitsuba's rectangle is analytic: [-1,1]^2 at z=0, mapped by to_world.
            m = np.array(shape["to_world"].matrix, float)
            corners = np.array([[x, y, 0, 1] for x in (-1, 1) for y in (-1, 1)], float) @ m.T
            expect = corners[:, :3]
        else:
            loaded = mi.load_dict({"type": "cube", "to_world": shape["to_world"]})
            expect = np.array(mi.traverse(loaded)["vertex_positions"]).reshape(-1, 3)
        # Same point sets (order aside), to 1e-5.
        got = np.unique(np.round(ours.vertices, 4), axis=0)
        assert len(got) == len(np.unique(np.round(expect, 4), axis=0)), name
        d = np.linalg.norm(ours.vertices[:, None] - expect[None], axis=2)
        assert d.min(axis=1).max() < 1e-5, name
        assert d.min(axis=0).max() < 1e-5, name
        np.testing.assert_allclose(ours.area, {"rectangle": 4.0, "cube": 24.0}[shape["type"]]
                                   * _area_scale(shape), rtol=1e-5)


def _area_scale(shape):
    """Area factor of to_world on the shape's faces (rectangles: |sx*sy|; cubes: mean face)."""
    m = np.array(shape["to_world"].matrix, float)[:3, :3]
    sx, sy, sz = np.linalg.norm(m, axis=0)
    if shape["type"] == "rectangle":
        return sx * sy
    return (sx * sy + sy * sz + sx * sz) / 3


def test_cornell_front_faces_match_mitsuba_normals(mi, cornell):
    """Our CCW winding faces where Mitsuba's (one-sided) shapes face: hit each of our
    triangles from its front and compare with Mitsuba's geometric normal there."""
    _, _, meshes = cornell
    scene = mi.load_dict(mi.cornell_box())
    checked = 0
    for name, mesh in meshes.items():
        for centre, normal in zip(mesh.triangles_center, mesh.face_normals):
            if centre[1] < -0.999 and normal[1] < -0.9:
                continue  # box bottoms lie on the floor: the hit is ambiguous
            origin = centre + 1e-3 * normal
            si = scene.ray_intersect(mi.Ray3f(mi.Point3f(*origin), mi.Vector3f(*(-normal))))
            assert si.is_valid(), name
            # (Mitsuba merges shapes that share a BSDF, so compare where, not which.)
            assert si.t == pytest.approx(1e-3, abs=1e-5), name
            np.testing.assert_allclose(np.array(si.n), normal, atol=1e-5, err_msg=name)
            checked += 1
    assert checked >= 30


def test_cornell_materials_and_emitter_match_mitsuba(mi, cornell):
    _, doc, _ = cornell
    ref = mi.cornell_box()
    mats = {m["name"]: m for m in doc["materials"]}
    mesh_material = {m["name"]: doc["materials"][m["primitives"][0]["material"]]["name"]
                     for m in doc["meshes"]}
    for name in SHAPES:
        bsdf = ref[name]["bsdf"]["id"]
        mat = mats[mesh_material[name]]
        pbr = mat["pbrMetallicRoughness"]
        np.testing.assert_allclose(pbr["baseColorFactor"][:3], ref[bsdf]["reflectance"]["value"],
                                   atol=1e-5, err_msg=name)
        assert pbr["metallicFactor"] == 0.0 and pbr["roughnessFactor"] == 1.0
        assert not mat.get("doubleSided", False)  # Mitsuba's shapes are one-sided
        radiance = np.array(mat.get("emissiveFactor", (0, 0, 0))) * mat.get(
            "extensions", {}).get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
        expect = ref[name].get("emitter", {}).get("radiance", {}).get("value", (0, 0, 0))
        np.testing.assert_allclose(radiance, expect, atol=1e-5, err_msg=name)
    assert "KHR_materials_emissive_strength" in doc["extensionsUsed"]


def test_cornell_camera_matches_mitsuba(mi, cornell):
    _, doc, _ = cornell
    sensor = mi.cornell_box()["sensor"]
    (cam,) = doc["cameras"]
    assert sensor["fov_axis"] == "smaller" and cam["perspective"]["aspectRatio"] == 1.0
    assert cam["perspective"]["yfov"] == pytest.approx(math.radians(sensor["fov"]), abs=1e-7)
    assert cam["perspective"]["znear"] == pytest.approx(sensor["near_clip"])
    (node,) = [n for n in doc["nodes"] if "camera" in n]
    ours = node_world_matrices(doc)[node["name"]]
    # Mitsuba's camera looks down its +z with +x to the left; glTF's down -z with +x right.
    theirs = np.array(sensor["to_world"].matrix, float) @ np.diag([-1, 1, -1, 1])
    np.testing.assert_allclose(ours, theirs, atol=1e-5)


# -- teapot ----------------------------------------------------------------------------------
def test_teapot_data_is_newells():
    assert teapot.PATCHES.shape == (32, 16)
    assert teapot.VERTICES.shape == (306, 3)
    # Every control point is used except four 0.002 offsets around the lid knob's
    # axis, which this index table replaces by the axis point itself (203).
    unused = set(range(306)) - set(np.unique(teapot.PATCHES).tolist())
    assert unused == {204, 205, 215, 222}
    np.testing.assert_allclose(np.abs(teapot.VERTICES[sorted(unused)]).sum(axis=1), 3.152)
    assert {k: len(v) for k, v in teapot.PATCH_GROUPS.items()} == {
        "rim": 4, "body": 8, "handle": 4, "spout": 4, "lid": 8, "bottom": 4}
    # Corner control points interpolate the surface: base centre, lid knob top.
    assert tuple(teapot.VERTICES[269]) == (0, 0, 0) and tuple(teapot.VERTICES[203]) == (0, 0, 3.15)


def test_teapot_tessellation_is_closed_ish_outward_and_bounded():
    pos, nrm, idx, patch = teapot.tessellate(segments=8)
    assert len(idx) == 32 * 8 * 8 * 2 - len(set(range(20, 24)) | set(range(28, 32))) * 8
    assert set(np.unique(patch)) == set(range(32))
    mesh = trimesh.Trimesh(pos, idx, process=False)
    np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1, atol=1e-6)
    # Bounds (y up): base on 0, knob top 3.15, handle back at x=-3 (corner point 135),
    # body radius 2 (corner points 56, 59, ...), spout tip between its control rows.
    lo, hi = mesh.bounds
    assert lo[1] == pytest.approx(0, abs=1e-9) and hi[1] == pytest.approx(3.15, abs=1e-9)
    assert lo[0] == pytest.approx(-3.0, abs=1e-9)
    assert 3.3 < hi[0] < 3.525
    assert lo[2] == pytest.approx(-2.0, abs=1e-9) and hi[2] == pytest.approx(2.0, abs=1e-9)
    # Closed-ish: no edge shared by more than 2 triangles, and open edges only where
    # Newell's data is open (the rim/lid gap and spout tip at height 2.4) or where the
    # handle and spout end on the body.
    edges, counts = np.unique(np.sort(mesh.edges, axis=1), axis=0, return_counts=True)
    assert counts.max() == 2
    open_vertices = np.unique(edges[counts == 1])
    handle_spout = np.unique(idx[(patch >= 12) & (patch < 20)])
    at_rim = np.abs(pos[:, 1] - 2.4) < 1e-9
    assert np.all(at_rim[open_vertices] | np.isin(open_vertices, handle_spout))
    assert (counts == 1).sum() < 0.05 * len(edges)
    # Outward: rays from far away hit front faces.
    rng = np.random.default_rng(0)
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    origins = np.array([0, 1.5, 0]) + 10 * d
    _, rays, tris = mesh.ray.intersects_location(origins, -d, multiple_hits=False)
    assert len(rays) == 500
    assert np.mean((mesh.face_normals[tris] * -d[rays]).sum(axis=1) < 0) > 0.99
    # Vertex normals agree with the winding.
    assert np.all((mesh.face_normals * nrm[idx].sum(axis=1)).sum(axis=1) > 0)
    assert mesh.volume > 0


# -- living-room -----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def room():
    path = builtin_path("living-room")
    return path, glb_json(path), world_meshes(path)


REQUIRED_OBJECTS = ["Floor", "Ceiling", "Wall north", "Wall south", "Wall east", "Wall west",
                    "Ceiling light 1", "Ceiling light 2", "Ceiling light 3", "Sofa base",
                    "Sofa back", "Table top", "Teapot", "Vase", "Chrome sphere", "Side table",
                    "Glass screen", "Rug", "Bookshelf", "Painting east", "Door"]


def material_of(doc, node_name):
    (node,) = [n for n in doc["nodes"] if n["name"] == node_name]
    return doc["materials"][doc["meshes"][node["mesh"]]["primitives"][0]["material"]]


def test_living_room_objects_and_size(room):
    path, doc, meshes = room
    assert len(meshes) >= 20
    assert set(REQUIRED_OBJECTS) <= set(meshes)
    assert sum(len(m.faces) for m in meshes.values()) < 40_000
    assert path.stat().st_size < 1.5e6
    lo = np.min([m.bounds[0] for m in meshes.values()], axis=0)
    hi = np.max([m.bounds[1] for m in meshes.values()], axis=0)
    # 5 m x 2.7 m x 4 m, plus the window reveal beyond the north wall.
    np.testing.assert_allclose(lo, [-2.5, 0, -2.2], atol=1e-6)
    np.testing.assert_allclose(hi, [2.5, 2.7, 2.0], atol=1e-6)
    # Not everything baked into vertices: furniture is placed by node transforms.
    moved = [n for n in doc["nodes"] if "mesh" in n and ("rotation" in n or "scale" in n)]
    assert len(moved) >= 5
    assert any(n.get("children") for n in doc["nodes"])


def test_living_room_materials(room):
    _, doc, meshes = room
    pbr = lambda name: material_of(doc, name)["pbrMetallicRoughness"]  # noqa: E731
    # Diffuse shell and sofa (roughness >= 0.5), glossy floor and table top.
    for name in ("Wall north", "Wall east", "Ceiling", "Sofa base", "Sofa back"):
        assert pbr(name)["roughnessFactor"] >= 0.5 and pbr(name)["metallicFactor"] == 0
    for name in ("Floor", "Table top"):
        assert pbr(name)["roughnessFactor"] < 0.5 and pbr(name)["metallicFactor"] == 0
    for name in ("Teapot", "Vase", "Chrome sphere", "Side table"):
        assert pbr(name)["metallicFactor"] == 1 and pbr(name)["roughnessFactor"] < 0.5
    # Textured floor and rug, with TEXCOORD_0.
    for name in ("Floor", "Rug"):
        assert "baseColorTexture" in pbr(name)
        (node,) = [n for n in doc["nodes"] if n["name"] == name]
        assert "TEXCOORD_0" in doc["meshes"][node["mesh"]]["primitives"][0]["attributes"]
    # Anisotropic brushed metal: the glTF extension and full lobes with mx != my.
    steel = material_of(doc, "Side table")
    assert steel["extensions"]["KHR_materials_anisotropy"]["anisotropyStrength"] == 0.8
    lobes = steel["extras"]["glint"]["lobes"]
    assert all(lobe["kind"] == "reflect" and lobe["mx"] != lobe["my"] for lobe in lobes)
    # Frosted glass: thin, transmissive, rough.
    glass = material_of(doc, "Glass screen")
    assert glass["extensions"]["KHR_materials_transmission"]["transmissionFactor"] == 0.9
    assert glass["pbrMetallicRoughness"]["roughnessFactor"] == 0.3 and glass["doubleSided"]
    assert np.ptp(meshes["Glass screen"].vertices @ meshes["Glass screen"].face_normals[0]) < 1e-6
    # Ceiling lights: emissive, facing down, at the ceiling.
    for k in (1, 2, 3):
        mat = material_of(doc, f"Ceiling light {k}")
        strength = mat["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"]
        assert 5 < strength * max(mat["emissiveFactor"]) < 100  # W/(m^2 sr)
        light = meshes[f"Ceiling light {k}"]
        assert np.allclose(light.face_normals, [0, -1, 0], atol=1e-6)
        assert light.vertices[:, 1].min() > 2.6
    assert {"KHR_materials_anisotropy", "KHR_materials_transmission",
            "KHR_materials_emissive_strength", "KHR_lights_punctual"} <= set(doc["extensionsUsed"])


def test_living_room_shell_faces_inwards_and_is_closed_except_the_window(room):
    _, _, meshes = room
    inward = {"Floor": [0, 1, 0], "Ceiling": [0, -1, 0], "Wall south": [0, 0, -1],
              "Wall east": [-1, 0, 0], "Wall west": [1, 0, 0]}
    for name, n in inward.items():
        np.testing.assert_allclose(meshes[name].face_normals, np.tile(n, (2, 1)), atol=1e-6)
    north = meshes["Wall north"]
    on_wall = np.abs(north.triangles_center[:, 2] + 2.0) < 1e-6
    np.testing.assert_allclose(north.face_normals[on_wall], np.tile([0, 0, 1], (on_wall.sum(), 1)),
                               atol=1e-6)
    # The hole is real: the window's centre is not covered by the wall.
    shell = trimesh.util.concatenate([meshes[n] for n in list(inward) + ["Wall north"]])
    window = shell.ray.intersects_any([[0.3, 1.55, 0.0]], [[0.0, 0.0, -1.0]])
    assert not window[0]
    # Rays from inside in all directions hit the shell, except those that leave through
    # the window opening (x in [-0.5, 1.1], y in [0.9, 2.2] at z = -2).
    rng = np.random.default_rng(1)
    d = rng.normal(size=(4000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    origins = rng.uniform([-2.4, 0.1, -1.9], [2.4, 2.6, 1.9], size=(4000, 3))
    hit = shell.ray.intersects_any(origins, d)
    t = (-2.0 - origins[:, 2]) / np.where(d[:, 2] < 0, d[:, 2], -1e-30)
    exit_point = origins + t[:, None] * d
    through_window = ((d[:, 2] < 0) & (exit_point[:, 0] > -0.5) & (exit_point[:, 0] < 1.1)
                      & (exit_point[:, 1] > 0.9) & (exit_point[:, 1] < 2.2))
    assert np.all(hit | through_window)
    assert through_window.sum() > 20
    # Every shell face a ray from inside reaches first is a front face (the window reveals too).
    locations, index_ray, index_tri = shell.ray.intersects_location(origins, d, multiple_hits=False)
    facing = np.einsum("ij,ij->i", shell.face_normals[index_tri], d[index_ray])
    assert np.all(facing < 0), f"{(facing >= 0).sum()} rays from inside hit a back face"
    reveal = np.abs(locations[:, 2] + 2.0) > 1e-3
    reveal &= locations[:, 2] < -2.0
    assert reveal.sum() > 0  # the reveals were reached, so they were checked


def test_living_room_cameras_and_lights(room):
    _, doc, _ = room
    world = node_world_matrices(doc)
    cams = {doc["cameras"][n["camera"]]["name"]: n["name"] for n in doc["nodes"] if "camera" in n}
    assert set(cams) == {"entrance", "sofa"}
    targets = {"entrance": (-1.0, 1.0, -0.8), "sofa": (1.0, 1.0, -0.6)}
    for cam, node in cams.items():
        m = world[node]
        forward = -m[:3, 2]
        to_target = np.array(targets[cam]) - m[:3, 3]
        assert forward @ to_target / np.linalg.norm(to_target) == pytest.approx(1, abs=1e-6)
        assert m[1, 1] > 0.8  # upright
        assert np.all(np.abs(m[:3, 3]) < [2.5, 2.7, 2.0]) and m[1, 3] > 0
    (light,) = doc["extensions"]["KHR_lights_punctual"]["lights"]
    assert light["type"] == "spot" and 100 <= light["intensity"] <= 5000  # candela
    spot_node = [n["name"] for n in doc["nodes"] if "extensions" in n][0]
    aim = -world[spot_node][:3, 2]
    assert aim[0] > 0.5 and aim[1] < 0  # down towards the east wall's painting


def test_living_room_sidecar():
    sidecar = SCENES / "living-room.glint.toml"
    cfg = tomllib.loads(sidecar.read_text())
    assert cfg["bake"]["quality"] in ("draft", "preview", "final")
    assert len(cfg["sky"]["radiance"]) == 3 and min(cfg["sky"]["radiance"]) > 0
    assert cfg["lights"]["units"] in ("photometric", "radiometric")
    keys = cfg["camera_paths"]["tour"]["keys"]
    assert len(keys) >= 2 and [k["time"] for k in keys] == sorted(k["time"] for k in keys)
    doc = glb_json(builtin_path("living-room"))
    names = {m["name"] for m in doc["materials"]}
    nodes = {n["name"] for n in doc["nodes"]}
    assert set(cfg["materials"]) <= names and set(cfg["objects"]) <= nodes
    for mat in cfg["materials"].values():
        for lobe in mat.get("lobes", []):
            assert set(lobe) == {"kind", "ks", "mx", "my", "r0", "alpha"}


# -- the committed files are the generator's output -----------------------------------------
def test_committed_scenes_are_reproduced_by_the_generator(tmp_path):
    written = generate(tmp_path)
    assert {p.name for p in written} >= {BUILTIN[name][0] for name in BUILTIN}
    for path in written:
        committed = SCENES / path.name
        assert committed.exists(), f"{path.name} not committed: run python3 -m glint.scenes.generate"
        assert committed.read_bytes() == path.read_bytes(), (
            f"scenes/{path.name} is out of date: run python3 -m glint.scenes.generate")


# -- material-classes ------------------------------------------------------------------------
def built_in_with_sidecar(name: str):
    """(glTF JSON, world meshes by node, sidecar TOML) of a built-in scene."""
    path = builtin_path(name)
    return glb_json(path), world_meshes(path), tomllib.loads((SCENES / f"{name}.glint.toml").read_text())


def test_material_classes_has_one_sphere_per_class_and_a_camera_on_all_four():
    doc, meshes, cfg = built_in_with_sidecar("material-classes")
    spheres = {"Ceramic sphere": "Glazed ceramic", "Chrome sphere": "Chrome",
               "Brushed sphere": "Brushed aluminium", "Frosted sphere": "Frosted glass"}
    for node, material in spheres.items():
        assert material_of(doc, node)["name"] == material
        lo, hi = meshes[node].bounds
        np.testing.assert_allclose(hi - lo, 0.44, atol=1e-3)  # curved: a sphere, 22 cm radius
    lobes = {name: cfg["materials"][name]["lobes"] for name in spheres.values()}
    (ceramic,) = lobes["Glazed ceramic"]  # sharp insulator
    assert ceramic["mx"] == ceramic["my"] <= 0.05 and ceramic["r0"] == 0.04
    (chrome,) = lobes["Chrome"]  # chrome-like glossy metal
    assert chrome["mx"] == chrome["my"] <= 0.05 and chrome["r0"] >= 0.9 and min(chrome["ks"]) >= 0.9
    assert all(lobe["my"] >= 5 * lobe["mx"] for lobe in lobes["Brushed aluminium"])  # anisotropic
    assert [lobe["kind"] for lobe in lobes["Frosted glass"]] == ["transmit", "reflect"]
    # The one camera sees every sphere's centre inside its frustum (16:9), with a margin.
    assert_centres_in_view(doc, meshes, spheres, margin=0.9)


def assert_centres_in_view(doc, meshes, nodes, margin=1.0):
    """The file's one camera sees the bounding-box centre of every node in `nodes` inside `margin`
    times its 16:9 frustum."""
    world = node_world_matrices(doc)
    (cam_node,) = [n for n in doc["nodes"] if "camera" in n]
    m = world[cam_node["name"]]
    yfov = doc["cameras"][cam_node["camera"]]["perspective"]["yfov"]
    for node in nodes:
        local = np.linalg.inv(m) @ np.r_[meshes[node].bounds.mean(axis=0), 1.0]
        assert local[2] < 0, node
        assert abs(local[1] / -local[2]) < math.tan(yfov / 2) * margin, node
        assert abs(local[0] / -local[2]) < math.tan(yfov / 2) * 16 / 9 * margin, node


# -- planar-classes --------------------------------------------------------------------------
def test_planar_classes_has_four_planar_reflectors_in_four_planes_and_a_camera_on_all():
    doc, meshes, cfg = built_in_with_sidecar("planar-classes")
    reflectors = {"Stone floor": "Polished stone", "Wood platform top": "Varnished wood",
                  "Tile panel": "Glossy tiles", "Aluminium panel": "Blurry aluminium"}
    assert {name: o["role"] for name, o in cfg["objects"].items()} == dict.fromkeys(reflectors, "planar")
    planes = set()
    for node, material in reflectors.items():
        assert material_of(doc, node)["name"] == material
        mesh = meshes[node]
        normal = mesh.face_normals[0]
        assert np.allclose(mesh.face_normals, normal, atol=1e-6)  # flat: one plane per reflector
        assert np.ptp(mesh.vertices @ normal) < 1e-5
        planes.add((*np.round(normal, 3), round(float(mesh.vertices[0] @ normal), 3)))
    assert len(planes) == 4  # each its own mirror pass (the default budget is 4)
    lobes = {m: cfg["materials"][m]["lobes"] for m in reflectors.values()}
    assert all(len(v) == 1 and v[0]["mx"] == v[0]["my"] for v in lobes.values())  # isotropic: multi-ring
    assert [lobes[m][0]["mx"] for m in reflectors.values()] == [0.02, 0.05, 0.1, 0.2]
    assert lobes["Blurry aluminium"][0]["r0"] >= 0.9 and lobes["Polished stone"][0]["r0"] == 0.05
    assert_centres_in_view(doc, meshes, reflectors)
