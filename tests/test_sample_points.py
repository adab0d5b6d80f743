"""Light-map samples moved out of geometry that covers them (bake/sample_points.py, issue 25), and
invalid texels filled from their own object (bake/dilate.py `labels`).

Small scenes written as glTF (scenes/gltf_writer.py) and loaded as any export: a ceiling that a
moulding-like box intersects, a floor running under a thick wall, a room corner whose wall faces
outwards (as some exports have it). Expected positions are worked out by hand from the geometry.
"""
from __future__ import annotations

import numpy as np
import pytest

from glint.bake.alpha import Coverage
from glint.bake.dilate import dilate
from glint.bake.gltf_loader import load_scene
from glint.bake.raytrace import RayTracer
from glint.bake.sample_points import adjust_samples
from glint.scenes.generate import Mesh, add_mesh, box, quad
from glint.scenes.gltf_writer import GltfWriter

S = 1.0 / 16  # texel size (preview's 16 texels per metre); footprint radius r = S / sqrt 2 = 4.4 cm
DOWN, UP = np.array([0.0, -1.0, 0.0]), np.array([0.0, 1.0, 0.0])


def _scene(tmp_path, meshes: dict, double_sided: bool):
    w = GltfWriter()
    m = w.add_material("Paint", base_color=(0.8, 0.8, 0.8), double_sided=double_sided)
    for name, mesh in meshes.items():
        w.add_node(name, mesh=add_mesh(w, name, mesh, m))
    path = w.write(tmp_path / "s.glb")
    (tmp_path / "s.glint.toml").write_text("[sky]\n")
    scene = load_scene(path)
    return scene, RayTracer(scene), [o.name for o in scene.objects]


def _ceiling():
    return quad((-1, 2, -1), (1, 2, -1), (1, 2, 1), (-1, 2, 1))  # faces down


def _adjust(tracer, names, obj, points, normal):
    points = np.asarray(points, float)
    return adjust_samples(tracer, points, np.tile(normal, (len(points), 1)), np.full(len(points), S),
                          np.full(len(points), names.index(obj)))


@pytest.mark.parametrize("double_sided", [True, False])
def test_sample_inside_an_intersecting_box_moves_out_on_its_own_surface(tmp_path, double_sided):
    """A box 8 cm wide (x in [-0.04, 0.04]) through the ceiling plane, 1 cm above it: a ceiling sample
    at x = 0.01 lies inside it. The probe towards +x meets the box's inside at t = 3 cm < r, the
    ceiling goes on past it: the sample moves to the middle of the free part, x = 0.01 + (0.03 + r) / 2
    = 0.047, on the ceiling. A sample at x = 0.1 (free) and one at x = 0.3 stay where they are.

    Bug this catches (tried): probes that find no back faces (what the old rule sees of an all
    double-sided scene) leave the sample inside: moved [False, False, False]; it fails the next two
    tests too."""
    scene, tracer, names = _scene(tmp_path, {"Ceiling": _ceiling(), "Box": box((0.08, 0.1, 2.0), (0, 1.96, 0))},
                                  double_sided)
    a = _adjust(tracer, names, "Ceiling", [[0.01, 2.0, 0.3], [0.1, 2.0, 0.3], [0.3, 2.0, 0.3]], DOWN)
    assert a.moved.tolist() == [True, False, False]
    assert not a.invalid.any()
    r = S / np.sqrt(2)
    np.testing.assert_allclose(a.points[0], [0.01 + (0.03 + r) / 2, 2.0, 0.3], atol=1e-6)
    np.testing.assert_array_equal(a.points[1:], [[0.1, 2.0, 0.3], [0.3, 2.0, 0.3]])


def test_sample_whose_free_side_is_inside_another_object_is_invalid(tmp_path):
    """Two boxes side by side through the ceiling, 1 mm apart (x in [-0.05, 0.03] and [0.031, 0.2]): a
    ceiling sample at x = 0.01 in the first can only move into the second: invalid, not moved."""
    scene, tracer, names = _scene(tmp_path, {"Ceiling": _ceiling(), "A": box((0.08, 0.1, 2.0), (-0.01, 1.96, 0)),
                                             "B": box((0.169, 0.1, 2.0), (0.1155, 1.96, 0))}, True)
    a = _adjust(tracer, names, "Ceiling", [[0.01, 2.0, 0.0]], DOWN)
    assert a.invalid.tolist() == [True] and a.moved.tolist() == [False]


def test_room_corner_whose_wall_faces_outwards_is_left_alone(tmp_path):
    """A floor meeting a double-sided wall at x = 1 that faces outwards (+x): from the floor the wall is
    seen from behind, but the floor ends there, so a floor sample 2 cm from the wall is not covered.

    Bug this catches (tried): without the continuation test (every back face within r covers), the
    sample is taken for covered and, with no free position on the floor, made invalid."""
    floor = quad((-1, 0, 1), (1, 0, 1), (1, 0, -1), (-1, 0, -1))
    wall = quad((1, 0, 1), (1, 0, -1), (1, 2, -1), (1, 2, 1))  # normal +x: away from the room
    assert np.allclose(wall.normals[0], [1, 0, 0])
    scene, tracer, names = _scene(tmp_path, {"Floor": floor, "Wall": wall}, True)
    a = _adjust(tracer, names, "Floor", [[0.98, 0.0, 0.0]], UP)
    assert not a.moved.any() and not a.invalid.any()
    np.testing.assert_array_equal(a.points, [[0.98, 0.0, 0.0]])


