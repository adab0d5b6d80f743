"""Bounding planes of a cube-mapped object (section 4.4.1): the walls, floor and ceiling that its
reflected rays are intersected with before the cube-map look-up.

Architectural interiors are bounded by planes, so the viewer intersects each sample ray with a
few of them and looks the cube map up towards the nearest hit instead of along the ray (the
thesis' Fig. 4.5). The thesis leaves the choice to the user; here it is automatic, overridable
per object in the sidecar (`[objects."NAME"] bounding_planes = false` for none, or a list of
`{ point = [x, y, z], normal = [x, y, z] }`).

Candidates (`candidate_surfaces`) are the scene's large flat surfaces: every `planar` object
(its mirror plane, `glint.core.geometry.plane_of`) and every `diffuse` object whose largest coplanar
group of faces (the flatness tolerances of bake/roles.py) is at least `LARGE_AREA` and covers
at least `FLAT_FRACTION` of its area (a wall with a window reveal counts, a sofa does not).
Their material decides nothing else: a plane stands for geometry, whatever it looks like.

For one object (`choose_planes`) a candidate qualifies when
- it faces the object: the object's centre is on the side the surface's normal points to
  (a double-sided surface faces both ways), and its box lies there too, up to
  `max(ENCLOSE_MIN, ENCLOSE_RELATIVE * box diagonal)` (an object standing on the floor);
- it is over or beside the object: the centre's projection onto the plane falls on the
  surface itself, so a small table top is a plane for the teapot on it, not for a vase across
  the room.
Of parallel planes facing the same way only the nearest is kept: a ray from the object meets
it first, always, so a farther one (the floor under the teapot's table) is never the nearest
hit. The nearest plane below (normal up: the floor, or the table the object stands on) and the
nearest above (normal down: the ceiling) are always kept, the thesis' minimal enclosure; the
others fill up to `MAX_PLANES` nearest first. The result is sorted nearest first.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glint.core.geometry import PLANAR_ANGLE_DEG, face_cross, fit_plane, flatness_tolerance, plane_of
from glint.core.scene import Object, Scene

LARGE_AREA = 1.0  # m^2: a diffuse surface smaller than this is furniture, not a bounding plane
FLAT_FRACTION = 0.8  # of the object's area in its largest coplanar group
MAX_PLANES = 6  # per object: each costs a ray-plane test per sample per pixel
ENCLOSE_MIN = 0.01  # m
ENCLOSE_RELATIVE = 0.05  # times the object's bounding-box diagonal
UP = np.array([0.0, 1.0, 0.0])
UPRIGHT_COS = 0.5  # |normal . up| above this: a floor-like or ceiling-like plane


@dataclass(frozen=True)
class BoundingPlane:
    point: np.ndarray
    normal: np.ndarray  # unit, pointing to the side the object is on
    source: str | None = None  # the object whose surface it is; None when the sidecar gave it

    def to_dict(self) -> dict:
        return {"point": [float(x) + 0.0 for x in self.point],  # + 0.0: no -0.0 in the manifest
                "normal": [float(x) + 0.0 for x in self.normal], "object": self.source}


@dataclass(frozen=True)
class Surface:
    """A candidate: the plane of an object's largest flat part and that part's triangles."""
    name: str
    point: np.ndarray
    normal: np.ndarray
    triangles: np.ndarray  # (K, 3, 3) corners of the faces in the plane: its footprint
    two_sided: bool


def candidate_surfaces(scene: Scene) -> list[Surface]:
    out = []
    for obj in scene.objects:
        if obj.role not in ("planar", "diffuse") or not len(obj.indices):
            continue
        if obj.role == "diffuse" and obj.area < LARGE_AREA:
            continue
        flat = _flat_part(obj)
        if flat is None:
            continue
        point, normal, members = flat
        area = obj.triangle_areas[members].sum()
        if obj.role == "diffuse" and (area < LARGE_AREA or area < FLAT_FRACTION * obj.area):
            continue
        out.append(Surface(obj.name, point, normal, obj.positions[obj.indices[members]],
                           bool(scene.material_of(obj).double_sided)))
    return out


def choose_planes(obj: Object, surfaces: list[Surface]) -> list[BoundingPlane]:
    """The automatic bounding planes of `obj` (see the module docstring), nearest first."""
    return box_planes(*obj.bounds, surfaces)


def box_planes(lo: np.ndarray, hi: np.ndarray, surfaces: list[Surface]) -> list[BoundingPlane]:
    """The automatic bounding planes of the box lo..hi (an object's, or a shared probe's cluster of
    objects, bake/cubemap.py), nearest first."""
    centre = (lo + hi) / 2
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    slack = max(ENCLOSE_MIN, ENCLOSE_RELATIVE * float(np.linalg.norm(hi - lo)))
    found = []  # (distance from the centre, plane)
    for s in surfaces:
        normal = s.normal
        distance = float(np.dot(centre - s.point, normal))
        if distance < 0 and s.two_sided:
            normal, distance = -normal, -distance
        if distance <= 0 or np.min((corners - s.point) @ normal) < -slack:
            continue
        if not _on_footprint(centre - distance * normal, s.triangles):
            continue
        found.append((distance, BoundingPlane(np.asarray(s.point, float), np.asarray(normal, float), s.name)))
    found.sort(key=lambda item: item[0])

    parallel = np.cos(np.radians(PLANAR_ANGLE_DEG))
    kept: list[tuple[float, BoundingPlane]] = []
    for distance, plane in found:  # nearest first: a farther plane facing the same way is behind it
        if all(np.dot(plane.normal, k.normal) < parallel for _, k in kept):
            kept.append((distance, plane))
    below = next((item for item in kept if item[1].normal @ UP > UPRIGHT_COS), None)
    above = next((item for item in kept if item[1].normal @ UP < -UPRIGHT_COS), None)
    chosen = [item for item in (below, above) if item is not None]
    rest = [item for item in kept if item is not below and item is not above]
    chosen += rest[:MAX_PLANES - len(chosen)]
    return [plane for _, plane in sorted(chosen, key=lambda item: item[0])]


def override_planes(value) -> list[BoundingPlane] | None:
    """The sidecar's `bounding_planes` as checked by bake/sidecar.py: None for automatic (absent
    or true), [] for false, else its planes (normals made unit length there)."""
    if value is None or value is True:
        return None
    if value is False:
        return []
    return [BoundingPlane(np.asarray(p["point"], float), np.asarray(p["normal"], float)) for p in value]


def _flat_part(obj: Object) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(point, unit normal, face mask) of the object's largest coplanar group of faces.

    A planar object's plane is its mirror plane (`plane_of`). Elsewhere `plane_of`'s
    group-by-group search could take a pass per face of a finely tessellated sofa, so the
    group is seeded instead by an area-weighted vote over faces binned by normal (~2 degree
    bins) and offset, then grown with plane_of's tolerances and fitted with `fit_plane`."""
    cross = face_cross(obj.positions, obj.indices)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    if not np.any(area > 0):
        return None
    unit = np.divide(cross, 2 * area[:, None], out=np.zeros_like(cross), where=area[:, None] > 0)
    centre = obj.positions[obj.indices].mean(axis=1)
    tolerance = flatness_tolerance(obj)
    cos_max = np.cos(np.radians(PLANAR_ANGLE_DEG))

    def members_of(point, normal):
        return (area > 0) & (unit @ normal >= cos_max) & (np.abs((centre - point) @ normal) <= tolerance)

    if obj.role == "planar":
        point, normal = plane_of(obj)
        return point, normal, members_of(point, normal)
    offset = np.einsum("ij,ij->i", unit, centre)
    keys = np.column_stack([np.round(unit * 30.0), np.round(offset / (4 * tolerance))])
    _, bins = np.unique(keys[area > 0], axis=0, return_inverse=True)
    faces = np.flatnonzero(area > 0)
    votes = np.bincount(bins.ravel(), weights=area[faces])
    in_bin = faces[bins.ravel() == np.argmax(votes)]
    seed = in_bin[np.argmax(area[in_bin])]
    members = members_of(centre[seed], unit[seed])
    point, normal = fit_plane(obj.positions, obj.indices[members])
    return point, normal, members_of(point, normal)


def _on_footprint(p: np.ndarray, triangles: np.ndarray, eps: float = 1e-6) -> bool:
    """Whether point p (in the triangles' plane) lies on any of the triangles (barycentric test)."""
    a = triangles[:, 0]
    e1, e2, q = triangles[:, 1] - a, triangles[:, 2] - a, p - a
    d11, d12, d22 = (np.einsum("ij,ij->i", u, v) for u, v in ((e1, e1), (e1, e2), (e2, e2)))
    q1, q2 = np.einsum("ij,ij->i", q, e1), np.einsum("ij,ij->i", q, e2)
    det = d11 * d22 - d12 * d12
    ok = det > 0
    det = np.where(ok, det, 1.0)
    u = (d22 * q1 - d12 * q2) / det
    v = (d11 * q2 - d12 * q1) / det
    return bool(np.any(ok & (u >= -eps) & (v >= -eps) & (u + v <= 1 + eps)))
