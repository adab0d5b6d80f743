"""Object roles: how the renderer treats an object's view-dependent light (docs/SCENES.md, section 3).

- `diffuse`: its material has no lobes: light map only, no specular work at run time.
- `transmissive`: any transmit lobe (thin glass, section 3.3.1): cube map.
- `planar`: flat and large (section 4.5): a mirror buffer. Flat means every vertex
  lies within max(1 mm, 1e-3 * bounding-box diagonal) of the best-fit plane and
  every face normal is within 2 degrees of the plane normal (same side: a mirror
  buffer reflects one side). Large means area >= 0.1 m^2 (a small mirror pass is
  not worth its cost next to a cube map look-up).
- `curved`: everything else with a lobe: a cube map (section 4.4).

The sidecar's `[objects."NAME"] role = ...` replaces the derived role
(`Object.role_overridden`).
"""
from __future__ import annotations

import numpy as np

from glint.core.errors import GlintError
from glint.core.geometry import PLANAR_ANGLE_DEG, face_cross, fit_plane, flatness_tolerance
from glint.core.scene import ROLES, Object, Scene

PLANAR_MIN_AREA = 0.1  # m^2


def is_planar(obj: Object) -> bool:
    """Flat within tolerance and large (see the module docstring)."""
    if obj.area < PLANAR_MIN_AREA:
        return False
    point, normal = fit_plane(obj.positions, obj.indices)
    tolerance = flatness_tolerance(obj)
    used = obj.positions[np.unique(obj.indices)]
    if np.abs((used - point) @ normal).max() > tolerance:
        return False
    cross = face_cross(obj.positions, obj.indices)
    length = np.linalg.norm(cross, axis=1)
    ok = length > 0
    cosines = (cross[ok] @ normal) / length[ok]
    return bool(np.all(cosines >= np.cos(np.radians(PLANAR_ANGLE_DEG))))


def derived_role(obj: Object, scene: Scene) -> str:
    """The role from geometry and material alone."""
    mat = scene.material_of(obj)
    if not mat.lobes:
        return "diffuse"
    if mat.transmit_lobes:
        return "transmissive"
    return "planar" if is_planar(obj) else "curved"


def assign_roles(scene: Scene, overrides: dict[str, str] | None = None) -> None:
    """Set `role` on every object: `overrides` (object name -> role) win over derived roles."""
    overrides = overrides or {}
    for name, role in overrides.items():
        if role not in ROLES:
            raise GlintError(f"unknown role {role!r} for '{name}'; use one of {', '.join(ROLES)}")
    for obj in scene.objects:
        if obj.name in overrides:
            obj.role, obj.role_overridden = overrides[obj.name], True
        else:
            obj.role, obj.role_overridden = derived_role(obj, scene), False
