"""Levels of detail (viewer/lod.py) and their choice in the culling pass (shaders/cull.comp):
the simplified meshes against the original surface, the level each object gets against numpy,
and a cube-map face drawn with levels against the same face drawn whole."""
from __future__ import annotations

import math

import numpy as np
import trimesh
from conftest import FAST
from test_draw_list import BoxesOnly

from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.core.bake_dir import Bake
from glint.cubemap_stage import face_camera, farthest
from glint.scenes.gltf_writer import GltfWriter
from glint.services import bake_scene
from glint.viewer import lod
from glint.viewer.draw_list import DrawList
from glint.viewer.gpu_meshes import OBJECT_LOD_DTYPE
from glint.viewer.renderer import Renderer


def area(positions: np.ndarray, triangles: np.ndarray) -> float:
    a, b, c = (positions[triangles[:, k]] for k in range(3))
    return float(np.linalg.norm(np.cross(b - a, c - a), axis=1).sum() / 2)


def test_levels_keep_a_closed_surface_its_area_and_its_orientation():
    """An icosphere of 5120 triangles: every level has at most 3/4 of the triangles of the one before,
    stays closed (each edge shared by exactly two triangles, in opposite directions: no hole, no
    flipped triangle), keeps the sphere's area within 4 % (the original's is 0.4 % under 4 pi) and
    every triangle faces outwards; each vertex of a level lies near the vertex whose attributes
    (light-map coordinates) it takes.

    Deliberate bug this catches (tried): the kept vertices at their original positions instead of
    the simplifier's (a collapse checked for flips at the moved position): 9 inward triangles at
    level 2."""
    sphere = trimesh.creation.icosphere(subdivisions=4)
    original, faces = np.asarray(sphere.vertices), np.asarray(sphere.faces, np.uint32)
    levels = lod.levels(original, faces)
    assert len(levels) == lod.LOD_LEVELS
    previous = len(faces)
    for source, positions, level in levels:
        # each vertex stays near the one it comes from (a level's attributes are that vertex's)
        assert len(source) == len(positions) and np.all(np.linalg.norm(positions - original[source], axis=1) < 0.3)
        assert 0 < len(level) <= lod.LOD_MIN_KEPT * previous and level.max() < len(positions)
        edges = np.concatenate([level[:, [0, 1]], level[:, [1, 2]], level[:, [2, 0]]])
        directed = {tuple(e) for e in edges.tolist()}
        assert len(directed) == len(edges), "an edge is used twice in one direction"
        assert all((b, a) in directed for a, b in directed), "an open or flipped edge"
        assert abs(area(positions, level) / (4 * math.pi) - 1) < 0.04
        a, b, c = (positions[level[:, k]] for k in range(3))
        assert np.all(np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) > 0)
        previous = len(level)


def test_the_culling_pass_picks_the_level_numpy_picks(ctx):
    """3000 boxes, each with up to LOD_LEVELS levels of decreasing index counts: the command of every
    drawn object draws the coarsest level with at least 3 pi (asin(r / d) scale)^2 indices (the disc
    its bounding sphere covers seen from the eye), its own range when none has as many or the eye
    is inside the sphere; objects within 0.1 % of a level's count are left out of the comparison.

    Deliberate bugs this catches (tried): the finest sufficient level instead of the coarsest
    (`break` at the first): 2265 commands differ; the sphere's radius over d taken as the angle's
    tangent at the box's nearest point (d - r): 395 differ."""
    rng = np.random.default_rng(3)
    n = 3000
    lo = rng.uniform(-20, 20, (n, 3))
    bounds = np.stack([lo, lo + rng.uniform(0.05, 3.0, (n, 3))], axis=1)
    triangles = rng.integers(100, 20000, n)
    scene = BoxesOnly(ctx, bounds, triangles, np.zeros(n, np.int64))
    table = np.zeros(n, OBJECT_LOD_DTYPE)
    for i in range(n):
        count = 3 * triangles[i]
        for k in range(rng.integers(0, lod.LOD_LEVELS + 1)):
            count = int(count * rng.uniform(0.3, 0.7)) // 3 * 3
            table[i]["first"][k], table[i]["count"][k] = 1000 * (i + 1) + k, count
    scene.lod_buffer = ctx.buffer(table.tobytes())
    draws = DrawList(ctx, scene)
    eye, scale = np.array([1.0, -2.0, 0.5]), 40.0
    everything = np.diag([0.04, 0.04, 0.001, 1.0])  # every box in view (x, y within -0.92 .. 0.94)
    draws.cull(everything, detail=(eye, scale))
    commands = np.frombuffer(draws.command_buffer.read(size=20 * n), np.uint32).reshape(n, 5)[np.argsort(draws.order)]

    centre, radius = bounds.mean(axis=1), np.linalg.norm(bounds[:, 1] - bounds[:, 0], axis=1) / 2
    d = np.linalg.norm(centre - eye, axis=1)
    need = 3 * np.pi * (np.arcsin(np.minimum(radius / d, 1.0)) * scale) ** 2
    expected_first, expected_count = np.zeros(n, np.int64), 3 * triangles
    clear = np.ones(n, bool)
    for i in range(n):
        if d[i] <= radius[i]:
            continue
        for k in range(lod.LOD_LEVELS):
            count = table[i]["count"][k]
            clear[i] &= count == 0 or abs(count / need[i] - 1) > 1e-3
            if count > 0 and count >= need[i]:
                expected_first[i], expected_count[i] = table[i]["first"][k], count
    coarse = expected_count < 3 * triangles
    assert clear.sum() > 2990 and coarse.sum() > 500 and (~coarse).sum() > 500
    assert np.all(commands[:, 1] == 1)
    wrong = clear & (commands[:, 0] != expected_count)
    assert not wrong.any(), f"{wrong.sum()} commands differ"
    assert np.array_equal(commands[coarse & clear, 2], expected_first[coarse & clear])
    draws.release()


