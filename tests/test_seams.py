"""Light maps that do not leak where separately modelled meshes meet (issue 25), against Mitsuba 3.

The scene is tests/seam_scenes.py's interior: a room of double-sided quads lit by a sky through a
window, a crown moulding through the ceiling by 1 cm, a skirting board 1 mm off a wall, a sofa-like
box on the floor, a 10 cm thick wall over which floor and ceiling run. Along each of its 12 seams, a
strip 10 cm wide on the visible surface is cut into 4 x 4-texel blocks (25 cm along the seam at
preview's 16 texels per metre) of 12 points each; the light map's bilinear look-up there (what the
viewer reads) is averaged per block and held against Mitsuba's irradiance at the same points
(tests/data/seam_interior_reference.npz, 4096 samples per point, made by
tests/data/make_seam_references.py through bench/mitsuba_reference.py).

Bounds: no block more than 25 % too bright; the thick wall's room side away from its borders (its
dark side: the sky lights its other side) within 5 % on average. Measured in docs/BAKE.md
"Sample points".
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

import seam_scenes as S
from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.core.bake_dir import Bake
from glint.services import bake_scene

REFERENCE = Path(__file__).parent / "data" / "seam_interior_reference.npz"
TOO_BRIGHT = 1.25
# preview's texel density, 4 x its paths: at preview's 128 a block in the sofa's shade on the thick
# wall's foot reads 1.30 with the default seed, 1.10 with seed 1, 1.16 at 512 (noise the denoiser
# leaves, not a leak); this test is about where samples lie, not about noise
SAMPLES = 512
DARK_SIDE = 0.05


def _bake(tmp_path: Path, double_sided: bool = True, samples: int = SAMPLES, split_floor: bool = False):
    scene = load_scene(S.write_interior(tmp_path / "interior.glb", double_sided=double_sided, split_floor=split_floor))
    bake_scene(scene, resolve_settings(scene.bake_settings, quality="preview", samples=samples),
               tmp_path / "interior.bake", progress=False)
    return scene, Bake(tmp_path / "interior.bake")


def _look_up(scene, bake: Bake, strip: S.Strip, points: np.ndarray) -> np.ndarray:
    """The light map's bilinear value at points (K, 3) of the strip's face (the object's triangles
    facing the strip's normal)."""
    obj = [o.name for o in scene.objects].index(strip.object)
    o = scene.objects[obj]
    mesh = trimesh.Trimesh(o.positions, o.indices, process=False)
    faces = np.flatnonzero(mesh.face_normals @ np.asarray(strip.normal, float) > 0.99)
    _, distance, nearest = trimesh.proximity.closest_point(mesh.submesh([faces], append=True), points)
    assert distance.max() < 1e-5, f"{strip.name}: a point off its face"
    tri = faces[nearest]
    return bake.irradiance(obj, tri, trimesh.triangles.points_to_barycentric(mesh.triangles[tri], points))


def block_ratios(scene, bake: Bake) -> dict[str, np.ndarray]:
    """Per strip (and the thick wall's interior), the blocks' mean look-up over Mitsuba's mean."""
    ref = np.load(REFERENCE)
    out = {}
    for strip in (*S.SEAMS, S.THICK_WALL_INTERIOR):
        points, E = ref[f"{strip.name}/points"].astype(np.float64), ref[f"{strip.name}/E"].astype(np.float64)
        ours = _look_up(scene, bake, strip, points.reshape(-1, 3)).reshape(points.shape)
        out[strip.name] = ours.mean(axis=(1, 2)) / E.mean(axis=(1, 2))
    return out


def _report(ratios: dict) -> str:
    return "\n".join(f"{k:24s} " + " ".join(f"{r:.2f}" for r in v) for k, v in ratios.items())


@pytest.mark.slow
@pytest.mark.parametrize("double_sided", [True, False])
def test_seams_are_not_too_bright(tmp_path, double_sided):
    """Every seam block at most 25 % above Mitsuba, the thick wall's dark side within 5 %.

    The same room single-sided has the same reference: from inside it only front faces are seen.
    Bugs this catches (tried): the old rule (samples on chart borders' edges, none moved: bake/
    texels.py EDGE_INSET = 0 and bake/sample_points.py off) reads the moulding under the ceiling
    at up to ~1.8 x and fails (test_the_old_rule_leaks below keeps that checked)."""
    scene, bake = _bake(tmp_path, double_sided)
    ratios = block_ratios(scene, bake)
    print(_report(ratios))
    interior = ratios.pop(S.THICK_WALL_INTERIOR.name)
    worst = max(float(v.max()) for v in ratios.values())
    assert worst <= TOO_BRIGHT, _report(ratios)
    assert abs(float(interior.mean()) - 1.0) <= DARK_SIDE, interior


@pytest.mark.slow
def test_the_old_rule_leaks(tmp_path, monkeypatch):
    """Without this fix the same comparison fails: some seam block more than 25 % too bright (measured:
    docs/BAKE.md "Sample points"). Keeps the test above able to fail."""
    import glint.bake.lightmap as lightmap
    import glint.bake.texels as texels
    from glint.bake.sample_points import SampleAdjustment

    monkeypatch.setattr(texels, "EDGE_INSET", 0.0)
    monkeypatch.setattr(lightmap, "adjust_samples", lambda tracer, points, normals, sizes, objects, coverage=None: SampleAdjustment(
        np.asarray(points, np.float64), np.zeros(len(points), bool), np.zeros(len(points), bool)))
    scene, bake = _bake(tmp_path, samples=128)
    ratios = block_ratios(scene, bake)
    print(_report(ratios))
    ratios.pop(S.THICK_WALL_INTERIOR.name)
    assert max(float(v.max()) for v in ratios.values()) > 1.5


@pytest.mark.slow
def test_no_line_where_two_meshes_of_one_floor_meet(tmp_path):
    """The floor as two meshes meeting at x = 0 (separate charts): the light map's look-ups 2 mm either
    side of the seam, at 24 points along it in front of the sofa, differ by at most 2 % on average and
    4 % at worst (measured 0.9 % and 2.2 %; texels one apart inside a chart differ by 0.7 % and 2.4 %).

    Bug this catches (tried): no stitching (bake/seams.py `stitch` returning its input) differs by
    5.8 % on average and 11.4 % at worst."""
    scene, bake = _bake(tmp_path, samples=128, split_floor=True)
    names = [o.name for o in scene.objects]
    z = np.linspace(-0.9, 0.1, 24)
    values = []
    for name, x in (("Floor", -0.002), ("Floor east", 0.002)):
        obj = names.index(name)
        o = scene.objects[obj]
        mesh = trimesh.Trimesh(o.positions, o.indices, process=False)
        points = np.c_[np.full(len(z), x), np.zeros(len(z)), z]
        _, _, tri = trimesh.proximity.closest_point(mesh, points)
        bary = trimesh.triangles.points_to_barycentric(mesh.triangles[tri], points)
        values.append(bake.irradiance(obj, tri, bary).mean(axis=1))
    west, east = values
    difference = np.abs(west - east) / (0.5 * (west + east))
    print(f"across the seam: mean {difference.mean():.4f}, max {difference.max():.4f}")
    assert difference.mean() <= 0.02
    assert difference.max() <= 0.04


def test_near_pairs_search_each_point_in_its_own_radius():
    """`near_pairs` gives exactly the brute-force pairs closer than both radii (random points, radii
    over three orders of magnitude), and a set of 60,000 tiny texels beside one huge one returns at
    once. Deliberate bug this catches (tried): the search before it, one radius for all (the
    largest): the 60,000 points ask for ~1.8e9 pairs (std::bad_alloc after 54 s; found baking the 10,000-box
    room of scenes/stress.py)."""
    from glint.bake.seams import near_pairs

    rng = np.random.default_rng(25)
    points = rng.random((600, 3))
    radius = 10.0 ** rng.uniform(-3, 0, 600) * 0.3
    i, j = near_pairs(points, radius)
    d = np.linalg.norm(points[:, None] - points[None], axis=-1)
    bi, bj = np.nonzero((d < np.minimum(radius[:, None], radius[None])) & np.triu(np.ones_like(d, bool), 1))
    assert len(bi) > 50 and np.array_equal(i, bi) and np.array_equal(j, bj)
    many = rng.random((60_000, 3))
    sizes = np.full(60_000, 1e-3)
    sizes[0] = 10.0  # one texel as large as the scene
    i, j = near_pairs(many, sizes)
    assert len(i) < 10 * len(many)
