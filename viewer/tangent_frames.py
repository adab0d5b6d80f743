"""Tangent frames of the bake's meshes, for normal maps and anisotropic lobes (numpy only: viewer/gpu_meshes.py
stores them in the vertex buffer's `tangent`, which shaders/raster_surface.glsl reads).

The file's TANGENT where the bake has it, else MikkTSpace's from the texture coordinates (`tangents`;
vertices equal in position, normal and uv share one, so light-map seams do not split them, and a vertex
whose triangles differ in handedness is split in two). Where there are none (no texture coordinates, or
degenerate ones) the tangent is a fixed world axis projected onto the tangent plane (`axis_tangents`:
world X, or world Z where the normal is within ~25 degrees of X), so anisotropic lobes keep one
orientation across such objects.
"""
from __future__ import annotations

import numpy as np


def surface_tangents(positions, normals, uvs, indices, supplied=None):
    """The tangent frame of a mesh, for normal maps and anisotropic lobes: -> (source (K,) the
    vertex each output vertex copies, indices (M, 3) into the output vertices, tangents (K, 4):
    xyz unit, w the bitangent sign, b = w n x t as glTF defines it). The file's TANGENT where
    given (`supplied`, non-zero rows); else MikkTSpace from the uvs (`tangents`, which splits a
    vertex whose faces disagree in handedness); else a world axis (`axis_tangents`)."""
    tri = np.asarray(indices, np.int64).reshape(-1, 3)
    n = len(positions)
    if supplied is not None and np.all(np.any(np.asarray(supplied)[:, :3] != 0, axis=1)):
        source, out = np.arange(n), np.asarray(supplied, np.float32).reshape(-1, 4).copy()
    elif uvs is not None and len(tri):
        corner = tangents(positions, normals, uvs, tri)
        # one output vertex per (vertex, handedness) its corners have: usually the vertex itself
        key = tri.ravel() * 2 + (corner[..., 3].ravel() < 0)
        keys, inverse = np.unique(key, return_inverse=True)
        source, tri = keys // 2, inverse.reshape(-1, 3)
        out = np.zeros((len(keys), 4), np.float32)
        out[inverse] = corner.reshape(-1, 4)
        if supplied is not None:  # the file's tangents where it has usable ones
            given = np.asarray(supplied, np.float32)[source]
            usable = np.any(given[:, :3] != 0, axis=1)
            out[usable] = given[usable]
    else:
        source, out = np.arange(n), np.zeros((n, 4), np.float32)
    nrm = np.asarray(normals, np.float64)[source]
    none = ~np.any(out[:, :3] != 0, axis=1)  # no uvs, or degenerate ones
    out[none] = axis_tangents(nrm[none])
    return source, tri, out


def tangents(positions, normals, uvs, indices) -> np.ndarray:
    """(M, 3, 4) tangents per triangle corner by MikkTSpace's rule (Mikkelsen 2008, the
    reference mikktspace.c that Blender's glTF exporter and glTF's sample viewer use): xyz
    unit, w = +-1 with the bitangent b = w n x t. Per triangle the unit dp/du (Mikkelsen's vOs),
    at each corner projected onto the vertex normal and weighted by the corner's angle (the
    edges projected onto the normal's plane), summed over the corners of one vertex group:
    vertices equal in position, normal and uv (so light-map seams, which split vertices, do not
    split the frame), and of one handedness, the sign of the triangle's uv area (glTF's v runs
    down the image, Mikkelsen's up: w = -sign of the area in glTF's uv, as three.js's
    computeMikkTSpaceTangents(negateSign=True)). Zero where every triangle of a group is
    degenerate in uv. Differences from the reference: it also requires the faces of a group to
    be connected through the vertex (two fans of one vertex that touch only there get one frame
    here); it gives degenerate triangles their neighbours' frame (here they add nothing); and
    its per-vertex bitangent magnitudes (the 'magS/magT' outputs) are not computed."""
    tri = np.asarray(indices, np.int64).reshape(-1, 3)
    out = np.zeros((len(tri), 3, 4), np.float32)
    if not len(tri):
        return out
    pos = np.asarray(positions, np.float64)
    nrm = np.asarray(normals, np.float64)
    tex = np.asarray(uvs, np.float64)
    p, t = pos[tri], tex[tri]
    d1, d2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    t21, t31 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    area = t21[:, 0] * t31[:, 1] - t21[:, 1] * t31[:, 0]  # twice the signed uv area
    # [d1 d2] = [dp/du dp/dv] [t21 t31]: dp/du = (t31v d1 - t21v d2) / area
    os = (t31[:, 1:2] * d1 - t21[:, 1:2] * d2) * np.sign(area)[:, None]
    length = np.linalg.norm(os, axis=1, keepdims=True)
    ok = (np.abs(area) > 1e-20) & (length[:, 0] > 1e-20)
    os = np.where(ok[:, None], os / np.maximum(length, 1e-300), 0.0)
    w = np.where(area < 0, 1.0, -1.0)  # handedness in glTF's v-down uv (docstring)
    # per corner: the face tangent projected onto the vertex normal, weighted by the corner angle
    n = nrm[tri]  # (M, 3, 3)
    vs = os[:, None, :] - n * np.einsum("fcj,fj->fc", n, os)[..., None]
    vs /= np.maximum(np.linalg.norm(vs, axis=2, keepdims=True), 1e-300)
    e1 = np.roll(p, -1, axis=1) - p
    e2 = np.roll(p, 1, axis=1) - p

    def in_plane(e):
        e = e - n * np.einsum("fcj,fcj->fc", n, e)[..., None]
        return e / np.maximum(np.linalg.norm(e, axis=2, keepdims=True), 1e-300)

    angle = np.arccos(np.clip(np.einsum("fcj,fcj->fc", in_plane(e1), in_plane(e2)), -1.0, 1.0))
    contribution = vs * (angle * ok[:, None])[..., None]
    # vertex groups: equal position, normal and uv, and one handedness
    weld = np.unique(np.concatenate([pos, nrm, tex], axis=1), axis=0, return_inverse=True)[1].reshape(-1)
    group = np.unique(weld[tri] * 2 + (w[:, None] < 0), return_inverse=True)[1].reshape(-1)
    sums = np.zeros((group.max() + 1, 3))
    np.add.at(sums, group, contribution.reshape(-1, 3))
    corner = sums[group]
    length = np.linalg.norm(corner, axis=1, keepdims=True)
    good = length[:, 0] > 1e-12
    flat = out.reshape(-1, 4)
    flat[good, :3] = corner[good] / length[good]
    flat[good, 3] = np.repeat(w, 3)[good]
    return out


def axis_tangents(normals) -> np.ndarray:
    """(N, 4) tangents for vertices without texture coordinates: world X projected onto the
    tangent plane (world Z where the normal lies within ~25 degrees of X, where that projection
    gets short), bitangent sign +1; zero for zero-length normals (the shader then builds any frame)."""
    nrm = np.asarray(normals, np.float64).reshape(-1, 3)
    out = np.zeros((len(nrm), 4), np.float32)
    length = np.linalg.norm(nrm, axis=1)
    good = length > 1e-12
    n = nrm[good] / length[good, None]
    axis = np.where((np.abs(n[:, 0]) > 0.9)[:, None], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    t = axis - n * np.einsum("ij,ij->i", axis, n)[:, None]  # |t| >= sin(25 deg) by the choice of axis
    out[good, :3] = t / np.linalg.norm(t, axis=1, keepdims=True)
    out[good, 3] = 1.0
    return out
