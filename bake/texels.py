"""Light-map texels: where on which triangle each texel of each atlas page lies.

Triangles are rasterised in UV space (texel units, the convention of
`bake/unwrap.py`: texel (y, x) is the square [x, x+1] x [y, y+1], centre at
(x + 0.5, y + 0.5)). Coverage is conservative: a texel whose centre is inside a
triangle samples that point; a texel whose square only overlaps a triangle
(chart borders, thin slivers) samples the point of the triangle closest to its
centre in UV. A texel claimed by several triangles (neighbours in one chart,
along their shared edge) takes the nearest, ties to the first in (object,
triangle) order, so the result is deterministic. Nothing is offset along the
normal here: the path tracer offsets its rays.

No sample lies on a chart's border: a point closer than EDGE_INSET texel (in UV) to one of its
triangle's border edges (edges no other triangle of the page shares), which every chart-border
texel's closest point is, is moved that far towards the triangle's centroid (at most half-way). A sample exactly on an edge where the surface meets another
(a floor under a wall, a wall's foot on the floor) starts its rays on the other surface's plane,
where float32 ray casting misses it at t ~ 0 and the rays leak past it (issue 25: the bright rows at
every contact; docs/BAKE.md "Sample points").

Each texel also gets its world size (`TexelPage.size`: metres per texel on its triangle,
sqrt(world area / UV area)), the footprint bake/sample_points.py searches for a free position.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Candidate (triangle, texel) pairs handled at once: bounds the memory of the
# vectorised rasteriser (about 30 float64 temporaries per pair) to ~100 MB.
BATCH = 1 << 19
EDGE_INSET = 0.1  # texels: how far (in UV) a sample stays from its triangle's edges (module docstring)


@dataclass
class TexelPage:
    position: np.ndarray  # (H, W, 3) float32 world position of the texel sample (nan-free; 0 where empty)
    normal: np.ndarray  # (H, W, 3) float32 unit interpolated shading normal (0 where empty)
    object: np.ndarray  # (H, W) int32 object index, -1 where no triangle covers the texel
    triangle: np.ndarray  # (H, W) int32 triangle index within the object, -1 where empty
    texcoord: np.ndarray | None = None  # (H, W, 2) float32 TEXCOORD_0 at the sample (0 without uvs)
    size: np.ndarray | None = None  # (H, W) float32 metres per texel on the owning triangle (0 where empty)


def rasterize_texels(objects, atlas) -> list[TexelPage]:
    """One `TexelPage` per atlas page for `objects` (list of `glint.core.scene.Object`) and their `atlas`."""
    W, H = atlas.width, atlas.height
    # All charted triangles of the scene, in (object, triangle) order.
    tri_obj, tri_idx, tri_uv, tri_page = [], [], [], []
    for k, charts in enumerate(atlas.objects):
        uv = charts.uv.astype(np.float64)[charts.indices] * (W, H)  # (M, 3, 2) texel units
        # xatlas leaves the triangles it could not chart (zero area) at one point.
        charted = ~np.all(uv == uv[:, :1], axis=(1, 2))
        ids = np.nonzero(charted)[0]
        tri_obj.append(np.full(len(ids), k, np.int64))
        tri_idx.append(ids)
        tri_uv.append(uv[ids])
        tri_page.append(charts.page[charts.indices[ids, 0]].astype(np.int64))
    tri_obj, tri_idx = np.concatenate(tri_obj), np.concatenate(tri_idx)
    tri_uv, tri_page = np.concatenate(tri_uv), np.concatenate(tri_page)

    pages = []
    for p in range(atlas.pages):
        sel = np.nonzero(tri_page == p)[0]  # stays in (object, triangle) order
        best = np.full(H * W, np.inf)
        owner = np.full(H * W, -1, np.int64)  # index into the scene's triangle list
        bary = np.zeros((H * W, 3))
        uv = tri_uv[sel]
        border = _border_edges(uv)
        for batch in _batches(uv, W, H):
            texel, tri, dist, b = _rasterise_batch(uv, batch, W, H, border)
            # Nearest candidate per texel; stable sort keeps (object, triangle) order on ties.
            order = np.lexsort((dist, texel))
            texel, tri, dist, b = texel[order], tri[order], dist[order], b[order]
            first = np.ones(len(texel), bool)
            first[1:] = texel[1:] != texel[:-1]
            texel, tri, dist, b = texel[first], tri[first], dist[first], b[first]
            better = dist < best[texel]  # strict: earlier batches win ties
            texel = texel[better]
            best[texel] = dist[better]
            owner[texel] = sel[tri[better]]
            bary[texel] = b[better]
        pages.append(_page(objects, atlas, owner, bary, tri_obj, tri_idx, W, H))
    return pages


def _border_edges(uv: np.ndarray) -> np.ndarray:
    """(K, 3) bool: edge i of each triangle (opposite corner i) is on a chart's border, i.e. no other
    triangle of these has an edge with the same two UV end points."""
    ends = np.stack([uv[:, [1, 2]], uv[:, [2, 0]], uv[:, [0, 1]]], axis=1)  # (K, 3, 2 ends, 2)
    key = np.round(ends * 1024.0).astype(np.int64)
    key = key[..., 0] * (1 << 31) + key[..., 1]  # (K, 3, 2) one integer per end point
    key = np.sort(key, axis=2).reshape(-1, 2)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return (counts[inverse.ravel()] == 1).reshape(-1, 3)


def _batches(uv: np.ndarray, W: int, H: int):
    """Split triangles (K, 3, 2) into consecutive index ranges of at most ~BATCH candidate texels."""
    x0, x1, y0, y1 = _texel_range(uv, W, H)
    counts = (x1 - x0 + 1) * (y1 - y0 + 1)
    ends = np.cumsum(counts)
    start = 0
    while start < len(uv):
        base = ends[start - 1] if start else 0
        stop = max(int(np.searchsorted(ends, base + BATCH, side="right")), start + 1)
        yield np.arange(start, stop)
        start = stop


def _texel_range(uv: np.ndarray, W: int, H: int):
    """Inclusive range of texels whose squares overlap each triangle's UV bounding box."""
    lo, hi = uv.min(axis=1), uv.max(axis=1)
    # Texel x overlaps [lo, hi] (with positive area) for floor(lo) <= x < hi.
    x0 = np.clip(np.floor(lo[:, 0]), 0, W - 1).astype(np.int64)
    y0 = np.clip(np.floor(lo[:, 1]), 0, H - 1).astype(np.int64)
    x1 = np.clip(np.ceil(hi[:, 0]) - 1, 0, W - 1).astype(np.int64)
    y1 = np.clip(np.ceil(hi[:, 1]) - 1, 0, H - 1).astype(np.int64)
    return x0, np.maximum(x1, x0), y0, np.maximum(y1, y0)