def test_floor_running_under_a_thick_wall_moves_to_the_room(tmp_path):
    """A floor that runs under a 10 cm wall (z in [1, 1.1]): a floor sample 1 cm inside the wall moves
    towards the room, to z = 1.01 - (0.01 + r) / 2 (the probe along -z meets the wall's inside at 1 cm)."""
    floor = quad((-1, 0, 1.1), (1, 0, 1.1), (1, 0, -1), (-1, 0, -1))
    scene, tracer, names = _scene(tmp_path, {"Floor": floor, "Wall": box((2.0, 2.0, 0.1), (0, 1.0, 1.05))}, True)
    a = _adjust(tracer, names, "Floor", [[0.0, 0.0, 1.01]], UP)
    r = S / np.sqrt(2)
    assert a.moved.tolist() == [True]
    np.testing.assert_allclose(a.points[0], [0.0, 0.0, 1.01 - (0.01 + r) / 2], atol=1e-6)


def test_invalid_texel_is_filled_from_its_own_object():
    """The middle texel of a 3 x 3 page is invalid; its left column belongs to its object (value 1), its
    right column to another (value 5): with labels it takes 1, without, the average of all 8 (3)."""
    image = np.zeros((3, 3, 1), np.float32)
    image[:, 0], image[:, 2] = 1.0, 5.0
    image[1, 1] = 100.0  # what the covered sample read
    valid = np.ones((3, 3), bool)
    valid[1, 1] = False
    valid[0, 1] = valid[2, 1] = False  # the middle column: the border between the two
    labels = np.array([[1, -1, 2], [1, 1, 2], [1, -1, 2]])
    assert dilate(image, valid, 1, labels)[1, 1, 0] == pytest.approx(1.0)
    assert dilate(image, valid, 1)[1, 1, 0] == pytest.approx(3.0)


@pytest.mark.parametrize("mode, moved", [("OPAQUE", True), ("MASK", False), ("BLEND", False)])
def test_cut_out_card_through_the_floor_covers_nothing(tmp_path, mode, moved):
    """A card standing through the floor (x = 0, facing +x), its base colour's alpha 0 (MASK: all cut
    out; BLEND: all passed, 1 - alpha > 1/2): a floor sample 2 cm behind it (x = -0.02), whose +x
    probe meets the card's back face within r = 4.4 cm, stays where it is; an opaque card of the
    same shape covers it and it moves (x = -0.02 + (0.02 + r) / 2). Expected by hand from the
    geometry. Bug this catches (tried): probes that ignore coverage move the sample under a card
    nobody sees (moved True for MASK and BLEND)."""
    w = GltfWriter()
    paint = w.add_material("Paint", base_color=(0.8, 0.8, 0.8))
    card = w.add_material("Card", base_color=(0.2, 0.6, 0.2, 0.0), alpha_mode=None if mode == "OPAQUE" else mode)
    w.add_node("Floor", mesh=add_mesh(w, "Floor", quad((-1, 0, 1), (1, 0, 1), (1, 0, -1), (-1, 0, -1)), paint))
    w.add_node("Card", mesh=add_mesh(w, "Card", quad((0, -0.1, 0.5), (0, -0.1, -0.5), (0, 0.5, -0.5), (0, 0.5, 0.5)),
                                     card))
    path = w.write(tmp_path / "s.glb")
    (tmp_path / "s.glint.toml").write_text("[sky]\n")
    scene = load_scene(path)
    tracer, names = RayTracer(scene), [o.name for o in scene.objects]
    a = adjust_samples(tracer, np.array([[-0.02, 0.0, 0.1]]), np.array([UP]), np.array([S]),
                       np.array([names.index("Floor")]), Coverage(scene, tracer))
    assert a.moved.tolist() == [moved] and not a.invalid.any()
    r = S / np.sqrt(2)
    want = [-0.02 + (0.02 + r) / 2 if moved else -0.02, 0.0, 0.1]
    np.testing.assert_allclose(a.points[0], want, atol=1e-6)


