"""The mirrored camera of a planar reflector (section 4.5.1) and clipping at its plane.

Conventions are `viewer/camera.py`'s: world metres, Y up, right-handed; numpy
(4, 4) matrices on column vectors; OpenGL clip space (depth in [-1, 1]). Maths in
float64, matrices handed out as float32 like `ViewCamera`'s.

The mirror pass
---------------
For a plane with point p and unit normal n, the reflection about it is the
affine map

    R = [ I - 2 n n^T   2 (p.n) n ]
        [ 0             1         ]

(an involution, det -1, fixing every point of the plane). The mirror buffer is
rendered with the *mirrored view matrix* `V @ R` (V the real camera's view
matrix): a scene point X lands where the real camera would see its mirror image
R X. Two consequences the renderer relies on:

* The mirror buffer is pixel-aligned with the main view for points of the plane
  (R P = P), so the lobe centre of a reflector pixel reads the mirror buffer at
  that same pixel (given equal resolutions) -- no flip, unlike a camera built
  with `look_at` from the mirrored eye (the thesis' Fig. 4.26 "flipped vertical
  axis"; `MirrorCamera.as_view_camera()` is that camera, and
  `view_matrix() == diag(-1, 1, 1, 1) @ as_view_camera().view_matrix()`).
* `V @ R` has determinant -1: it flips handedness, so counter-clockwise front
  faces come out clockwise. While rasterising the mirror pass set
  `ctx.front_face = MirrorCamera.front_face` ("cw"), or cull the other face
  (`MirrorCamera.flip_winding` is True).

World-space positions and normals written by the mirror pass are those of the
*unmirrored* scene (model matrix only, no R): `bench/mirror_projection.py`
intersects rays from the real reflector with them.

Clipping at the plane
---------------------
Geometry on the far side of the plane (below a mirror floor) sits between the
mirrored eye and the mirror and must not be drawn. Two ways, both provided:

1. `clip_plane()`: a world-space plane equation (a, b, c, d) with the eye's side
   positive; the vertex shader writes
   `gl_ClipDistance[0] = dot(clip_plane, vec4(world_pos, 1.0))` and the renderer
   enables `GL_CLIP_DISTANCE0`. Exact, leaves the projection (and hence depth
   precision and the far plane) untouched, works at any eye height; costs one
   vertex output, every program of the pass must write it, and the
   enable/disable state must bracket the pass.
2. `oblique_projection_matrix(aspect)`: Eric Lengyel's oblique near plane
   ("Modifying the Projection Matrix to Perform Oblique Near-Plane Clipping",
   2005): row 3 of the projection is replaced so the near plane *is* the mirror
   plane. Free (no shader change, no GL state), but the far plane tilts and
   depth precision degrades, badly so when the plane passes close to the eye
   (a camera at floor height: the near plane nearly contains the eye, and the
   construction is undefined at height 0). Clip x, y and w are unchanged, so
   screen positions are identical; only depth differs.

Recommendation for the renderer (OpenGL 4.3 core, shaders are ours): use
`gl_ClipDistance`; keep the oblique matrix for programs that cannot be changed
or as a fallback. Either way the reflector itself must be left out of its own
pass (it lies on the clip plane).

Grouping
--------
`group_coplanar` merges reflectors whose planes agree within an angle and an
offset tolerance: they share one mirror pass (e.g. a floor split into tiles).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Hashable, Sequence

import numpy as np

from glint.viewer.camera import ViewCamera

GROUP_ANGLE_DEG = 0.5  # planes closer than this in normal direction ...
GROUP_OFFSET = 5e-3  # ... and this in offset (m) share one mirror pass
MIN_EYE_HEIGHT = 1e-6  # m: an eye closer to the plane sees it edge-on (no pass)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, np.float64).reshape(3)
    n = float(np.linalg.norm(v))
    if not (np.isfinite(n) and n > 1e-12):
        raise ValueError(f"plane normal {v} has no direction")
    return v / n


def reflection_matrix(point, normal) -> np.ndarray:
    """The (4, 4) float64 reflection about the plane through `point` with normal `normal`:
    I - 2 n n^T with translation 2 (p.n) n."""
    n = _unit(normal)
    p = np.asarray(point, np.float64).reshape(3)
    m = np.eye(4)
    m[:3, :3] -= 2.0 * np.outer(n, n)
    m[:3, 3] = 2.0 * float(p @ n) * n
    return m


def plane_equation(point, normal) -> np.ndarray:
    """(a, b, c, d) float64 with (a, b, c) the unit normal and a x + b y + c z + d = 0 on the plane."""
    n = _unit(normal)
    return np.array([*n, -float(np.asarray(point, np.float64).reshape(3) @ n)])


def signed_distance(point, normal, x) -> np.ndarray:
    """Signed distance of points x (..., 3) from the plane, positive on the normal's side."""
    n = _unit(normal)
    return (np.asarray(x, np.float64) - np.asarray(point, np.float64).reshape(3)) @ n


