"""Large reflectors split into parts (bake/probe_parts.py): one mesh with pieces in two rooms gets a
probe in each room; a convex object and one the sidecar gives its own probe stay whole.

The scene is built here: two rooms side by side, x < 0 and x > 0, a 20 cm wall between them
(x in [-0.1, 0.1]); "Trim" is one glTF mesh of two rough-metal balls, one in each room, so its box
centre (0, 1, 0) lies inside the wall; "Ball" a chrome ball in the left room. What is expected --
which room each piece is in, where a probe must be to see its piece's room -- follows from that
geometry, not from the code under test.
"""
from __future__ import annotations

import numpy as np
import trimesh

from glint.bake.cubemap import plan_cubemaps
from glint.bake.gltf_loader import load_scene
from glint.scenes.gltf_writer import GltfWriter

LEFT, RIGHT = (-1.5, 1.0, 0.0), (1.5, 1.0, 0.0)  # the Trim's two balls
WALL = ((-0.1, 0.0, -2.0), (0.1, 2.5, 2.0))


def box_mesh(lo, hi):
    box = trimesh.creation.box(bounds=np.array([lo, hi], float))
    return box.vertices, box.faces, box.vertex_normals


def write_rooms(path, sidecar: str = ""):
    w = GltfWriter()
    wall = w.add_material("Wall", base_color=(0.7, 0.7, 0.7, 1))
    rough = w.add_material("Rough metal", base_color=(0.9, 0.9, 0.9, 1), metallic=1.0, roughness=0.4)
    chrome = w.add_material("Chrome", base_color=(0.9, 0.9, 0.9, 1), metallic=1.0, roughness=0.05)
    for name, (lo, hi) in {"Floor": ((-3, -0.1, -2), (3, 0, 2)), "Ceiling": ((-3, 2.5, -2), (3, 2.6, 2)),
                           "Wall": WALL}.items():
        v, f, n = box_mesh(lo, hi)
        w.add_node(name, mesh=w.add_mesh(name, v, f, wall, normals=n))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.2)
    n = len(ball.vertices)
    trim_v = np.concatenate([ball.vertices + LEFT, ball.vertices + RIGHT])
    trim_f = np.concatenate([ball.faces, ball.faces + n])
    normals = np.asarray(ball.vertex_normals)
    w.add_node("Trim", mesh=w.add_mesh("Trim", trim_v, trim_f, rough, normals=np.concatenate([normals, normals])))
    w.add_node("Ball", mesh=w.add_mesh("Ball", ball.vertices + (-1.5, 1.0, 1.2), ball.faces, chrome, normals=normals))
    w.write(path)
    path.with_name(path.stem + ".glint.toml").write_text("[sky]\nradiance = [1, 1, 1]\n" + sidecar)
    return path


def test_a_mesh_in_two_rooms_gets_a_probe_in_each():
    """The Trim's box centre lies in the wall, hidden from both balls: it is split into two parts, one
    per room (every vertex on one side of the wall), each named after it and marked part_of it; each
    part's probe centre is in its own room (x < -0.1 or x > 0.1: outside the wall, on its part's side)
    and hides both parts (the whole object, as an object's own probe hides it). The chrome ball, whose
    centre every point of it sees (no wall in between: its own triangles are not occluders), stays whole.

    Deliberate bugs this catches (tried): no split (one probe at x = 0, inside the wall: the part
    assertions fail); a part's probe hiding only that part (the hidden-set assertion fails). (The
    object's own triangles counted as occluders still keeps the chrome ball whole: halving a ball
    hides as much of each half's centre, and a halving is kept only where it hides less.)"""
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as d:
        scene = load_scene(write_rooms(Path(d) / "rooms.glb"))
    parts = [o for o in scene.objects if o.part_of == "Trim"]
    assert [o.name for o in parts] == ["Trim part 1 of 2", "Trim part 2 of 2"]
    sides = sorted(float(np.sign(o.positions[:, 0]).mean()) for o in parts)
    assert sides == [-1.0, 1.0]  # each part wholly in one room
    assert [o.name for o in scene.objects if o.name.startswith("Ball")] == ["Ball"]
    assert all(o.role == "curved" for o in parts)
    plans = {p.name: p for p in plan_cubemaps(scene, "t")}
    index = {o.name: k for k, o in enumerate(scene.objects)}
    for part in parts:
        plan = next(p for p in plans.values() if index[part.name] in p.members)
        side = np.sign(part.positions[:, 0].mean())
        assert side * plan.centre[0] > WALL[1][0], (part.name, plan.centre)
        assert {index[o.name] for o in parts} <= set(plan.hidden)


def test_what_the_sidecar_gives_its_own_probe_stays_whole():
    """`shared_probe = false` (the user's own probe) keeps the Trim whole, with one probe.

    Deliberate bug this catches (tried): the split ignoring the sidecar's options (two parts)."""
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as d:
        scene = load_scene(write_rooms(Path(d) / "rooms.glb", '[objects."Trim"]\nshared_probe = false\n'))
    assert [o.name for o in scene.objects if o.name.startswith("Trim")] == ["Trim"]
    assert not any(o.part_of for o in scene.objects)
