"""Walking never passes through a surface: the walker is a sphere of RADIUS around the eye.

Without it, a step into a wall put the near plane behind the wall's (single-sided, culled) back
face: the frame showed the outside of the room, black. `Collider.move(eye, target)` is what
viewer/controls.py WalkControls calls for each walking step: the step is cut where the eye would
come closer than RADIUS to a triangle, and what is left of it slides along that triangle's plane
(a walk at an angle into a wall goes on along it), checked again. Only walking is checked;
cameras of the scene, paths and tours go where they say.

The triangles are the bake's meshes (core/bake_dir.py, world space), on the CPU: each step tests
the triangles whose bounding boxes the step's box (grown by RADIUS) meets, with the Moller-Trumbore
segment test on the triangle pushed out by RADIUS along its normal (towards the walker): exact
against a face; a face's edges are not rounded, so past the free edge of a lone panel (a door
leaf, a table top) the walker can come closer than RADIUS, and a step longer than RADIUS at a
grazing angle could slip past such an edge (walking steps are centimetres: speed x frame time).

    collider = Collider.of_meshes(bake.meshes)
    controls.collide = collider.move
"""
from __future__ import annotations

import numpy as np

RADIUS = 0.2  # m: the walker's reach around the eye (well beyond any near plane's corners, znear 0.01 m)
SLIDES = 2  # a step cut at one surface slides along it, at most this many times (a corner: two walls)


class Collider:
    def __init__(self, triangles: np.ndarray, radius: float = RADIUS):
        """triangles: (T, 3, 3) world-space corners."""
        tri = np.asarray(triangles, np.float64).reshape(-1, 3, 3)
        e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        normal = np.cross(e1, e2)
        length = np.linalg.norm(normal, axis=1)
        keep = length > 1e-12  # degenerate triangles stop nothing
        self.tri, self.normal = tri[keep], normal[keep] / length[keep, None]
        self.radius = float(radius)
        self.lo = self.tri.min(axis=1) - self.radius
        self.hi = self.tri.max(axis=1) + self.radius

    @classmethod
    def of_meshes(cls, meshes: list[dict], radius: float = RADIUS) -> "Collider":
        """From the bake's meshes (`Bake.meshes`: positions and indices per object, world space)."""
        parts = [np.asarray(m["positions"], np.float64)[np.asarray(m["indices"], np.int64).reshape(-1, 3)]
                 for m in meshes if m.get("positions") is not None and m.get("indices") is not None]
        return cls(np.concatenate(parts) if parts else np.zeros((0, 3, 3)), radius)

    def first_hit(self, start: np.ndarray, end: np.ndarray) -> tuple[float, np.ndarray] | None:
        """(fraction of the segment start -> end, the surface's normal facing start) where the
        segment first comes within the radius of a triangle's face; None when it never does."""
        d = end - start
        box_lo, box_hi = np.minimum(start, end), np.maximum(start, end)
        near = np.nonzero(np.all((self.lo <= box_hi) & (self.hi >= box_lo), axis=1))[0]
        if len(near) == 0:
            return None
        tri, n = self.tri[near], self.normal[near]
        side = np.sign(np.einsum("ij,ij->i", start - tri[:, 0], n))  # which side the walker is on
        side[side == 0] = 1.0
        n = n * side[:, None]  # facing the walker
        shifted = tri + (n * self.radius)[:, None, :]  # the face moved out towards the walker
        e1, e2 = shifted[:, 1] - shifted[:, 0], shifted[:, 2] - shifted[:, 0]
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = start - shifted[:, 0]
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = np.einsum("j,ij->i", d, q) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        towards = np.einsum("j,ij->i", d, n) < 0  # only moving into a face stops the walker
        hit = ok & towards & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= -1e-9) & (t <= 1)
        if not hit.any():
            return None
        k = np.nonzero(hit)[0][np.argmin(t[hit])]
        return max(float(t[k]), 0.0), n[k]

    def move(self, eye, target) -> np.ndarray:
        """Where a walking step from `eye` towards `target` ends (module docstring)."""
        start, end = np.asarray(eye, np.float64), np.asarray(target, np.float64)
        for _ in range(SLIDES + 1):
            hit = self.first_hit(start, end)
            if hit is None:
                return end
            t, n = hit
            stop = start + (end - start) * t
            rest = end - stop
            end = stop + rest - np.dot(rest, n) * n  # slide: what is left, along the surface
            start = stop
        return start
