"""Light-map seams stitched: texels on either side of a seam between charts agree (issue 25).

Where two charts meet on a continuous surface (a floor modelled as two meshes, a surface xatlas cut
into charts), each chart's border texels are path traced on their own: their noise differs, and so,
after denoising, do their values. A bilinear look-up reads one chart on one side of the seam and the
other on the other side, and the difference shows as a line: 5.8 % on average, 11 % at worst, across a
floor split into two meshes at preview (docs/BAKE.md "Seams"; 0.9 % and 2.2 % stitched), against
0.7 % between texels one apart inside a chart.

Stitching: a border texel (a path-traced texel with a neighbour that is not of its chart) takes the
weighted mean of itself and the border texels of other charts whose samples lie within STITCH_RADIUS
texels of its own and whose normals agree (dot > MIN_COS: the same surface, not a corner), weights
1 - distance / radius (1 for itself). Texels that are not path traced are then filled again from the
stitched ones (bake/dilate.py), so the look-ups either side of the seam read nearly the same values.
Both sides of a texel are stitched separately (front pages with front pages, back with back).
"""
from __future__ import annotations

from itertools import chain

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from glint.bake.raytrace import RayTracer
from glint.bake.texels import TexelPage
from glint.parallel.cpus import usable_cpus

STITCH_RADIUS = 1.0  # texel sizes
MIN_COS = 0.9
PLANE_GAP = 0.1  # of the radius: how far one sample may lie off the other's tangent plane


def _charts(page: TexelPage) -> np.ndarray:
    """(H, W) int chart label per covered texel (charts are islands of covered texels: xatlas leaves
    `padding` texels between them), 0 where empty."""
    return ndimage.label(page.object >= 0, structure=np.ones((3, 3), bool))[0]


def _border(charts: np.ndarray) -> np.ndarray:
    """(H, W) bool: texels of a chart with an 8-neighbour that is not of the same chart."""
    pad = np.pad(charts, 1, constant_values=-1)
    H, W = charts.shape
    out = np.zeros(charts.shape, bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            out |= pad[1 + dy:1 + dy + H, 1 + dx:1 + dx + W] != charts
    return out & (charts > 0)


def stitch(tracer: RayTracer, images: list[np.ndarray], baked: list[np.ndarray], pages: list[TexelPage],
           sign: float = 1.0, sides: list[np.ndarray] | None = None) -> list[np.ndarray]:
    """The pages `images` (H, W, 3) with their border texels stitched (module docstring); `tracer`: the
    scene's; `baked`: the path-traced texels; `sign`: +1 for front pages, -1 for back pages (their
    normal is -n); `sides`: per page, the texels that have this side (None: every covered texel)."""
    rows, values, points, normals, sizes, chart_ids, objects = [], [], [], [], [], [], []
    offset = 0
    for k, (image, mask, page) in enumerate(zip(images, baked, pages)):
        charts = _charts(page)
        sel = _border(charts) & mask
        if sides is not None:
            sel &= sides[k]
        ys, xs = np.nonzero(sel)
        rows.append(np.stack([np.full(len(ys), k), ys, xs], axis=1))
        values.append(image[ys, xs].astype(np.float64))
        points.append(page.position[ys, xs].astype(np.float64))
        normals.append(sign * page.normal[ys, xs].astype(np.float64))
        size = page.size[ys, xs] if page.size is not None else np.full(len(ys), np.nan)
        sizes.append(size.astype(np.float64))
        chart_ids.append(charts[ys, xs].astype(np.int64) + offset)
        objects.append(page.object[ys, xs].astype(np.int64))
        offset += int(charts.max()) + 1
    rows, values, points = np.concatenate(rows), np.concatenate(values), np.concatenate(points)
    normals, sizes, chart_ids = np.concatenate(normals), np.concatenate(sizes), np.concatenate(chart_ids)
    objects = np.concatenate(objects)
    out = [image.copy() for image in images]
    if len(points) < 2 or not np.isfinite(sizes).all():
        return out
    radius = STITCH_RADIUS * sizes
    i, j = near_pairs(points, radius)
    if not len(i):
        return out
    d = np.linalg.norm(points[i] - points[j], axis=1)
    r = np.minimum(radius[i], radius[j])
    # the same surface: normals that agree, and each sample close to the other's tangent plane (a sofa's
    # back flush against a wall and its foot 2 cm in front face the same way, but are not one surface)
    gap = np.abs(np.einsum("ij,ij->i", points[i] - points[j], normals[i] + normals[j])) / 2.0
    keep = ((chart_ids[i] != chart_ids[j]) & (d < r) & (np.einsum("ij,ij->i", normals[i], normals[j]) > MIN_COS)
            & (gap < PLANE_GAP * r))
    i, j, d, r = i[keep], j[keep], d[keep], r[keep]
    touch = _touching(tracer, points[i], points[j], normals[i] + normals[j], objects[i], objects[j])
    i, j, w = i[touch], j[touch], (1.0 - d[touch] / r[touch])
    total = values.copy()
    weight = np.ones(len(values))
    np.add.at(total, i, w[:, None] * values[j])
    np.add.at(total, j, w[:, None] * values[i])
    np.add.at(weight, i, w)
    np.add.at(weight, j, w)
    stitched = total / weight[:, None]
    for k in range(len(images)):
        sel = rows[:, 0] == k
        out[k][rows[sel, 1], rows[sel, 2]] = stitched[sel]
    return out


def near_pairs(points: np.ndarray, radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(i, j), i < j, sorted: every pair of `points` closer than both their radii, found per point
    within its own radius. One search radius for all (the largest texel's) made a scene of 10,000
    small boxes on a large floor ask for billions of pairs (std::bad_alloc)."""
    # on every CPU: the bake's workers are idle while this process stitches
    near = cKDTree(points).query_ball_point(points, radius, return_sorted=False, workers=usable_cpus())
    counts = np.fromiter(map(len, near), np.int64, len(near))
    i = np.repeat(np.arange(len(points), dtype=np.int64), counts)
    # flattened in C (chain): a generator over the staircase's 4.4 M neighbours took 1.8 s
    j = np.fromiter(chain.from_iterable(near), np.int64, int(counts.sum()))
    keep = j > i
    i, j = i[keep], j[keep]
    d = np.linalg.norm(points[i] - points[j], axis=1)
    keep = d <= radius[j]  # within both radii: j's ball holds i too
    order = np.lexsort((j[keep], i[keep]))
    return i[keep][order], j[keep][order]


def _touching(tracer: RayTracer, a, b, n, object_a, object_b) -> np.ndarray:
    """(K,) bool: the point half-way between a and b lies on object_a or object_b (a ray from it lifted
    4 eps along n, back along -n, meets one of them within 8 eps)."""
    n = n / np.maximum(np.linalg.norm(n, axis=1), 1e-30)[:, None]
    mid = 0.5 * (a + b)
    eps = tracer.point_eps(mid, n)
    prim, _, _, _ = tracer.intersect_raw(mid + 4.0 * eps[:, None] * n, -n, 8.0 * eps)
    obj = tracer.tri_object[np.maximum(prim, 0)]
    return (prim >= 0) & ((obj == object_a) | (obj == object_b))