def write_sphere_room(path) -> None:
    """A floor under a constant sky and a dense sphere (20480 triangles) of 0.5 m radius at (0, 0.5, 0)."""
    w = GltfWriter()
    floor = w.add_material("Floor", base_color=(0.6, 0.5, 0.4), roughness=1.0)
    ball = w.add_material("Ball", base_color=(0.2, 0.5, 0.8), roughness=1.0)
    s = 6.0
    w.add_node("Floor", mesh=w.add_mesh("Floor", np.array([[-s, 0, s], [s, 0, s], [s, 0, -s], [-s, 0, -s]], float),
                                        [[0, 1, 2], [0, 2, 3]], floor, normals=np.tile([0.0, 1.0, 0.0], (4, 1))))
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.5)
    w.add_node("Ball", mesh=w.add_mesh("Ball", np.asarray(sphere.vertices) + [0, 0.5, 0], np.asarray(sphere.faces),
                                       ball, normals=np.asarray(sphere.vertex_normals)))
    w.write(path)
    path.with_name(path.stem + ".glint.toml").write_text("[sky]\nradiance = [1.0, 1.0, 1.0]\n")


def test_faces_drawn_with_levels_match_faces_drawn_whole(ctx, tmp_path):
    """The six faces of a 32-texel probe (2 x 2 supersamples) at 1 m and at 5 m from a dense sphere,
    rendered with levels of detail at 1 triangle per pixel (the bake's LOD_TRIANGLES_PER_PIXEL) and
    with every mesh whole: the radiance differs by under 0.3 % of the whole faces' (L1 over the
    faces; measured 0.04 % and 0.003 %) and under 1 % of the texels by more than 10 % (0.16 %,
    0.02 %); from 5 m the faces draw under an eighth of the triangles (16x fewer), from 1 m over
    4x as many as from 5 m.

    Deliberate bugs this catches (tried): a level's vertices taking the attributes of the previous
    level's vertex numbers (`source` not composed along the chain of levels): L1 0.7 %, 4.0 % of
    the texels off by more than 10 %; every object at its coarsest level whatever its distance:
    from 1 m only 3x the triangles of 5 m."""
    path = tmp_path / "sphere.gltf"
    write_sphere_room(path)
    scene = load_scene(path)
    out = tmp_path / "sphere.bake"
    bake_scene(scene, resolve_settings(scene.bake_settings, **FAST), out, progress=False)
    bake = Bake(out)
    size = 32
    faces, drawn = {}, {}
    for level in (0.0, 1.0):
        with Renderer(ctx, bake, supersample=2, timing=False, display=False, lod=level) as r:
            lo, hi = r.scene.bounds
            for distance in (1.0, 5.0):
                centre = np.array([distance, 0.6, 0.3])
                images, triangles = [], 0
                for k in range(6):
                    r.render(face_camera(centre, k, farthest(lo, hi, centre)), size, size)
                    images.append(r.read_linear()[..., :3].mean(axis=-1))
                    triangles += r.draws.record(0)["triangles"]
                faces[level, distance], drawn[level, distance] = np.stack(images), triangles
    for distance in (1.0, 5.0):
        whole, detail = faces[0.0, distance], faces[1.0, distance]
        assert np.all(np.isfinite(detail))
        l1 = np.abs(detail - whole).sum() / whole.sum()
        off = np.mean(np.abs(detail - whole) > 0.1 * np.maximum(whole, 0.05 * whole.mean()))
        assert l1 < 0.003 and off < 0.01, (distance, l1, off)
    assert drawn[1.0, 5.0] < drawn[0.0, 5.0] / 8
    assert drawn[1.0, 1.0] > 4 * drawn[1.0, 5.0]  # the near probe draws the sphere finer
