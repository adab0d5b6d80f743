"""Object roles: how the renderer treats an object's view-dependent light (DESIGN.md).

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

from bake.scene import ROLES, Object, Scene
from bake.validate import face_cross
from glint.errors import GlintError

PLANAR_MIN_AREA = 0.1  # m^2
PLANAR_DISTANCE = 1e-3  # m, absolute floor of the flatness tolerance
PLANAR_RELATIVE = 1e-3  # times the bounding-box diagonal
PLANAR_ANGLE_DEG = 2.0


def fit_plane(positions: np.ndarray, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Best-fit plane of a triangle set -> (point, unit normal).

    Area-weighted least squares over the triangles (exact second moments of
    each triangle, so a finely tessellated part does not outweigh a coarse one);
    the normal is the smallest principal axis, oriented like the summed face normals.
    """
    p = positions[indices]  # (M, 3, 3)
    cross = face_cross(positions, indices)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    total = area.sum()
    if total <= 0:
        raise GlintError("cannot fit a plane to triangles without area")
    centroid = (area[:, None] * p.mean(axis=1)).sum(axis=0) / total
    q = p - centroid
    # Second moment of a triangle about the origin: A/12 * (sum_i v_i v_i^T + s s^T), s = sum_i v_i.
    s = q.sum(axis=1)
    cov = (np.einsum("m,mki,mkj->ij", area, q, q) + np.einsum("m,mi,mj->ij", area, s, s)) / 12.0
    _, vectors = np.linalg.eigh(cov)
    normal = vectors[:, 0]
    if np.dot(normal, cross.sum(axis=0)) < 0:
        normal = -normal
    return centroid, normal / np.linalg.norm(normal)


def plane_of(obj: Object) -> tuple[np.ndarray, np.ndarray]:
    """The mirror plane of an object -> (point, unit normal), for the planar passes.

    For a flat object this is its best-fit plane. An object made `planar` by the
    sidecar need not be flat (a table top modelled as a thin box): then the plane
    is that of its largest coplanar group of faces (same normal within 2 degrees,
    same offset within the flatness tolerance), preferring the upward-facing
    group on a tie, so a slab mirrors on its top face.
    """
    cross = face_cross(obj.positions, obj.indices)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    unit = np.divide(cross, 2 * area[:, None], out=np.zeros_like(cross), where=area[:, None] > 0)
    centre = obj.positions[obj.indices].mean(axis=1)
    tolerance = _tolerance(obj)
    cos_max = np.cos(np.radians(PLANAR_ANGLE_DEG))
    remaining = area > 0
    groups = []
    while remaining.any():
        seed = int(np.argmax(np.where(remaining, area, -1.0)))
        n = unit[seed]
        coplanar = np.abs((centre - centre[seed]) @ n) <= tolerance
        member = remaining & (unit @ n >= cos_max) & coplanar
        groups.append((area[member].sum(), n[1], member))
        remaining &= ~member
    best = max(g[0] for g in groups)
    _, _, member = max((g for g in groups if g[0] >= best * (1 - 1e-6)), key=lambda g: g[1])
    return fit_plane(obj.positions, obj.indices[member])


def _tolerance(obj: Object) -> float:
    lo, hi = obj.bounds
    return max(PLANAR_DISTANCE, PLANAR_RELATIVE * float(np.linalg.norm(hi - lo)))


def is_planar(obj: Object) -> bool:
    """Flat within tolerance and large (see the module docstring)."""
    if obj.area < PLANAR_MIN_AREA:
        return False
    point, normal = fit_plane(obj.positions, obj.indices)
    tolerance = _tolerance(obj)
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


def planar_objects(scene: Scene) -> list[tuple[Object, np.ndarray, np.ndarray]]:
    """(object, plane point, plane normal) for every `planar` object, for the mirror passes."""
    return [(obj, *plane_of(obj)) for obj in scene.objects if obj.role == "planar"]
