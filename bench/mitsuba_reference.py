"""Independent references from Mitsuba 3 (scalar_rgb; the llvm variants abort on this machine image).

Irradiance at a surface point, the documented method: a tiny Lambertian patch of
albedo 1 (a 4 mm disk, 0.5 mm above the surface, facing along the normal) seen by a
`radiancemeter` looking straight down at it. Its outgoing radiance is L = E / pi
(Eq. 4.1 with kd = 1), so E = pi * L. Mitsuba's path integrator does next-event
estimation with MIS at the patch, which makes this far less noisy than an
`irradiancemeter`, whose cosine-distributed rays must hit the small light by chance.
"""
from __future__ import annotations

import numpy as np
import trimesh  # trimesh.proximity needs rtree (the test extra declares it)

POINTS = 50
MARGIN = 0.1  # metres from facet borders and from other objects (the box is 2 m wide)


def _mitsuba():
    import mitsuba as mi  # optional (glint[bench], and part of glint[test]): imported only when a reference is rendered

    mi.set_variant("scalar_rgb")
    return mi


def cornell_box_irradiance(points: np.ndarray, normals: np.ndarray, spp: int = 1024,
                           seed: int = 0) -> np.ndarray:
    """(K, 3) irradiance at `points` with surface `normals` in mitsuba.cornell_box(), infinite depth."""
    mi = _mitsuba()
    scene_dict = mi.cornell_box()
    scene_dict["integrator"] = {"type": "path", "max_depth": -1, "rr_depth": 8}
    del scene_dict["sensor"]
    return irradiance_at(scene_dict, points, normals, spp, seed)


def scene_irradiance(scene, points: np.ndarray, normals: np.ndarray, spp: int = 1024,
                     seed: int = 0) -> np.ndarray:
    """(K, 3) irradiance at `points` facing `normals` in a glint Scene, converted for Mitsuba by
    bench/mitsuba_scene.py (two-sided materials as its `two_sided` BSDF), infinite depth."""
    _mitsuba()
    from glint.bench.mitsuba_scene import convert

    scene_dict, _ = convert(scene)
    scene_dict["integrator"] = {"type": "path", "max_depth": -1, "rr_depth": 8}
    return irradiance_at(scene_dict, points, normals, spp, seed)


def irradiance_at(scene_dict: dict, points: np.ndarray, normals: np.ndarray, spp: int = 1024,
                  seed: int = 0) -> np.ndarray:
    """(K, 3) irradiance at `points` facing `normals` in a Mitsuba scene dict without sensors: a
    white Lambertian patch and a radiancemeter per point (the module docstring), E = pi L."""
    mi = _mitsuba()
    scene_dict = dict(scene_dict)
    scene_dict["patch_bsdf"] = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}}
    for i, (p, n) in enumerate(zip(np.asarray(points, float), np.asarray(normals, float))):
        n = n / np.linalg.norm(n)
        centre = p + 5e-4 * n
        scene_dict[f"patch_{i}"] = {
            "type": "disk",
            "to_world": mi.ScalarTransform4f().look_at(origin=centre.tolist(), target=(centre + n).tolist(),
                                                       up=_any_perpendicular(n).tolist())
            @ mi.ScalarTransform4f().scale([2e-3, 2e-3, 1.0]),
            "bsdf": {"type": "ref", "id": "patch_bsdf"},
        }
        eye = centre + 1e-2 * n
        scene_dict[f"sensor_{i:04d}"] = {
            "type": "radiancemeter", "origin": eye.tolist(), "direction": (-n).tolist(),
            "film": {"type": "hdrfilm", "width": 1, "height": 1, "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp, "seed": seed + i},
        }
    scene = mi.load_dict(scene_dict)
    out = np.zeros((len(points), 3))
    for i in range(len(points)):
        image = np.array(mi.render(scene, sensor=i, spp=spp, seed=seed + i))
        out[i] = np.pi * image.reshape(-1, 3)[0]
    return out


def _any_perpendicular(n: np.ndarray) -> np.ndarray:
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    v = np.cross(n, a)
    return v / np.linalg.norm(v)


def sample_points(scene, count: int, margin: float, seed: int = 1):
    """(object, triangle, barycentric, point, normal) for points at least `margin`
    from the borders of their flat facet and from every other object."""
    rng = np.random.default_rng(seed)
    meshes = [trimesh.Trimesh(o.positions, o.indices, process=False) for o in scene.objects]
    candidates = []
    for i, (obj, mesh) in enumerate(zip(scene.objects, meshes)):
        areas = obj.triangle_areas
        tri = rng.choice(len(areas), size=400, p=areas / areas.sum())
        r1, r2 = rng.random(400), rng.random(400)
        s = np.sqrt(r1)
        bary = np.stack([1 - s, s * (1 - r2), s * r2], axis=1)
        pts = np.einsum("kj,kjc->kc", bary, obj.positions[obj.indices[tri]])
        keep = _distance_to_facet_border(mesh, tri, pts) > margin
        for j, other in enumerate(meshes):
            if j != i and keep.any():
                _, dist, _ = trimesh.proximity.closest_point(other, pts)
                keep &= dist > margin
        normals = mesh.face_normals[tri]
        candidates += [(i, t, b, p, n) for t, b, p, n, k in zip(tri, bary, pts, normals, keep) if k]
    # spread: round-robin over objects so every surface is represented
    by_object: dict[int, list] = {}
    for c in candidates:
        by_object.setdefault(c[0], []).append(c)
    chosen, lists = [], list(by_object.values())
    while len(chosen) < count and any(lists):
        for lst in lists:
            if lst and len(chosen) < count:
                chosen.append(lst.pop())
    return chosen, len(by_object)


def _distance_to_facet_border(mesh: trimesh.Trimesh, triangles, points) -> np.ndarray:
    """Distance from each point to the boundary of the coplanar facet its triangle belongs to."""
    facet_of = np.full(len(mesh.faces), -1)
    for f, faces in enumerate(mesh.facets):
        facet_of[faces] = f
    out = np.empty(len(points))
    for k, (t, p) in enumerate(zip(triangles, points)):
        f = facet_of[t]
        if f >= 0:
            edges = mesh.facets_boundary[f]
        else:
            face = mesh.faces[t]
            edges = np.array([[face[0], face[1]], [face[1], face[2]], [face[2], face[0]]])
        a, b = mesh.vertices[edges[:, 0]], mesh.vertices[edges[:, 1]]
        ab = b - a
        u = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
        out[k] = np.linalg.norm(a + u[:, None] * ab - p, axis=1).min()
    return out
