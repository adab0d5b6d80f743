"""Adaptive sampling in the light-map stage (issue 25, bake/lightmap.py "Adaptive sampling"): which
texels get more paths, that their paths continue their own sequence, and that the result does not
depend on how the refinement is split into tasks.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

import glint.bake.lightmap as LM
from glint.bake.gltf_loader import load_scene
from glint.bake.irradiance import compute_irradiance, refine_irradiance
from glint.bake.lights import luminance
from glint.bake.raytrace import RayTracer
from glint.bake.settings import resolve_settings
from glint.bake.texels import TexelPage, rasterize_texels
from glint.bake.unwrap import unwrap
from glint.scenes import builtin_path


def _page(objects: np.ndarray) -> TexelPage:
    H, W = objects.shape
    zero = np.zeros((H, W, 3), np.float32)
    return TexelPage(zero, zero, objects.astype(np.int32), np.zeros((H, W), np.int32))


def test_a_texel_is_refined_for_its_neighbours_never_for_its_own_paths():
    """An 8 x 8 page, object 0 in columns 0-3, object 1 in columns 4-7; every texel's paths equal (no
    deviation) but three, whose paths are one bright in 128 (deviation ~11 x the mean): (2, 1) alone, and (5, 3)
    with (6, 3), the latter two at object 0's edge next to object 1. Expected, by hand: the 3 x 3
    around each flagged texel, only object 0's texels, and a flagged texel only when another flagged
    texel is its neighbour: (5, 3) and (6, 3) yes, (2, 1) no.

    Bug this catches (tried): the texel's own flag counted (`flags[:, 4] = 0.0` removed in
    bake/lightmap.py undersampled) refines (2, 1) too: the set differs."""
    objects = np.where(np.arange(8)[None, :] < 4, 0, 1) * np.ones((8, 1), int)
    page = _page(objects)
    covered = [np.ones((8, 8), bool)]
    n = 64
    count = np.full(n, 128, np.int64)
    total = np.ones((n, 3)) * 128.0  # luminance 1 per path (LUMA sums to 1)
    square = np.full(n, 128.0)
    flagged = [(2, 1), (5, 3), (6, 3)]
    for y, x in flagged:  # one path of luminance 128, the others 0: the same mean, a standard error of ~1
        square[y * 8 + x] = 128.0 ** 2
    assert abs(luminance(total[0]) - 128.0) < 1e-9
    refined = LM.undersampled([page], covered, [np.zeros((8, 8), bool)], total, square, count, np.ones(n, bool))
    expected = set()
    for y, x in flagged:
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                yy, xx = y + dy, x + dx
                if (dy or dx) and 0 <= yy < 8 and 0 <= xx < 4:
                    expected.add(yy * 8 + xx)
    assert set(refined.tolist()) == expected
    assert 2 * 8 + 1 not in expected and {5 * 8 + 3, 6 * 8 + 3} <= expected


def test_refined_paths_continue_the_texels_own_sequence():
    """Points on cornell-box's surfaces: 128 paths, then refined to 1024 (refine_irradiance), against
    16384 paths of another seed. The mean relative error over the lit points must fall to under 0.45 x
    its value (measured: 0.049 -> 0.016; 1 / sqrt(8) = 0.35 x expected for 8 x the paths).

    Bug this catches (tried): refine_irradiance tracing each round from sample 0 again (`first_sample`
    0 instead of n) repeats paths: 0.049 -> 0.029 (0.59 x)."""
    scene = load_scene(builtin_path("cornell-box"))
    tracer = RayTracer(scene)
    rng = np.random.default_rng(3)
    s = resolve_settings(scene.bake_settings, quality="draft")
    page = rasterize_texels(scene.objects, unwrap(scene.objects, s.texels_per_metre, s.padding, s.max_page_size))[0]
    ys, xs = np.nonzero(page.object >= 0)
    pick = rng.choice(len(ys), 48, replace=False)
    points = page.position[ys[pick], xs[pick]].astype(np.float64)
    normals = page.normal[ys[pick], xs[pick]].astype(np.float64)
    points = points + 1e-3 * normals
    first = compute_irradiance(scene, tracer, points, normals, 128, seed=5)
    ids = np.arange(len(points), dtype=np.uint64)
    total, square, count = first.total.copy(), first.square.copy(), first.samples.copy()
    refine_irradiance(scene, tracer, points, normals, ids, total, square, count, 1024, seed=5)
    assert (count == 1024).all()
    reference = luminance(compute_irradiance(scene, tracer, points, normals, 16384, seed=99).total) / 16384
    lit = reference > 0.05 * reference.max()
    before = np.mean(np.abs(luminance(first.total)[lit] / 128 / reference[lit] - 1))
    after = np.mean(np.abs(luminance(total)[lit] / 1024 / reference[lit] - 1))
    print(f"mean relative error: 128 paths {before:.3f}, refined to 1024 {after:.3f}")
    assert after < 0.45 * before


def test_refinement_does_not_depend_on_the_workers(monkeypatch):
    """cornell-box at draft with a low SELECT_CV (so that hundreds of texels are refined), in small
    tiles: one worker and two give the same light maps, byte for byte, and the refinement added paths.

    Bug this catches (tried): the refinement's results put back by task order (`rows` taken from the
    first task) instead of each task's own texels: the pages differ between 1 and 2 workers."""
    monkeypatch.setattr(LM, "TILE", 512)
    monkeypatch.setattr(LM, "SELECT_CV", 1.7)
    scene = load_scene(builtin_path("cornell-box"))
    s = resolve_settings(scene.bake_settings, quality="draft", adaptive_samples=4)
    pages = rasterize_texels(scene.objects, unwrap(scene.objects, s.texels_per_metre, s.padding, s.max_page_size))
    one = LM.bake_lightmaps(scene, pages, replace(s, jobs=1))
    two = LM.bake_lightmaps(scene, pages, replace(s, jobs=2))
    flagged = one.refined - one.enclosed  # to 4 x samples; the cavity texels to ENCLOSED_SAMPLES x
    assert one.refined > 100 and one.refined_paths == (flagged * 3 + one.enclosed * (LM.ENCLOSED_SAMPLES - 1)) * s.samples
    assert (one.refined, one.refined_paths) == (two.refined, two.refined_paths)
    for a, b in zip(one.irradiance, two.irradiance):
        assert np.array_equal(a, b)


