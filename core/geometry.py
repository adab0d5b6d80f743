"""Triangle-set geometry that the bake and the renderer both use: face normals, planes.

The planar tolerances are those of the `planar` role (glint.bake.roles): flat means every
vertex within max(`PLANAR_DISTANCE`, `PLANAR_RELATIVE` x the bounding-box diagonal) of the
best-fit plane and every face normal within `PLANAR_ANGLE_DEG` of its normal.
"""
from __future__ import annotations

import numpy as np

from glint.core.errors import GlintError
from glint.core.scene import Object

PLANAR_DISTANCE = 1e-3  # m, absolute floor of the flatness tolerance
PLANAR_RELATIVE = 1e-3  # times the bounding-box diagonal
PLANAR_ANGLE_DEG = 2.0


def face_cross(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(M, 3) cross products of triangle edges: direction = face normal, length = 2 * area."""
    p = positions[indices]
    return np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])


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


def oriented_box(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A tight box around points -> (centre (3,), axes (3, 3) unit rows, half extents (3,)): the
    box along the points' principal axes, or the axis-aligned one where that is smaller (a cube's
    principal axes are arbitrary). A turned pane gets its own flat box, not a fat axis-aligned one."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    if len(p) == 0:
        return np.zeros(3), np.eye(3), np.zeros(3)
    boxes = [np.eye(3)]
    if len(p) > 3:
        _, vectors = np.linalg.eigh(np.cov((p - p.mean(axis=0)).T))
        boxes.append(vectors.T)
    best = None
    for axes in boxes:
        q = p @ axes.T
        lo, hi = q.min(axis=0), q.max(axis=0)
        if best is None or np.prod(hi - lo) < np.prod(best[2] * 2) * (1 - 1e-6):
            best = (((lo + hi) / 2) @ axes, axes, (hi - lo) / 2)
    return best


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
    tolerance = flatness_tolerance(obj)
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


def flatness_tolerance(obj: Object) -> float:
    lo, hi = obj.bounds
    return max(PLANAR_DISTANCE, PLANAR_RELATIVE * float(np.linalg.norm(hi - lo)))