def _rasterise_batch(uv: np.ndarray, batch: np.ndarray, W: int, H: int, border: np.ndarray):
    """Candidate texels of triangles `batch`: (texel, triangle, distance, barycentrics) of the covered ones."""
    x0, x1, y0, y1 = _texel_range(uv[batch], W, H)
    nx = x1 - x0 + 1
    counts = nx * (y1 - y0 + 1)
    tri = np.repeat(batch, counts)
    local = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    nx_r = np.repeat(nx, counts)
    x = np.repeat(x0, counts) + local % nx_r
    y = np.repeat(y0, counts) + local // nx_r
    p = np.stack([x + 0.5, y + 0.5], axis=1)

    a, b, c = uv[tri, 0], uv[tri, 1], uv[tri, 2]
    area2 = _cross(b - a, c - a)
    s = np.sign(area2)
    # Edge functions: w_a is proportional to the barycentric of a (edge b->c), etc.
    edges = ((b, c), (c, a), (a, b))
    w = np.stack([_cross(e1 - e0, p - e0) for e0, e1 in edges], axis=1)  # (n, 3)
    # Half the extent of the texel square along each edge function's gradient.
    r = np.stack([0.5 * (np.abs(e1 - e0).sum(axis=1)) for e0, e1 in edges], axis=1)
    # Separating-axis test of square vs triangle on the three edge normals (the two
    # box axes are the candidate range); a UV-degenerate triangle must straddle its lines.
    overlaps = np.where(s[:, None] != 0, s[:, None] * w + r > 0, r - np.abs(w) >= 0).all(axis=1)
    inside = (s[:, None] * w >= 0).all(axis=1) & (s != 0)

    keep = overlaps | inside
    p, a, b, c, w, area2, inside, tri = p[keep], a[keep], b[keep], c[keep], w[keep], area2[keep], inside[keep], tri[keep]
    texel = y[keep] * W + x[keep]

    bary = np.zeros((len(p), 3))
    bary[inside] = w[inside] / area2[inside, None]
    dist = np.zeros(len(p))
    out = ~inside
    if out.any():
        d, bo = _closest_on_edges(p[out], a[out], b[out], c[out])
        dist[out], bary[out] = d, bo
    return texel, tri, dist, _inset(bary, a, b, c, border[tri])


