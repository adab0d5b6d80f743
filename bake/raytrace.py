"""Ray casting against the whole scene with Intel Embree (`embreex`), in batches.

All objects go into one Embree triangle mesh, in scene order: object i owns the
global triangles `tri_offset[i] : tri_offset[i + 1]` (its `indices` in order).
Every per-triangle table here (`tri_object`, `tri_material`, normals, ...) is
indexed by that global triangle id ("prim"); `bake/lights.py` uses the same ids.

Precision and ray offsets. Embree works in float32, so vertices are stored
relative to the scene's bounding-box centre. Hit positions are rebuilt in
float64 from the barycentrics as p0 + b1 (p1 - p0) + b2 (p2 - p0): a point on
the triangle's plane whatever the float32 error of the barycentrics. A new ray
then starts at `offset(p, ng, d, eps)`: p moved eps along the geometric normal,
to the side the ray leaves by; Embree's tnear is 0, so the ray's own triangle
lies at t < 0. eps is per triangle: EPS_REL x the largest |coordinate| of its
vertices relative to the centre (float32 rounds the vertices, and Embree's
plane distance, in proportion to that), e.g. 12 um on a wall 3 m from the
centre, 4 cm on a 10 km ground plane. EPS_REL is an order of magnitude above the
smallest factor that removes self-hits with grazing rays up to 10 km (docs/BAKE.md,
"Ray offsets (EPS_REL)"). Light leaks through concave corners only within eps of the edge.
A texel's own eps comes from the triangle under it, found by one short probe
ray along -n (`point_eps`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from embreex import mesh_construction, rtcore_scene

from glint.core.scene import Scene

EPS_REL = 4e-6  # ray offset per unit of vertex coordinate magnitude (see module docstring)
T_INFINITE = 1e30


@dataclass
class Hits:
    """First hits of a batch of rays (all N rays from `intersect`, misses with `prim == -1` and their
    other fields 0; only the rays that hit from `intersect_hits`).

    prim: global triangle id (int64); object: object index; triangle: triangle index within that
    object; material: material index; b1, b2: barycentrics (point = (1-b1-b2) p0 + b1 p1 + b2 p2);
    t: distance along the (unit) direction; position: (., 3) float64;
    ng: (., 3) unit geometric normal of the triangle's front (counter-clockwise) face, not flipped;
    ns: (., 3) unit interpolated vertex (shading) normal, not flipped (ng on flat triangles);
    front: True where the ray hit the front face (dot(d, ng) < 0);
    eps: the triangle's ray offset (see the module docstring).
    """

    prim: np.ndarray
    object: np.ndarray
    triangle: np.ndarray
    material: np.ndarray
    b1: np.ndarray
    b2: np.ndarray
    t: np.ndarray
    position: np.ndarray
    ng: np.ndarray
    ns: np.ndarray
    front: np.ndarray
    eps: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        return self.prim >= 0


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.sqrt(np.einsum("ij,ij->i", v, v))
    return v / np.maximum(n, 1e-30)[:, None]


class RayTracer:
    """Embree scene over all objects of `scene`; build once per process, then query in batches."""

    def __init__(self, scene: Scene):
        objs = scene.objects
        counts = [len(o.indices) for o in objs]
        vcounts = [len(o.positions) for o in objs]
        self.tri_offset = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        voff = np.concatenate([[0], np.cumsum(vcounts)]).astype(np.int64)
        self.n_triangles = int(self.tri_offset[-1])

        if objs:
            P = np.concatenate([np.asarray(o.positions, np.float64).reshape(-1, 3) for o in objs])
            N = np.concatenate([np.asarray(o.normals, np.float64).reshape(-1, 3) for o in objs])
            I = np.concatenate([np.asarray(o.indices, np.int64).reshape(-1, 3) + voff[i]
                                for i, o in enumerate(objs)])
            UV = np.concatenate([np.zeros((len(o.positions), 2)) if o.uvs is None
                                 else np.asarray(o.uvs, np.float64).reshape(-1, 2) for o in objs])
            colors = [getattr(o, "colors", None) for o in objs]
            self.has_vertex_colors = any(c is not None for c in colors)
            if self.has_vertex_colors:
                self.vertex_colors = np.concatenate([
                    np.ones((len(o.positions), 3)) if c is None else np.asarray(c, np.float64).reshape(-1, 3)
                    for o, c in zip(objs, colors)])
        else:
            P, N, I, UV = np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 2))
        if not len(I):  # keep one degenerate triangle so gathers of (never-hit) misses stay valid
            P, N, I, UV = np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3), np.int64), np.zeros((1, 2))
            counts = [0] * len(objs)
        self.vertex_positions = P
        self.vertex_normals = _unit(N) if len(N) else N
        self.vertex_uvs = UV
        if not len(objs) or not self.has_vertex_colors or len(self.vertex_colors) != len(P):
            self.has_vertex_colors = False
            self.vertex_colors = None
        self.tri_vertices = I
        self.tri_object = np.repeat(np.arange(len(objs), dtype=np.int64), counts)
        self.tri_material = np.repeat(np.array([o.material for o in objs], np.int64), counts)
        if not self.n_triangles:
            self.tri_object = self.tri_material = np.zeros(1, np.int64)

        self.tri_p0 = P[I[:, 0]]
        self.tri_e1 = P[I[:, 1]] - self.tri_p0
        self.tri_e2 = P[I[:, 2]] - self.tri_p0
        cross = np.cross(self.tri_e1, self.tri_e2)
        self.tri_area = 0.5 * np.linalg.norm(cross, axis=1)
        self.tri_ng = _unit(cross)  # zero-area triangles get a zero normal; Embree never hits them
        vn = self.vertex_normals[I]  # (T, 3, 3)
        # smooth: vertex normals differ from the face normal, so the shading normal needs interpolating
        self.tri_smooth = np.abs(vn - self.tri_ng[:, None, :]).max(axis=(1, 2)) > 1e-6
        if len(P):
            lo, hi = P.min(axis=0), P.max(axis=0)
        else:
            lo = hi = np.zeros(3)
        self.center = 0.5 * (lo + hi)
        self.diagonal = float(np.linalg.norm(hi - lo))
        self.eps_floor = 1e-9 * self.diagonal + 1e-12
        self.tri_eps = EPS_REL * np.abs(P[I] - self.center).max(axis=(1, 2)) + self.eps_floor
        # one row per triangle, gathered once per hit (one fancy-index gather beats seven)
        self._table = np.concatenate([self.tri_p0, self.tri_e1, self.tri_e2, self.tri_ng,
                                      self.tri_object[:, None], self.tri_material[:, None],
                                      self.tri_offset[self.tri_object][:, None] if self.n_triangles
                                      else np.zeros((1, 1)), self.tri_eps[:, None]], axis=1)

        self._embree = rtcore_scene.EmbreeScene()
        if self.n_triangles:
            mesh_construction.TriangleMesh(self._embree, (P - self.center).astype(np.float32),
                                           I.astype(np.int32))
        self.rays = 0  # rays traced so far (intersect + occluded), for statistics

    # -- queries -------------------------------------------------------------------------------
    def _prep(self, origins, directions, tmax):
        n = len(origins)
        o = np.ascontiguousarray(np.asarray(origins, np.float64) - self.center, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        if tmax is None:
            t = np.full(n, T_INFINITE, np.float32)
        else:
            # Embree writes the hit distance into this array: always pass a fresh copy
            t = np.array(np.broadcast_to(tmax, (n,)), dtype=np.float32)
        self.rays += n
        return o, d, t

    def intersect_raw(self, origins, directions, tmax=None):
        """First hit: (prim (N,) int64 with -1 for a miss, b1, b2, t) straight from Embree."""
        n = len(origins)
        if n == 0 or not self.n_triangles:
            z = np.zeros(n, np.float32)
            return np.full(n, -1, np.int64), z, z, np.full(n, np.inf, np.float32)
        o, d, t = self._prep(origins, directions, tmax)
        r = self._embree.run(o, d, dists=t, output=1)
        prim = r["primID"].astype(np.int64)
        prim[r["geomID"] < 0] = -1
        return prim, r["u"], r["v"], r["tfar"]

    def intersect(self, origins, directions, tmax=None) -> Hits:
        """First hits of rays o + t d, 0 < t < tmax, for all N rays; `directions` must be unit length."""
        n = len(origins)
        rows, h = self.intersect_hits(origins, directions, tmax)
        full = Hits(np.full(n, -1, np.int64), np.full(n, -1, np.int64), np.full(n, -1, np.int64),
                    np.full(n, -1, np.int64), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros((n, 3)),
                    np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n, bool), np.zeros(n))
        for name in Hits.__dataclass_fields__:
            getattr(full, name)[rows] = getattr(h, name)
        return full

    def intersect_hits(self, origins, directions, tmax=None) -> tuple[np.ndarray, Hits]:
        """(rows, hits): the indices of the rays that hit something and their hit records."""
        prim, b1, b2, t = self.intersect_raw(origins, directions, tmax)
        rows = np.flatnonzero(prim >= 0)
        if len(rows) < len(prim):
            prim, b1, b2, t = prim[rows], b1[rows], b2[rows], t[rows]
            directions = np.take(directions, rows, axis=0)
        return rows, self.hit_records(prim, b1, b2, t, directions)

    def hit_records(self, prim, b1, b2, t, directions) -> Hits:
        """Hit records of rays that hit triangles `prim` (all >= 0) at barycentrics (b1, b2)."""
        row = np.take(self._table, prim, axis=0)
        b1 = b1.astype(np.float64)
        b2 = b2.astype(np.float64)
        # p0 + b1 e1 + b2 e2 (einsum over the row's (p0, e1, e2) block: faster than strided views, docs/BAKE.md "The integrator's speed")
        position = np.einsum("ij,ijk->ik", np.stack([np.ones(len(prim)), b1, b2], axis=1),
                             row[:, :9].reshape(-1, 3, 3))
        ng = np.ascontiguousarray(row[:, 9:12])
        ns = ng.copy()
        smooth = np.flatnonzero(self.tri_smooth[prim])
        if len(smooth):
            ns[smooth] = self.shading_normal(prim[smooth], b1[smooth], b2[smooth])
        front = (directions[:, 0] * ng[:, 0] + directions[:, 1] * ng[:, 1] + directions[:, 2] * ng[:, 2]) < 0
        obj = row[:, 12].astype(np.int64)
        return Hits(prim, obj, prim - row[:, 14].astype(np.int64), row[:, 13].astype(np.int64), b1, b2,
                    t.astype(np.float64), position, ng, ns, front, row[:, 15])

    def shading_normal(self, prim, b1, b2) -> np.ndarray:
        """Interpolated unit vertex normal; the geometric normal where that degenerates."""
        v = np.take(self.tri_vertices, prim, axis=0)
        vn = self.vertex_normals
        b0 = 1.0 - b1 - b2
        n = (b0[:, None] * np.take(vn, v[:, 0], axis=0) + b1[:, None] * np.take(vn, v[:, 1], axis=0)
             + b2[:, None] * np.take(vn, v[:, 2], axis=0))
        length = np.sqrt(np.einsum("ij,ij->i", n, n))
        bad = length < 1e-6
        n = n / np.maximum(length, 1e-30)[:, None]
        if bad.any():
            n[bad] = np.take(self.tri_ng, prim[bad], axis=0)
        return n

    def colors(self, prim, b1, b2) -> np.ndarray:
        """Interpolated vertex colours (the objects' `colors`, glTF COLOR_0; 1 for objects without)."""
        if not self.has_vertex_colors:
            return np.ones((len(prim), 3))
        v = np.take(self.tri_vertices, prim, axis=0)
        c = self.vertex_colors
        b0 = 1.0 - b1 - b2
        return (b0[:, None] * np.take(c, v[:, 0], axis=0) + b1[:, None] * np.take(c, v[:, 1], axis=0)
                + b2[:, None] * np.take(c, v[:, 2], axis=0))

    def texcoords(self, prim, b1, b2) -> np.ndarray:
        """Interpolated texture coordinates (the objects' `uvs`; 0 for objects without)."""
        v = np.take(self.tri_vertices, prim, axis=0)
        uv = self.vertex_uvs
        b0 = 1.0 - b1 - b2
        return (b0[:, None] * np.take(uv, v[:, 0], axis=0) + b1[:, None] * np.take(uv, v[:, 1], axis=0)
                + b2[:, None] * np.take(uv, v[:, 2], axis=0))

    def occluded(self, origins, directions, tmax=None) -> np.ndarray:
        """(N,) bool: does anything lie on o + t d, 0 < t < tmax (any hit, cheaper than intersect)."""
        n = len(origins)
        if n == 0 or not self.n_triangles:
            return np.zeros(n, bool)
        o, d, t = self._prep(origins, directions, tmax)
        return self._embree.run(o, d, dists=t, query="OCCLUDED") != -1

    def from_behind(self, prim, directions) -> np.ndarray:
        """(N,) bool: rays along `directions` (N, 3) whose hit triangle `prim` (N,; -1: no hit) they
        meet from behind, against the normal its winding gives (whatever the material's doubleSided)."""
        prim = np.asarray(prim)
        hit = prim >= 0
        out = np.zeros(len(prim), bool)
        out[hit] = np.einsum("ij,ij->i", np.asarray(directions)[hit], self.tri_ng[prim[hit]]) > 0
        return out

    def point_eps(self, points, normals) -> np.ndarray:
        """Ray offsets for points on surfaces (texels): the eps of the triangle found by a probe ray
        from p + D n along -n (D: the offset of the scene's largest coordinates), at least the
        offset the point's own coordinates need."""
        p = np.asarray(points, np.float64)
        own = EPS_REL * np.abs(p - self.center).max(axis=1) + self.eps_floor
        if not self.n_triangles or not len(p):
            return own
        D = 4 * (EPS_REL * np.abs(self.vertex_positions - self.center).max() + self.eps_floor)
        prim, _, _, _ = self.intersect_raw(p + D * normals, -normals, np.full(len(p), 2 * D))
        return np.where(prim >= 0, np.maximum(own, self.tri_eps[np.maximum(prim, 0)]), own)

    def offset(self, points, ng, directions, eps) -> np.ndarray:
        """Ray origins: `points` moved eps along the geometric normal, to the side `directions` point to."""
        side = np.where(ng[:, 0] * directions[:, 0] + ng[:, 1] * directions[:, 1] + ng[:, 2] * directions[:, 2] < 0,
                        -eps, eps)
        return points + side[:, None] * ng