def oblique_projection(projection: np.ndarray, clip_plane_eye: np.ndarray) -> np.ndarray:
    """Lengyel's oblique near plane: `projection` (an OpenGL perspective matrix, (4, 4))
    with row 3 replaced so the near plane becomes `clip_plane_eye` (a, b, c, d in
    eye space, kept side positive, the eye (origin) on the negative side: d < 0).

    Returns float64. Points with dot(clip_plane_eye, v) < 0 get z_clip < -w_clip;
    x, y and w in clip space are unchanged. The far plane passes through the
    original frustum's far corner q farthest along the plane's positive side.
    """
    m = np.asarray(projection, np.float64).copy()
    c = np.asarray(clip_plane_eye, np.float64).reshape(4)
    if not c[3] < 0:
        raise ValueError("oblique near plane: the eye must lie strictly on the clipped side (d < 0)")
    # The frustum corner opposite the plane: clip (sgn cx', sgn cy', 1, 1) back in eye space.
    c_clip = np.linalg.inv(m).T @ c
    q = np.linalg.solve(m, np.array([math.copysign(1.0, c_clip[0]), math.copysign(1.0, c_clip[1]), 1.0, 1.0]))
    cq = float(c @ q)
    if not cq > 0:
        # The whole far face is on the clipped side: nothing of the frustum survives
        # except near the eye; keep the orientation (clipped side negative) and scale
        # so the far plane sits at the plane's distance scale. Degenerate, documented.
        cq = abs(cq) if abs(cq) > 1e-12 else 1.0
    scaled = c * (2.0 / cq)
    m[2, :] = scaled - m[3, :]
    return m


@dataclass
class MirrorCamera:
    """The real camera mirrored about a reflector plane (section 4.5.1).

    `point`, `normal`: the plane, the normal oriented towards the real eye (the
    kept side). `eye`, `forward`, `up`: the real camera's, mirrored. See the
    module docstring for the matrices, winding and clipping.
    """

    camera: ViewCamera
    point: np.ndarray
    normal: np.ndarray
    reflection: np.ndarray = field(init=False)
    eye: np.ndarray = field(init=False)
    forward: np.ndarray = field(init=False)
    up: np.ndarray = field(init=False)
    flip_winding: bool = field(init=False, default=True)
    front_face: str = field(init=False, default="cw")

    def __post_init__(self):
        self.point = np.asarray(self.point, np.float64).reshape(3)
        n = _unit(self.normal)
        h = float((self.camera.eye - self.point) @ n)
        if abs(h) < MIN_EYE_HEIGHT:
            raise ValueError(f"the eye is {h:.3g} m from the mirror plane: it sees it edge-on")
        self.normal = n if h > 0 else -n  # towards the eye
        self.reflection = reflection_matrix(self.point, self.normal)
        lin = self.reflection[:3, :3]
        self.eye = (self.reflection @ np.append(self.camera.eye, 1.0))[:3]
        self.forward = lin @ self.camera.forward
        self.up = lin @ self.camera.up
        # det(V R) = -1 always: the winding flips.
        self.flip_winding, self.front_face = True, "cw"

    @classmethod
    def about(cls, camera: ViewCamera, point, normal) -> "MirrorCamera":
        return cls(camera=camera, point=point, normal=normal)

    @property
    def eye_height(self) -> float:
        """Distance of the real eye from the plane (> 0)."""
        return float((self.camera.eye - self.point) @ self.normal)

    # -- matrices --------------------------------------------------------------------------------
    def view_matrix64(self) -> np.ndarray:
        return self.camera.view_matrix().astype(np.float64) @ self.reflection

    def view_matrix(self) -> np.ndarray:
        """World -> mirrored eye space: `V @ R` (det -1: flip the winding)."""
        return self.view_matrix64().astype(np.float32)

    def projection_matrix(self, aspect: float) -> np.ndarray:
        """The real camera's projection (use with `clip_plane()`)."""
        return self.camera.projection_matrix(aspect)

    def clip_plane(self, bias: float = 0.0) -> np.ndarray:
        """World-space (a, b, c, d), float32, positive on the eye's side, for
        `gl_ClipDistance[0] = dot(plane, vec4(world_pos, 1))`. `bias` (m) moves the
        plane towards the eye (> 0) or behind the mirror (< 0)."""
        e = plane_equation(self.point, self.normal)
        e[3] -= bias
        return e.astype(np.float32)

    def clip_plane_eye(self, bias: float = 0.0) -> np.ndarray:
        """`clip_plane` in mirrored eye space (float64): e_eye = (V R)^-T e_world."""
        e = plane_equation(self.point, self.normal)
        e[3] -= bias
        return np.linalg.inv(self.view_matrix64()).T @ e

    def oblique_projection_matrix(self, aspect: float, bias: float = 0.0) -> np.ndarray:
        """The real camera's projection with the mirror plane as its near plane (Lengyel 2005), float32."""
        return oblique_projection(self.camera.projection_matrix(aspect), self.clip_plane_eye(bias)).astype(np.float32)

    def view_projection(self, aspect: float, *, oblique: bool = False) -> np.ndarray:
        """Projection @ V @ R, float32 -- what `bench/mirror_projection.py` projects with
        (the oblique variant differs only in depth)."""
        proj = (self.oblique_projection_matrix(aspect) if oblique else self.projection_matrix(aspect))
        return (proj.astype(np.float64) @ self.view_matrix64()).astype(np.float32)

    def as_view_camera(self) -> ViewCamera:
        """A proper (right-handed) camera at the mirrored eye with mirrored forward and up.
        Its image is the mirror buffer flipped left-right; kept for reference and tests."""
        c = self.camera
        return ViewCamera(eye=self.eye, forward=self.forward, up=self.up, yfov=c.yfov,
                          znear=c.znear, zfar=c.zfar, name=f"{c.name} mirrored")


