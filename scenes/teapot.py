"""Newell's Utah teapot: 32 bicubic Bezier patches on 306 control points, tessellated.

Data: Martin Newell's 1975 teapot (Crow, "The Origins of the Teapot", IEEE CG&A
7(1), 1987), in the widely circulated form of Steve Baker's `teaset`
(http://www.sjbaker.org/teapot/teaset.tgz, from Juhana Kouhia's teasetorig):
rim 4, body 8, handle 4, spout 4, lid 8 and bottom 4 patches. teapot.json
holds that data with indices from zero (as in M. Kilgard's OpenGL 4
tessellation examples, tessellation/teapot.cpp); four of the 306 points (the
0.002 offsets around the lid knob's axis, 204, 205, 215, 222) are not referenced
by this index table, which uses the axis point 203. Units are Newell's: the
teapot stands on z = 0 and is 3.15 high; `tessellate` turns it to Y up.
"""
from __future__ import annotations

import json
from importlib import resources

import numpy as np

_DATA = json.loads(resources.files(__package__).joinpath("teapot.json").read_text())
# 32 patches of 16 control-point indices: rim 4, body 8, handle 4, spout 4, lid 8, bottom 4
PATCHES = np.array(_DATA["patches"], dtype=np.int64)
PATCH_GROUPS = {"rim": range(0, 4), "body": range(4, 12), "handle": range(12, 16),
                "spout": range(16, 20), "lid": range(20, 28), "bottom": range(28, 32)}

VERTICES = np.array(_DATA["vertices"], dtype=np.float64)  # 306 control points, Newell's units
HEIGHT = 3.15  # top of the lid knob (vertex 203) above the base (vertex 269), Newell's units


def _bernstein(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cubic Bernstein basis B_i(t) and its derivative, each (len(t), 4)."""
    s = 1.0 - t
    b = np.stack([s ** 3, 3 * t * s ** 2, 3 * t ** 2 * s, t ** 3], axis=1)
    db = np.stack([-3 * s ** 2, 3 * s ** 2 - 6 * t * s, 6 * t * s - 3 * t ** 2, 3 * t ** 2], axis=1)
    return b, db


def evaluate_patch(ctrl: np.ndarray, u: np.ndarray, v: np.ndarray):
    """Points, d/du and d/dv on a grid: ctrl (4, 4, 3) indexed [row u][column v]."""
    bu, dbu = _bernstein(u)
    bv, dbv = _bernstein(v)
    p = np.einsum("ai,bj,ijk->abk", bu, bv, ctrl)
    pu = np.einsum("ai,bj,ijk->abk", dbu, bv, ctrl)
    pv = np.einsum("ai,bj,ijk->abk", bu, dbv, ctrl)
    return p, pu, pv


def tessellate(segments: int = 8, y_up: bool = True):
    """All 32 patches as one triangle mesh with outward normals.

    Returns (positions (N, 3), normals (N, 3), indices (M, 3), patch_of_triangle (M,)).
    Each patch is a (segments+1)^2 vertex grid; vertices on patch seams are
    merged so normals are continuous and the mesh is one connected surface
    (the rim/lid gap and the spout opening are in Newell's data and stay open).
    """
    t = np.linspace(0.0, 1.0, segments + 1)
    # Normals at the lid knob and base centre, where a row of control points
    # collapses and du x dv vanishes, come from just inside the patch instead.
    tn = t.copy()
    tn[0], tn[-1] = 1e-4, 1 - 1e-4
    n = segments + 1
    positions, normals, indices, patch_ids = [], [], [], []
    grid = np.arange(n * n).reshape(n, n)
    a, b, c, d = grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]
    # In this data du x dv points into the teapot, so wind (a, d, c) (a, c, b)
    # to make counter-clockwise = outside, and negate the cross product.
    quad = np.concatenate([np.stack([a, d, c], -1).reshape(-1, 3),
                           np.stack([a, c, b], -1).reshape(-1, 3)])
    for k, patch in enumerate(PATCHES):
        ctrl = VERTICES[patch].reshape(4, 4, 3)
        p, _, _ = evaluate_patch(ctrl, t, t)
        _, pu, pv = evaluate_patch(ctrl, tn, tn)
        nrm = -np.cross(pu, pv)
        positions.append(p.reshape(-1, 3))
        normals.append(nrm.reshape(-1, 3))
        indices.append(quad + k * n * n)
        patch_ids.append(np.full(len(quad), k))
    pos = np.concatenate(positions)
    nrm = np.concatenate(normals)
    idx = np.concatenate(indices)
    patch_of_triangle = np.concatenate(patch_ids)

    # Weld seams: positions equal to 1e-9 become one vertex; its normal is the
    # sum of the patches' unit normals (a smooth surface across the seam).
    key = np.round(pos * 1e6).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    order = np.argsort(first)  # keep vertices in first-seen order: deterministic and local
    remap = np.empty_like(order)
    remap[order] = np.arange(len(order))
    inverse = remap[inverse]
    length = np.linalg.norm(nrm, axis=1, keepdims=True)
    unit = np.divide(nrm, length, out=np.zeros_like(nrm), where=length > 0)
    welded_n = np.zeros((len(order), 3))
    np.add.at(welded_n, inverse, unit)
    welded_p = pos[first[order]]
    idx = inverse[idx]
    # Patches whose whole edge collapses to a point give zero-area triangles; drop them.
    keep = (idx[:, 0] != idx[:, 1]) & (idx[:, 1] != idx[:, 2]) & (idx[:, 2] != idx[:, 0])
    idx, patch_of_triangle = idx[keep], patch_of_triangle[keep]
    welded_n /= np.maximum(np.linalg.norm(welded_n, axis=1, keepdims=True), 1e-12)
    if y_up:  # Newell's z-up to glTF's y-up: (x, y, z) -> (x, z, -y), a proper rotation
        rot = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], float)
        welded_p = welded_p @ rot.T
        welded_n = welded_n @ rot.T
    return welded_p, welded_n, idx, patch_of_triangle
