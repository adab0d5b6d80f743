"""bake/roles.py: diffuse / curved / planar / transmissive, derived and overridden."""
import numpy as np
import pytest
import trimesh

from glint.bake.gltf_loader import load_scene
from glint.bake.roles import assign_roles, is_planar
from glint.core.errors import GlintError
from glint.core.geometry import plane_of
from glint.core.scene import Lobe, Material, Object, Scene
from glint.scenes.gltf_writer import GltfWriter

GLOSSY = Material("Glossy", lobes=[Lobe("reflect", mx=0.05, my=0.05)])
MATTE = Material("Matte")
GLASS = Material("Glass", kd=np.zeros(3, np.float32),
                 lobes=[Lobe("reflect", mx=0.01, my=0.01), Lobe("transmit", mx=0.01, my=0.01)])


def grid(nx=8, ny=8, size=(1.0, 1.0), bump=None) -> tuple[np.ndarray, np.ndarray]:
    """An (nx x ny)-cell grid in the XZ plane facing +Y; bump(x, z) adds height."""
    x, z = np.meshgrid(np.linspace(0, size[0], nx + 1), np.linspace(0, -size[1], ny + 1))
    y = np.zeros_like(x) if bump is None else bump(x, z)
    p = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    i = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    a, b, c, d = i[:-1, :-1], i[:-1, 1:], i[1:, 1:], i[1:, :-1]
    tris = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                           np.stack([a, c, d], -1).reshape(-1, 3)])
    return p, tris


def make(positions, indices, material=0, name="obj"):
    normals = np.tile(np.float32([0, 1, 0]), (len(positions), 1))
    return Object(name, np.asarray(positions, float), normals, np.asarray(indices), material)


def scene_of(*objects, materials=(GLOSSY, MATTE, GLASS)):
    return Scene("test", None, objects=list(objects), materials=list(materials))


def test_large_flat_quad_is_planar_small_one_is_curved():
    big = make(*grid(size=(1.0, 1.0)), name="big")
    small = make(*grid(size=(0.3, 0.3)), name="small")  # 0.09 m^2 < 0.1 m^2
    scene = scene_of(big, small)
    assign_roles(scene)
    assert big.role == "planar" and small.role == "curved"
    assert not big.role_overridden


def test_sphere_with_lobe_is_curved():
    s = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    sphere = make(s.vertices, s.faces)
    scene = scene_of(sphere)
    assign_roles(scene)
    assert sphere.role == "curved"


def test_no_lobes_is_diffuse_and_transmit_lobe_is_transmissive():
    wall = make(*grid(size=(3, 2.5)), material=1)
    pane = make(*grid(size=(1, 1)), material=2)  # flat and large, but glass wins
    scene = scene_of(wall, pane)
    assign_roles(scene)
    assert wall.role == "diffuse" and pane.role == "transmissive"


def test_flatness_tolerance_of_one_millimetre_and_two_degrees():
    # 0.4 mm ripple on a 1 m panel: flat (tolerance max(1 mm, 1e-3 * diag))
    ripple = make(*grid(16, 16, bump=lambda x, z: 4e-4 * np.sin(9 * x) * np.cos(7 * z)))
    assert is_planar(ripple)
    # a 5 mm bow over 1 m: not flat
    bow = make(*grid(16, 16, bump=lambda x, z: 0.02 * (x - 0.5) ** 2))
    assert not is_planar(bow)
    # a fold of 3 degrees between two halves
    rise = np.tan(np.radians(3))
    fold = make(*grid(16, 16, bump=lambda x, z: np.where(x > 0.5, (x - 0.5) * rise, 0)))
    assert not is_planar(fold)
    # A flipped triangle in an otherwise flat panel is not a one-sided mirror.
    p, t = grid()
    t = t.copy()
    t[0] = t[0, ::-1]
    assert not is_planar(make(p, t))


def test_plane_of_a_tilted_offset_panel():
    p, t = grid(size=(2, 1))
    # rotate 30 degrees about X then move: normal (0, cos30, sin30) ... by hand
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    rx = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    moved = p @ rx.T + [1, 2, 3]
    obj = make(moved, t)
    point, normal = plane_of(obj)
    np.testing.assert_allclose(normal, [0, c, s], atol=1e-9)
    # the plane passes through every vertex and through the panel's centre
    np.testing.assert_allclose((moved - point) @ normal, 0, atol=1e-9)
    np.testing.assert_allclose(point, np.array([1, 0, -0.5]) @ rx.T + [1, 2, 3], atol=1e-9)
    scene = scene_of(obj)
    assign_roles(scene)
    assert obj.role == "planar"


def test_overrides_win_and_are_marked():
    wall = make(*grid(size=(3, 2.5)), material=1, name="wall")
    ball = make(*grid(size=(0.2, 0.2)), material=0, name="ball")
    scene = scene_of(wall, ball)
    assign_roles(scene, {"wall": "planar", "ball": "diffuse"})
    assert (wall.role, wall.role_overridden) == ("planar", True)
    assert (ball.role, ball.role_overridden) == ("diffuse", True)
    with pytest.raises(GlintError, match="unknown role 'shiny'"):
        assign_roles(scene, {"wall": "shiny"})


def test_sidecar_role_by_node_and_by_mesh_name(tmp_path):
    w = GltfWriter()
    glossy = w.add_material("Glossy", roughness=0.1)
    p, t = grid(size=(1, 1))
    top = w.add_mesh("TopMesh", p, t, glossy, normals=np.tile([0, 1, 0], (len(p), 1)))
    w.add_node("Table top", mesh=top)
    w.add_node("Other top", mesh=top, translation=(2, 0, 0))
    leg = w.add_mesh("LegMesh", p * 0.2, t, glossy, normals=np.tile([0, 1, 0], (len(p), 1)))
    w.add_node("Leg", mesh=leg)
    w.add_node("Bulb", light=w.add_light("Bulb", "point"), translation=(0, 2, 0))
    w.write(tmp_path / "room.glb")
    (tmp_path / "room.glint.toml").write_text(
        '[objects."Table top"]\nrole = "curved"\n[objects."LegMesh"]\nrole = "diffuse"\n')
    scene = load_scene(tmp_path / "room.glb")
    roles = {o.name: (o.role, o.role_overridden) for o in scene.objects}
    assert roles == {"Table top": ("curved", True), "Other top": ("planar", False),
                     "Leg": ("diffuse", True)}


def test_plane_of_an_overridden_slab_is_its_top_face():
    box = trimesh.creation.box(extents=(1.2, 0.04, 0.8))
    box.apply_translation((0, 0.73, 0))  # top face at y = 0.75
    slab = make(box.vertices, box.faces)
    assert not is_planar(slab)  # a box is not flat ...
    scene = scene_of(slab)
    assign_roles(scene, {"obj": "planar"})  # ... but the sidecar may say it mirrors
    point, normal = plane_of(slab)
    np.testing.assert_allclose(normal, [0, 1, 0], atol=1e-9)
    assert point[1] == pytest.approx(0.75)