def test_sample_is_not_moved_into_a_slot_behind_a_plate(tmp_path):
    """A card modelled as one sheet standing through the floor (x = 0, facing +x) with a wall 1.4 cm in
    front of it (a box from x = 0.014): a floor sample 2 cm behind the card meets its back within r and
    the floor goes on past it, so it is covered; its only free positions lie between card and wall
    (x = -0.02 + (0.02 + r) / 2 = 0.012 along +x), a slot 1.4 cm wide, under SLOT x S = 1.56 cm: not
    taken, the sample is invalid (filled from its neighbours) and stays where it was. The wooden
    staircase's post has such a fin, 1 cm from a wall.

    Bug this catches (tried): without the slot rule the sample moves into the gap, to x = 0.012 (on the
    staircase: black where the reference is lit)."""
    card = quad((0, -0.1, 0.5), (0, -0.1, -0.5), (0, 0.5, -0.5), (0, 0.5, 0.5))
    assert np.allclose(card.normals[0], [1, 0, 0])
    scene, tracer, names = _scene(tmp_path, {"Floor": quad((-1, 0, 1), (1, 0, 1), (1, 0, -1), (-1, 0, -1)),
                                             "Card": card, "Wall": box((0.2, 1.0, 2.0), (0.114, 0.4, 0.0))}, True)
    a = _adjust(tracer, names, "Floor", [[-0.02, 0.0, 0.1]], UP)
    assert a.invalid.tolist() == [True] and a.moved.tolist() == [False]
    np.testing.assert_array_equal(a.points, [[-0.02, 0.0, 0.1]])


def _trough(radius: float, facets: int, length: float = 1.0):
    """An open half cylinder (y below its axis at y = radius, along z), `facets` flat facets, normals
    outwards (away from the axis): its inside, the concave side, is its back."""
    angle = np.pi + np.pi * np.arange(facets + 1) / facets
    ring = np.stack([radius * np.cos(angle), radius + radius * np.sin(angle)], axis=1)
    positions = np.concatenate([np.column_stack([ring, np.full(len(ring), z)]) for z in (-length / 2, length / 2)])
    normals = np.tile(np.column_stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)]), (2, 1))
    k = facets + 1
    indices = np.array([[i, i + 1, i + k + 1] for i in range(facets)] + [[i, i + k + 1, i + k] for i in range(facets)])
    mesh = Mesh(positions, normals, indices)
    p = mesh.positions[mesh.indices]
    ng = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert (np.einsum("ij,ij->i", ng, mesh.normals[mesh.indices[:, 0]]) > 0).all()  # wound to face outwards
    return mesh, ring


def test_concave_side_of_a_faceted_curve_is_not_covered(tmp_path):
    """The inside of an open trough 4 cm across (radius 2 cm, 16 facets 4 mm wide, normals outwards, as
    a handrail's profile is exported), baked on that concave back side: every probe longer than a facet
    meets the trough's own next facets from behind, and the trough goes on past them. That is the surface
    curving, not covering: no sample at the facets' middles is moved or invalid.

    Bug this catches (tried): a continuation test that accepts the very facet the probe crossed as the
    surface going on takes every such sample for covered (12 of the 12 invalid); the wooden staircase's
    handrails then read 0 on their lit side (20 % of its texels invalid, 4 % with the fix)."""
    mesh, ring = _trough(0.02, 16)
    scene, tracer, names = _scene(tmp_path, {"Trough": mesh}, True)
    middle = (ring[2:14] + ring[3:15]) / 2  # facets 2-13, away from the rims
    points = np.column_stack([middle, np.zeros(len(middle))])
    inward = np.column_stack([-(ring[3:15] - ring[2:14])[:, 1], (ring[3:15] - ring[2:14])[:, 0], np.zeros(len(middle))])
    inward /= np.linalg.norm(inward, axis=1, keepdims=True)
    assert (inward[:, 1] > 0).all()  # towards the axis
    a = adjust_samples(tracer, points, inward, np.full(len(points), S), np.full(len(points), names.index("Trough")))
    assert not a.moved.any() and not a.invalid.any()
    np.testing.assert_array_equal(a.points, points)


def test_enclosed_samples_are_those_in_cavities(tmp_path):
    """A sofa-like box 1 x 1 m whose bottom is 5 cm above the floor, and a solid 0.4 m cube elsewhere:
    the floor under the sofa's middle is enclosed (every probe meets the sofa's bottom, at most
    5 cm / cos 80 deg = 29 cm away for the R2 set's most grazing probe, under ENCLOSED_REACH = 8 texels
    of S = 6.25 cm: 0.5 m);
    the open floor 1.5 m from both is not; nor is the back side of the cube's top (inside a solid: its
    probes all meet the cube from behind within 0.4 / cos 53 deg = 0.5 m at most, but no one sees
    that cavity).

    Bug this catches (tried): without the front-face majority every solid's inside counts (the
    cube's back side True; on the wooden staircase 31 % of its samples instead of 7.6 %)."""
    from glint.bake.sample_points import enclosed

    floor = quad((-2, 0, 2), (2, 0, 2), (2, 0, -2), (-2, 0, -2))
    scene, tracer, names = _scene(tmp_path, {"Floor": floor, "Sofa": box((1.0, 0.4, 1.0), (0.0, 0.25, 0.0)),
                                             "Cube": box((0.4, 0.4, 0.4), (1.5, 0.2, 1.5))}, True)
    points = np.array([[0.0, 0.0, 0.0], [-1.5, 0.0, -1.5], [1.5, 0.4, 1.5]])
    normals = np.array([UP, UP, DOWN])
    assert enclosed(tracer, points, normals, np.full(3, S)).tolist() == [True, False, False]
