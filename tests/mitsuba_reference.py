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


def _mitsuba():
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    return mi


def cornell_box_irradiance(points: np.ndarray, normals: np.ndarray, spp: int = 1024,
                           seed: int = 0) -> np.ndarray:
    """(K, 3) irradiance at `points` with surface `normals` in mitsuba.cornell_box(), infinite depth."""
    mi = _mitsuba()
    scene_dict = mi.cornell_box()
    scene_dict["integrator"] = {"type": "path", "max_depth": -1, "rr_depth": 8}
    del scene_dict["sensor"]
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
