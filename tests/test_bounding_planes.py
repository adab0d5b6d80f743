"""bake/bounding_planes.py: automatic bounding planes per cube-mapped object, and the sidecar's
`bounding_planes` override. Scenes are built from axis-aligned quads and boxes, so every
expected plane, side and distance is known by construction."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh
from conftest import quad

from glint.bake.bounding_planes import MAX_PLANES, candidate_surfaces, choose_planes
from glint.bake.cubemap import plan_cubemaps
from glint.bake.gltf_loader import load_scene
from glint.bake.roles import assign_roles
from glint.core.errors import GlintError
from glint.core.scene import Lobe, Material, Object, Scene
from glint.scenes.gltf_writer import GltfWriter

MATTE, GLOSSY = 0, 1
MATERIALS = [Material("Matte"), Material("Glossy", lobes=[Lobe("reflect", mx=0.05, my=0.05)]),
             Material("Two-sided matte", double_sided=True)]
TWO_SIDED = 2


def quad_object(name, centre, u, v, material=MATTE):
    p, i = quad(centre, u, v)
    n = np.cross(u, v) / np.linalg.norm(np.cross(u, v))
    return Object(name, p, np.tile(n, (4, 1)).astype(np.float32), i, material)


def box_object(name, centre, extents, material=GLOSSY):
    b = trimesh.creation.box(extents=extents)
    return Object(name, b.vertices + np.asarray(centre, float), b.vertex_normals.astype(np.float32),
                  np.asarray(b.faces, np.int64), material)


def room(width=4.0, depth=4.0, height=3.0):
    """Floor (y = 0), ceiling (y = height) and four walls of a box room centred on x = z = 0,
    all facing in."""
    w, d, h = width / 2, depth / 2, height / 2
    return [quad_object("Floor", (0, 0, 0), (w, 0, 0), (0, 0, -d)),
            quad_object("Ceiling", (0, height, 0), (w, 0, 0), (0, 0, d)),
            quad_object("North", (0, h, -d), (w, 0, 0), (0, h, 0)),
            quad_object("South", (0, h, d), (-w, 0, 0), (0, h, 0)),
            quad_object("West", (-w, h, 0), (0, 0, -d), (0, h, 0)),
            quad_object("East", (w, h, 0), (0, 0, d), (0, h, 0))]


def scene_of(objects):
    scene = Scene("test", None, objects=list(objects), materials=list(MATERIALS))
    assign_roles(scene)
    return scene


def planes_of(scene, name):
    obj = next(o for o in scene.objects if o.name == name)
    return choose_planes(obj, candidate_surfaces(scene))


def test_box_room_gives_its_six_faces_nearest_first_facing_the_object():
    centre = np.array([0.5, 1.0, -1.2])
    scene = scene_of(room() + [box_object("Ball", centre, (0.2, 0.2, 0.2))])
    assert scene.objects[-1].role == "curved"
    planes = planes_of(scene, "Ball")
    # (plane, normal towards the room, distance from the centre)
    expected = {"North": ((0, 0, 1), 0.8), "Floor": ((0, 1, 0), 1.0), "East": ((-1, 0, 0), 1.5),
                "Ceiling": ((0, -1, 0), 2.0), "West": ((1, 0, 0), 2.5), "South": ((0, 0, -1), 3.2)}
    assert [p.source for p in planes] == list(expected)
    for p in planes:
        normal, distance = expected[p.source]
        np.testing.assert_allclose(p.normal, normal, atol=1e-9)
        assert np.dot(centre - p.point, p.normal) == pytest.approx(distance)
    assert planes[0].to_dict()["object"] == "North"


def test_table_top_replaces_the_floor_under_it_only():
    """A planar table top is the lower plane of the vase standing on it (the floor lies behind
    it for every downward ray); the vase beside the table keeps the floor."""
    table = quad_object("Table top", (0, 0.7, 0), (0.5, 0, 0), (0, 0, -0.3), GLOSSY)
    on = box_object("On table", (0.2, 0.8, 0.0), (0.1, 0.2, 0.1))
    beside = box_object("Beside", (1.5, 1.0, 0.0), (0.2, 0.4, 0.2))  # higher than the table, beside it
    scene = scene_of(room() + [table, on, beside])
    assert table.role == "planar"
    names = [p.source for p in planes_of(scene, "On table")]
    assert names[0] == "Table top" and "Floor" not in names and "Ceiling" in names
    names = [p.source for p in planes_of(scene, "Beside")]
    assert "Floor" in names and "Table top" not in names


def test_small_or_bulky_diffuse_objects_are_not_planes_a_wall_with_a_reveal_is():
    objects = room()
    objects[2] = Object("North", *_wall_with_reveal(), MATTE)  # replace the plain north wall
    objects += [quad_object("Poster", (0.5, 1.0, -1.5), (0.4, 0, 0), (0, 0.4, 0)),  # 0.64 m^2
                box_object("Sofa", (-0.5, 0.5, 0.0), (2.0, 1.0, 1.0), MATTE)]  # largest face 2 of 10 m^2
    scene = scene_of(objects + [box_object("Ball", (1.0, 1.0, -1.2), (0.2, 0.2, 0.2))])
    assert {s.name for s in candidate_surfaces(scene)} == {"Floor", "Ceiling", "North", "South", "West", "East"}
    north = next(p for p in planes_of(scene, "Ball") if p.source == "North")
    np.testing.assert_allclose(north.normal, (0, 0, 1), atol=1e-9)
    assert north.point[2] == pytest.approx(-2.0)


def _wall_with_reveal():
    """The 4 x 3 m north wall (z = -2, facing +z) with a 1 x 1 m window whose 0.2 m reveals
    run back to z = -2.2: 11 m^2 of wall, 0.8 m^2 of reveal."""
    xs, ys = [-2.0, -0.5, 0.5, 2.0], [0.0, 1.0, 2.0, 3.0]
    p, tris = [], []
    for a in range(3):
        for b in range(3):
            if a == 1 and b == 1:
                continue  # the opening
            k = len(p)
            p += [(xs[a], ys[b], -2), (xs[a + 1], ys[b], -2), (xs[a + 1], ys[b + 1], -2), (xs[a], ys[b + 1], -2)]
            tris += [(k, k + 1, k + 2), (k, k + 2, k + 3)]
    # reveals: the four sides of the opening, facing into it
    for c, u, v in (((0, 1.0, -2.1), (0.5, 0, 0), (0, 0, 0.1)), ((0, 2.0, -2.1), (-0.5, 0, 0), (0, 0, 0.1)),
                    ((-0.5, 1.5, -2.1), (0, 0, 0.1), (0, 0.5, 0)), ((0.5, 1.5, -2.1), (0, 0, -0.1), (0, 0.5, 0))):
        q, i = quad(c, u, v)
        tris += [tuple(t) for t in i + len(p)]
        p += [tuple(x) for x in q]
    p = np.array(p, float)
    normals = np.zeros_like(p, np.float32)
    return p, normals, np.array(tris, np.int64)


def test_walls_facing_away_are_not_planes_unless_two_sided():
    """A ball outside the room, behind the east wall: the wall faces away from it. Made
    double-sided, the same wall serves (its normal turned towards the ball)."""
    objects = room() + [box_object("Ball", (3.0, 1.0, 0.0), (0.2, 0.2, 0.2))]
    scene = scene_of(objects)
    assert "East" not in [p.source for p in planes_of(scene, "Ball")]
    objects[5].material = TWO_SIDED
    east = next(p for p in planes_of(scene_of(objects), "Ball") if p.source == "East")
    np.testing.assert_allclose(east.normal, (1, 0, 0), atol=1e-9)


def test_many_walls_keep_floor_and_ceiling_and_at_most_max_planes():
    """An octagonal room 1.6 m across, 20 m high: eight walls are nearer than floor and ceiling,
    yet those two stay, with the four nearest walls."""
    r, h = 0.8, 20.0
    objects = [quad_object("Floor", (0, 0, 0), (5, 0, 0), (0, 0, -5)),
               quad_object("Ceiling", (0, h, 0), (5, 0, 0), (0, 0, 5))]
    for k in range(8):
        a = 2 * np.pi * k / 8
        inward = -np.array([np.cos(a), 0, np.sin(a)])
        along = np.cross((0, 1, 0), inward)  # cross(along, up) = inward: faces in
        objects.append(quad_object(f"Wall {k}", -inward * r + (0, h / 2, 0), along * 0.35, (0, h / 2, 0)))
    centre = np.array([0.1, 3.0, 0.05])
    scene = scene_of(objects + [box_object("Ball", centre, (0.1, 0.1, 0.1))])
    planes = planes_of(scene, "Ball")
    assert len(planes) == MAX_PLANES == 6
    names = [p.source for p in planes]
    assert "Floor" in names and "Ceiling" in names
    # wall k: the plane x cos a + z sin a = r, so the centre is r - (x cos a + z sin a) from it
    walls = sorted((r - centre[0] * np.cos(2 * np.pi * k / 8) - centre[2] * np.sin(2 * np.pi * k / 8), f"Wall {k}")
                   for k in range(8))
    assert set(names) - {"Floor", "Ceiling"} == {name for _, name in walls[:4]}
    distances = [float(np.dot(centre - p.point, p.normal)) for p in planes]
    assert distances == sorted(distances)


# -- the sidecar -------------------------------------------------------------------------------------
def write_scene(path, sidecar):
    w = GltfWriter()
    matte = w.add_material("Matte", roughness=1.0)
    glossy = w.add_material("Glossy", extras={"glint": {"lobes": [{"kind": "reflect", "mx": 0.05, "my": 0.05}]}})
    for obj in room():
        w.add_node(obj.name, mesh=w.add_mesh(obj.name, obj.positions, obj.indices, matte))
    for name, x in (("Ball", 0.5), ("Cup", -0.5)):
        b = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
        w.add_node(name, mesh=w.add_mesh(f"{name} mesh", b.vertices, b.faces, glossy), translation=(x, 1.0, 0))
    w.write(path)
    path.with_name(path.stem + ".glint.toml").write_text("[sky]\nradiance = 1.0\n" + sidecar)
    return path


def test_sidecar_switches_planes_off_or_gives_them(tmp_path):
    sidecar = ('[objects."Ball"]\nbounding_planes = false\n'
               '[objects."Cup mesh"]\n'  # by mesh name, as roles are
               'bounding_planes = [ { point = [0, 0.5, 0], normal = [0, 2, 0] },'
               ' { point = [0, 2, 0], normal = [0, -1, 0], colour = 1 } ]\n')
    scene = load_scene(write_scene(tmp_path / "s.glb", sidecar))
    assert any("'colour'" in w for w in scene.warnings)
    plans = {p.name: p for p in plan_cubemaps(scene, "transport")}
    assert set(plans) == {"Ball", "Cup"}
    assert plans["Ball"].manifest_entry()["bounding_planes"] == []
    assert plans["Cup"].manifest_entry()["bounding_planes"] == [
        {"point": [0.0, 0.5, 0.0], "normal": [0.0, 1.0, 0.0], "object": None},
        {"point": [0.0, 2.0, 0.0], "normal": [0.0, -1.0, 0.0], "object": None}]
    # without the sidecar both get the room's six planes
    scene = load_scene(write_scene(tmp_path / "t.glb", '[objects."Ball"]\nbounding_planes = true\n'))
    for plan in plan_cubemaps(scene, "transport"):
        assert {p.source for p in plan.planes} == {"Floor", "Ceiling", "North", "South", "West", "East"}


@pytest.mark.parametrize("value, words", [
    ("1", "true, false or a list"),
    ("[ { point = [0, 0, 0], normal = [0, 0, 0] } ]", "normal must not be zero"),
    ("[ { point = [0, 0, 0] } ]", "missing 'normal'"),
    ("[ { point = [0, 0], normal = [0, 1, 0] } ]", "list of 3 numbers"),
    ("[" + ", ".join(["{ point = [0, 0, 0], normal = [0, 1, 0] }"] * 7) + "]", "at most 6"),
])
def test_bad_bounding_planes_are_clear_errors(tmp_path, value, words):
    with pytest.raises(GlintError, match=words):
        load_scene(write_scene(tmp_path / "s.glb", f'[objects."Ball"]\nbounding_planes = {value}\n'))


def test_options_for_an_unknown_object_warn(tmp_path):
    scene = load_scene(write_scene(tmp_path / "s.glb", '[objects."Nope"]\ncubemap_size = 64\n'))
    assert sum("Nope" in w for w in scene.warnings) == 1
