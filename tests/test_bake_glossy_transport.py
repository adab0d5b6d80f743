"""The bake's transport through reflection lobes against Mitsuba 3: irradiance on the walls and
ceiling of a room whose floor is a glossy or near-mirror metal (glTF metallicFactor 1, roughnessFactor
sqrt(m): Beckmann m 0.05 or 0.001, r0 1, ks = base colour 0.9, kd 0).

The method of tests/test_bake_vs_mitsuba.py (bench/mitsuba_reference.py: Mitsuba's irradiance at
a point is pi x the radiance of a tiny white Lambertian patch there), with the bake's integrator
(bake/irradiance.py) evaluated at the same points; Mitsuba renders the same scene with the section
3.3 BSDF as its plugin (bench/mitsuba_bsdf.py), unlimited depth. Most of the light reaching the
walls has bounced off the floor (the lamp faces down), so a bake whose paths end at a metal floor
(kd = 0) misses it.
"""
from __future__ import annotations

import numpy as np
import pytest

from glint.bake.gltf_loader import load_scene
from glint.bake.irradiance import compute_irradiance
from glint.bake.raytrace import RayTracer
from glint.bench.measure_regularisation import write_metal_floor_room
from glint.bench.mitsuba_reference import scene_irradiance


def wall_points():
    """24 points: 5 on each wall at heights 0.4-1.6 m, 4 on the ceiling away from the lamp; inward normals."""
    points, normals = [], []
    for axis, sign in ((0, -1), (0, 1), (2, -1), (2, 1)):
        for k, (s, y) in enumerate(((-0.6, 0.4), (0.0, 1.0), (0.6, 1.6), (-0.5, 1.3), (0.5, 0.7))):
            p = np.zeros(3)
            p[axis], p[2 - axis], p[1] = sign * 1.0, s, y
            n = np.zeros(3)
            n[axis] = -sign
            points.append(p)
            normals.append(n)
    for x, z in ((-0.8, -0.8), (0.8, -0.8), (-0.8, 0.8), (0.8, 0.8)):
        points.append(np.array([x, 2.0, z]))
        normals.append(np.array([0.0, -1.0, 0.0]))
    return np.array(points), np.array(normals)


def mitsuba_irradiance(scene, points, normals, cache: str) -> np.ndarray:
    """Mitsuba 3's irradiance at `points` facing `normals` (bench/mitsuba_reference.py's
    scene_irradiance, scalar_rgb, 2048 samples per point), read from tests/data/mitsuba/`cache`.npz
    when its key matches the scene, points, variant and code (tests/mitsuba_cache.py), else rendered."""
    import mitsuba_cache

    from glint.bench import mitsuba_reference

    return mitsuba_cache.reference(cache, lambda: scene_irradiance(scene, points, normals, spp=2048),
                                   variant="scalar_rgb", code=[mitsuba_irradiance, mitsuba_reference], scene=scene,
                                   points=points, normals=normals)


@pytest.mark.slow
@pytest.mark.parametrize("M", [0.05, 0.001])  # glTF roughness sqrt(M): a Beckmann m near M
def test_metal_floor_room_irradiance_matches_mitsuba(tmp_path, M):
    """Mean relative L1 error over the 24 points at most 3 %, the signed mean within +-1.5 % (measured:
    1.4 % and -0.3 %; the two sides' noise: the bake's 16384 paths and Mitsuba's 2048 samples per
    point, each ~1-3 % per point, the caustic of the lamp off the floor dominating).

    Deliberate bugs this catches (tried, never committed): the bake's paths ignoring the lobes (the
    transport before this change: paths end at the metal floor) gives mean error 26.7 % and signed
    mean -26.7 % (walls and ceiling far too dark, up to -46 % at a point); next-event estimation at
    a path vertex with only kd / pi (the lobes left out of the light sample, its MIS weight still
    against the mixture) gives signed mean -2.8 %. (The lobe pdf without Eq. 4.9's cos(theta_h)
    passes here: cos(theta_h) ~ 1 for m = 0.05.) At m = 0.001 the bake's lobe is widened to
    M_REGULARISE = 0.02 (bake/scatter.py), Mitsuba's is not: the case bounds the regularisation's
    bias on a near-mirror floor under an area lamp (measured 1.5 %, signed -0.5 %).
    Mitsuba's irradiance is cached in tests/data/mitsuba/metal_floor_room_M.npz (`mitsuba_irradiance`)."""
    scene = load_scene(write_metal_floor_room(tmp_path / "room.glb", M))
    floor = next(m for m in scene.materials if m.name == "Floor")
    # the metal's lobes as the loader maps them (fitted to the glTF BRDF, issue 24): the first's m near M,
    # Kurt's alpha ~ 1/2; from roughness 0.2 (M 0.04) three, together GGX's tail (bake/gltf_fit_table.py)
    assert float(np.max(floor.kd)) == 0 and [lobe.kind for lobe in floor.lobes] in (["reflect"], ["reflect"] * 3)
    assert 0.5 * M <= floor.lobes[0].mx <= 2 * M and floor.lobes[0].alpha > 0.3
    points, normals = wall_points()
    ours = compute_irradiance(scene, RayTracer(scene), points, normals, 16384, seed=1).irradiance
    reference = mitsuba_irradiance(scene, points, normals, f"metal_floor_room_{M}")
    rel = np.abs(ours - reference).sum(axis=1) / reference.sum(axis=1)
    signed = (ours - reference).sum(axis=1) / reference.sum(axis=1)
    print(f"mean relative error {rel.mean():.4f}, max {rel.max():.4f}, signed mean {signed.mean():+.4f}")
    assert rel.mean() <= 0.03
    assert abs(signed.mean()) <= 0.015