# -- grouping coplanar reflectors ----------------------------------------------------------------
@dataclass
class PlaneGroup:
    """Reflectors sharing one plane (within tolerance): one mirror pass.

    `point`, `normal`: the representative plane (area-weighted mean of the
    members' planes, normal oriented like the first member's); `keys`: the
    members' keys in input order of seeding.
    """

    point: np.ndarray
    normal: np.ndarray
    keys: list[Hashable]


def planes_match(p0, n0, p1, n1, *, angle_deg: float = GROUP_ANGLE_DEG, offset: float = GROUP_OFFSET) -> bool:
    """Same geometric plane within tolerance: normals (either orientation) within
    `angle_deg`, and each plane's point within `offset` of the other plane."""
    n0, n1 = _unit(n0), _unit(n1)
    if abs(float(n0 @ n1)) < math.cos(math.radians(angle_deg)):
        return False
    p0, p1 = np.asarray(p0, np.float64).reshape(3), np.asarray(p1, np.float64).reshape(3)
    return abs(float((p1 - p0) @ n0)) <= offset and abs(float((p0 - p1) @ n1)) <= offset


def group_coplanar(planes: Sequence[tuple[Hashable, Any, Any]], weights: Sequence[float] | None = None, *,
                   angle_deg: float = GROUP_ANGLE_DEG, offset: float = GROUP_OFFSET) -> list[PlaneGroup]:
    """Group (key, point, normal) planes that match (`planes_match`) into shared passes.

    Greedy and deterministic: planes are taken largest weight first (input order
    on ties; weights default to 1), each joins the first group whose seed plane it
    matches, else seeds a new group. Comparing with the seed (not any member)
    keeps a chain of slightly tilted planes from drifting into one group.
    Orientation is ignored (a plane and its flip are the same mirror).
    """
    if not planes:
        return []
    w = np.ones(len(planes)) if weights is None else np.asarray(weights, np.float64)
    order = sorted(range(len(planes)), key=lambda i: (-w[i], i))
    points = np.array([np.asarray(p, np.float64).reshape(3) for _, p, _ in planes])
    normals = np.array([_unit(n) for _, _, n in planes])
    cos_min = math.cos(math.radians(angle_deg))
    seeds: list[int] = []  # each group's seed plane
    members: list[list[int]] = []
    for i in order:  # `planes_match` against every seed at once; the first that matches takes it
        if seeds:
            sp, sn = points[seeds], normals[seeds]
            match = ((np.abs(sn @ normals[i]) >= cos_min) & (np.abs(((points[i] - sp) * sn).sum(axis=1)) <= offset)
                     & (np.abs((sp - points[i]) @ normals[i]) <= offset))
            hit = np.flatnonzero(match)
            if hit.size:
                members[int(hit[0])].append(i)
                continue
        seeds.append(i)
        members.append([i])
    groups = []
    for seed, idx in zip(seeds, members):
        sp, sn = points[seed], normals[seed]
        ww = np.maximum(w[idx], 1e-12)
        ns = normals[idx].copy()
        ns *= np.sign(ns @ sn)[:, None] + (ns @ sn == 0)[:, None]
        n = _unit((ww[:, None] * ns).sum(axis=0))
        offset_mean = float((ww * (points[idx] @ n)).sum() / ww.sum())
        # The representative point: the seed's point moved onto the mean plane.
        point = sp + (offset_mean - float(sp @ n)) * n
        groups.append(PlaneGroup(point=point, normal=n, keys=[planes[i][0] for i in idx]))
    return groups