def test_texels_in_a_cavity_get_more_paths_whatever_their_paths(tmp_path, monkeypatch):
    """A floor with a sofa-like box 1 x 1 m over it, 5 cm up, single-sided, at draft (8 texels per
    metre: conservatively rasterised, at most 10 x 10 floor texels touch the square under the box, and
    as many on its bottom facing the floor), no texel
    flagged (SELECT_CV out of reach): the texels in that cavity, and only they, get ENCLOSED_SAMPLES x
    `samples` paths: 0 < enclosed <= 200 (measured: 130), every refined texel an enclosed one, and exactly
    (ENCLOSED_SAMPLES - 1) x samples paths added for each. With adaptive sampling off none is.

    Bug this catches (tried): the cavity texels left out of the refinement (enclosed 0: living-room's
    last firefly stays, docs/BAKE.md "Fireflies")."""
    from glint.scenes.generate import add_mesh, box, quad
    from glint.scenes.gltf_writer import GltfWriter

    monkeypatch.setattr(LM, "SELECT_CV", 1e9)
    w = GltfWriter()
    m = w.add_material("Paint", base_color=(0.8, 0.8, 0.8))
    w.add_node("Floor", mesh=add_mesh(w, "Floor", quad((-2, 0, 2), (2, 0, 2), (2, 0, -2), (-2, 0, -2)), m))
    w.add_node("Sofa", mesh=add_mesh(w, "Sofa", box((1.0, 0.4, 1.0), (0.0, 0.25, 0.0)), m))
    path = w.write(tmp_path / "s.glb")
    (tmp_path / "s.glint.toml").write_text("[sky]\n")
    scene = load_scene(path)
    s = resolve_settings(scene.bake_settings, quality="draft")
    pages = rasterize_texels(scene.objects, unwrap(scene.objects, s.texels_per_metre, s.padding, s.max_page_size))
    on = LM.bake_lightmaps(scene, pages, replace(s, jobs=1))
    print(f"enclosed {on.enclosed}, refined {on.refined}, +{on.refined_paths} paths")
    assert 0 < on.enclosed <= 200 and on.refined == on.enclosed
    assert on.refined_paths == on.enclosed * (LM.ENCLOSED_SAMPLES - 1) * s.samples
    off = LM.bake_lightmaps(scene, pages, replace(s, jobs=1, adaptive_samples=1))
    assert off.enclosed == off.refined == off.refined_paths == 0
