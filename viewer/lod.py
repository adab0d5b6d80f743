"""Levels of detail: simplified copies of a mesh, for renders whose pixels are larger than its
triangles.

The bake's cube-map probes (glint/cubemap_stage.py) render the whole scene six times per probe on
faces of 32 texels or so. On a software renderer the cost is the triangles, and most of an
architectural scene's triangles (a staircase's turned balusters, a plant's leaves) are far smaller
than a texel seen from a probe a few metres away. A renderer made with `lod=True` keeps, for every
object of at least `LOD_MIN_TRIANGLES`, up to `LOD_LEVELS` coarser versions, each with about half
the triangles of the one before; shaders/cull.comp picks per object and view the coarsest level
that still has `triangles_per_pixel` triangles for each pixel of the disc its bounding sphere
covers (viewer/draw_list.py `DrawList.cull`), so a probe draws near objects whole and far ones
coarse.

Simplification: quadric edge collapses (Garland and Heckbert 1997) by `fast_simplification`, the
library made for it; it moves each kept vertex to its quadric's optimum and refuses collapses
that would flip a triangle. Each vertex of a level is one of the mesh's vertices (`source`), moved:
its other attributes (light-map and texture coordinates, normal, tangent, colour, object id) are
that vertex's. Seams (vertices split by their light-map or texture coordinates) are open borders to
the simplifier; their sides may move apart by about the collapsed edges' length, which a level is
picked to keep under a pixel.
"""
from __future__ import annotations

import numpy as np

LOD_LEVELS = 4          # coarser versions per object, each about half the triangles of the one before
LOD_MIN_TRIANGLES = 64  # objects with fewer keep only their own mesh
LOD_MIN_KEPT = 0.75     # a level is kept only if it has at most this fraction of the one before


def simplified(positions: np.ndarray, indices: np.ndarray, target: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """About `target` triangles from the (M, 3) `indices` over `positions`: (source: the vertex of
    `positions` each new vertex comes from, (V', 3) their moved positions, (M', 3) triangles over them)."""
    import fast_simplification  # only renders with levels of detail need it

    points, triangles, collapses = fast_simplification.simplify(
        np.asarray(positions, np.float64), np.asarray(indices, np.int64), target_count=int(target),
        return_collapses=True)
    # fast_simplification keeps the surviving vertices in their order: vertex i1 of each collapse
    # (i0, i1) went into i0; the output's vertices are the survivors of the triangles, sorted.
    kept = np.arange(len(positions))
    if len(collapses):
        kept[collapses[:, 1]] = collapses[:, 0]
        while True:  # follow chains (i1 -> i0, later i0 -> j) to the survivor
            nxt = kept[kept]
            if np.array_equal(nxt, kept):
                break
            kept = nxt
    t = kept[np.asarray(indices, np.int64)]
    t = t[(t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])]
    source = np.unique(t)
    if len(source) != len(points):  # the library's documented output changed: fail loudly, not garble
        raise RuntimeError(f"fast_simplification returned {len(points)} vertices for {len(source)} survivors")
    return source, points.astype(np.float32), np.asarray(triangles, np.uint32).reshape(-1, 3)


def levels(positions: np.ndarray, indices: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The coarser versions of a mesh, finest first, each the one before halved (`LOD_LEVELS` at
    most; none for meshes under LOD_MIN_TRIANGLES; a level that does not shrink by LOD_MIN_KEPT
    ends the list): (source: the vertex of `positions` each of its vertices comes from, positions,
    triangles)."""
    out: list = []
    source, points, current = np.arange(len(positions)), np.asarray(positions), np.asarray(indices).reshape(-1, 3)
    while len(out) < LOD_LEVELS and len(current) >= LOD_MIN_TRIANGLES:
        kept, points_k, coarser = simplified(points, current, len(current) // 2)
        if len(coarser) == 0 or len(coarser) > LOD_MIN_KEPT * len(current):
            break
        source, points, current = source[kept], points_k, coarser
        out.append((source, points, current))
    return out