def _inset(bary, a, b, c, border):
    """Barycentrics moved towards the centroid until the UV point is EDGE_INSET from every `border`
    edge (at most half-way: slivers thinner than that keep their middle)."""
    q = bary[:, 0:1] * a + bary[:, 1:2] * b + bary[:, 2:3] * c
    area2 = np.abs(_cross(b - a, c - a))
    lengths = np.stack([np.hypot(*(c - b).T), np.hypot(*(a - c).T), np.hypot(*(b - a).T)], axis=1)
    # distance to edge i (opposite corner i) = bary_i x 2 area / |edge i|
    edge = np.min(np.where(border, np.clip(bary, 0.0, None) * area2[:, None] / np.maximum(lengths, 1e-300), np.inf),
                  axis=1)
    centre = (a + b + c) / 3.0
    to_centre = np.hypot(*(centre - q).T)
    # moving towards the centroid by a fraction lam raises every edge distance by at least lam x the
    # centroid's smallest edge distance (2 area / 3 / longest edge)
    inner = area2 / 3.0 / np.maximum(lengths.max(axis=1), 1e-300)
    lam = np.clip((EDGE_INSET - edge) / np.maximum(inner - edge, 1e-300), 0.0, 0.5)
    lam = np.where((area2 > 0) & (to_centre > 0) & np.isfinite(edge), lam, 0.0)
    return (1.0 - lam)[:, None] * bary + (lam / 3.0)[:, None]


def _closest_on_edges(p, a, b, c):
    """Distance from p to the nearest point on triangle abc's boundary, and that point's barycentrics."""
    best = np.full(len(p), np.inf)
    bary = np.zeros((len(p), 3))
    for i, j, e0, e1 in ((0, 1, a, b), (1, 2, b, c), (2, 0, c, a)):
        d = e1 - e0
        t = np.clip(((p - e0) * d).sum(axis=1) / np.maximum((d * d).sum(axis=1), 1e-300), 0.0, 1.0)
        q = e0 + t[:, None] * d
        dist = np.hypot(*(p - q).T)
        better = dist < best
        best[better] = dist[better]
        bary[better] = 0.0
        bary[better, i] = 1.0 - t[better]
        bary[better, j] = t[better]
    return best, bary


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _page(objects, atlas, owner, bary, tri_obj, tri_idx, W, H) -> TexelPage:
    """Interpolate world positions and shading normals of the owned texels."""
    position = np.zeros((H * W, 3), np.float32)
    normal = np.zeros((H * W, 3), np.float32)
    obj_map = np.full(H * W, -1, np.int32)
    tri_map = np.full(H * W, -1, np.int32)
    texcoord = np.zeros((H * W, 2), np.float32)
    size = np.zeros(H * W, np.float32)
    covered = np.nonzero(owner >= 0)[0]
    k_of = tri_obj[owner[covered]]
    for k in np.unique(k_of):
        texels = covered[k_of == k]
        tris = tri_idx[owner[texels]]
        obj, charts = objects[k], atlas.objects[k]
        corners = charts.vmapping[charts.indices[tris]]  # (n, 3) original vertex indices
        P = np.asarray(obj.positions, np.float64)[corners]
        N = np.asarray(obj.normals, np.float64)[corners]
        bw = bary[texels][:, :, None]
        pos = (bw * P).sum(axis=1)
        nrm = (bw * N).sum(axis=1)
        length = np.linalg.norm(nrm, axis=1)
        # Opposite normals at a corner can cancel: use the face normal there.
        flat = length < 1e-6
        if flat.any():
            g = np.cross(P[flat, 1] - P[flat, 0], P[flat, 2] - P[flat, 0])
            nrm[flat] = g
            length[flat] = np.linalg.norm(g, axis=1)
        nrm /= np.maximum(length, 1e-300)[:, None]
        if obj.uvs is not None:  # for the coverage of MASK materials (bake/alpha.py)
            texcoord[texels] = (bw * np.asarray(obj.uvs, np.float64)[corners]).sum(axis=1)
        uv = charts.uv.astype(np.float64)[charts.indices[tris]] * (W, H)
        uv_area = 0.5 * np.abs(_cross(uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]))
        world_area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
        size[texels] = np.sqrt(world_area / np.maximum(uv_area, 1e-300))
        position[texels] = pos
        normal[texels] = nrm
        obj_map[texels] = k
        tri_map[texels] = tris
    return TexelPage(position=position.reshape(H, W, 3), normal=normal.reshape(H, W, 3),
                     object=obj_map.reshape(H, W), triangle=tri_map.reshape(H, W),
                     texcoord=texcoord.reshape(H, W, 2), size=size.reshape(H, W))
