"""Large reflectors split into parts, so that each part's cube map is seen from where its surface is (issue 24).

One probe stands for the light arriving anywhere on a curved or transmissive object, looked up from
its box centre (bake/cubemap.py, section 4.4.1). For a compact object that is the thesis' rule; for a
mesh whose parts spread through a building -- a wood mesh of trims and posts modelled as one object,
10 m across, as exporters write them -- the box centre can lie behind a wall, and a post in a dark
room then reflects the lit hall the probe sees (the wooden staircase: 12 blocks of 880 more than half
a stop too bright, docs/BAKE.md).

`split_large_reflectors` asks of each curved or transmissive object that its probe centre be seen
from its surface: from SAMPLES points of it (triangle centroids, taken by area, a step off the
surface on the centre's side), segments to the centre are traced through the scene's diffuse and planar objects
(the environment a probe shows; the object itself is hidden from its probe). Where more than
HIDDEN_SHARE of them are blocked, the object is cut in two at the median triangle centroid along
whichever box axis hides least of the halves' own centres, and each half is asked the same, while a
halving lowers the hidden share (the halves' shares weighted by their area below the part's: a convex object's centre, seen from all of
it, keeps it whole; a wall-mounted one whose centre lies in the wall does not gain by halving and
stays whole), no part is under MIN_PART of the object's diagonal and there are at most MAX_PARTS
parts. Each part is an Object of its own (named "NAME part k of n", `part_of` the object's
name; it keeps its material, role and sidecar options), so the bake gives it light-map charts and a
probe, shared with its neighbours where the sharing rule lets it (bake/cubemap.py `cluster`);
light-map seams between parts are stitched as between any two meshes (bake/seams.py). A part's probe
hides all its object's parts, as an object's own probe hides the object. Objects the sidecar gives a
probe of their own (`cubemap_size`, `bounding_planes`, `shared_probe = false`) are not split.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from glint.bake.cubemap import CUBEMAP_ROLES, own_probe
from glint.bake.raytrace import RayTracer
from glint.core.scene import Object, Scene

SAMPLES = 256  # surface points per part whose segment to the part's centre is traced (by area)
HIDDEN_SHARE = 0.1  # a part is halved when more of its points than this cannot see its centre ...
MAX_PARTS = 32  # ... into at most this many parts ...
MIN_PART = 1.0 / 16.0  # ... none with a box diagonal under this share of the object's
STEP = 1e-3  # of the object's box diagonal: how far off the surface a sample point starts


def split_large_reflectors(scene: Scene) -> int:
    """Replace each curved or transmissive object whose probe centre its surface does not see by its
    parts (module docstring), in place, keeping the order; returns how many objects were split."""
    candidates = {k for k, obj in enumerate(scene.objects)
                  if obj.role in CUBEMAP_ROLES and not own_probe(obj) and len(obj.indices) > 1}
    environment = [obj for obj in scene.objects if obj.role in ("diffuse", "planar")]
    if not candidates or not environment:
        return 0
    tracer = RayTracer(replace(scene, objects=environment))
    out, split = [], 0
    for k, obj in enumerate(scene.objects):
        groups = _parts(obj, tracer) if k in candidates else []
        if len(groups) <= 1:
            out.append(obj)
            continue
        split += 1
        out += [_part(obj, triangles, n + 1, len(groups)) for n, triangles in enumerate(groups)]
    scene.objects = out
    return split


def _parts(obj: Object, tracer: RayTracer) -> list[np.ndarray]:
    """The triangle indices of each part of `obj` (one part: not split)."""
    corners = obj.positions[obj.indices]  # (T, 3, 3)
    centroids = corners.mean(axis=1)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    areas = np.linalg.norm(normals, axis=1)
    whole = float(np.linalg.norm(obj.bounds[1] - obj.bounds[0]))
    step = STEP * whole

    def box(triangles):
        c = corners[triangles].reshape(-1, 3)
        return c.min(axis=0), c.max(axis=0)

    def hidden(triangles) -> float:
        """The share of the part's sample points from which its box centre is hidden."""
        lo, hi = box(triangles)
        centre = (lo + hi) / 2
        cumulative = np.cumsum(areas[triangles])
        if not cumulative[-1] > 0:
            return 0.0
        quantiles = (np.arange(SAMPLES) + 0.5) / SAMPLES * cumulative[-1]  # by area: what pixels show
        pick = triangles[np.minimum(np.searchsorted(cumulative, quantiles), len(triangles) - 1)]
        to_centre = centre - centroids[pick]
        n = normals[pick] / np.maximum(np.linalg.norm(normals[pick], axis=1, keepdims=True), 1e-300)
        side = np.where(np.einsum("ij,ij->i", n, to_centre) < 0, -1.0, 1.0)
        origins = centroids[pick] + (step * side)[:, None] * n
        direction = centre - origins
        length = np.linalg.norm(direction, axis=1)
        far = length > step
        if not far.any():
            return 0.0
        blocked = tracer.occluded(origins[far], direction[far] / length[far, None], length[far])
        return float(blocked.sum()) / len(pick)

    def halves(triangles, share):
        """The part's best halving (the lowest hidden share, weighted by area) at the median centroid
        along one of the box axes, or None (module docstring)."""
        lo, hi = box(triangles)
        if share <= HIDDEN_SHARE or len(triangles) < 2 or float(np.linalg.norm(hi - lo)) <= MIN_PART * whole:
            return None
        best, best_share = None, share
        for axis in np.argsort(lo - hi, kind="stable"):  # the longest axis first: it wins ties
            order = triangles[np.argsort(centroids[triangles, axis], kind="stable")]
            pair = [order[:len(order) // 2], order[len(order) // 2:]]
            shares = [hidden(t) for t in pair]
            weights = [float(areas[t].sum()) for t in pair]
            mean = float(np.dot(shares, weights)) / max(sum(weights), 1e-300)
            if mean < best_share:
                best, best_share = list(zip(pair, shares)), mean
        return best

    first = np.arange(len(obj.indices))
    done, todo = [], [(first, hidden(first))]
    while todo:
        triangles, share = todo.pop(0)
        pair = halves(triangles, share) if len(done) + len(todo) + 2 <= MAX_PARTS else None
        if pair is None:
            done.append(triangles)
        else:
            todo += pair
    return [np.sort(t) for t in done]


def _part(obj: Object, triangles: np.ndarray, number: int, count: int) -> Object:
    """The part of `obj` made of `triangles`: its vertices, re-indexed."""
    used, indices = np.unique(obj.indices[triangles], return_inverse=True)

    def pick(a):
        return None if a is None else a[used]

    return replace(obj, name=f"{obj.name} part {number} of {count}", positions=obj.positions[used],
                   normals=obj.normals[used], indices=indices.reshape(-1, 3).astype(obj.indices.dtype),
                   uvs=pick(obj.uvs), colors=pick(obj.colors), tangents=pick(obj.tangents), part_of=obj.name,
                   options=dict(obj.options))
