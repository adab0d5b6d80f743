"""Light-map sample points moved out of the geometry that covers them (issue 25).

A texel samples one point of its surface (bake/texels.py). Where separately modelled meshes meet,
that point may lie where the surface is covered: inside a crown moulding that intersects the
ceiling, above the ceiling on the moulding's face, under a sofa's edge, behind a wall a floor runs
under. Traced from there, the texel sees the inside of the other object, or through it, the sky;
its light-map value is then wrong (dark inside, bright beyond) and bilinear filtering shows it along
the whole seam. With double-sided materials (what Blender exports by default) the back-face rule of
bake/lightmap.py no longer catches it: the back of a double-sided surface is a valid surface.

The test, per sample (point p, normal n of the side being baked, world texel size s): PROBES short
rays from p lifted eps along n, in the tangent plane, as long as half the texel's diagonal
(r = s / sqrt 2: the footprint). A probe that hits the back of a surface (the side its winding
faces away from; winding, not the material's doubleSided, says which side of a closed mesh is its
inside) at t < r is evidence that p is covered, but only when p's own surface goes on past the hit:
a point lifted eps from a ray's end just beyond it (t + margin) and probed along -n finds p's own
object. Otherwise the other surface meets p's surface at an edge (a room's corner, whose walls may
face outwards in exports) and p is where it should be. This is Bakery's "adjust sample positions"
and the push-off of Unity's progressive lightmapper, with the continuation test in place of their
back-face tolerance, which double-sided exports defeat.

Curved surfaces. On the concave side of a faceted curve (a handrail's profile, the inside of a
bowl) a probe longer than a facet meets the next facets of the sample's own surface from behind,
and that surface goes on past them: the surface curving, not covering. So the continuation test
looks past the triangle the probe crossed: the crossed facet itself is not the surface going on,
while a moulding's face that crosses the ceiling at a shallow angle still has the ceiling beyond it.

A covered sample moves along the probe that found the nearest such hit, to the middle of the free
part of its footprint on that line ((t + r) / 2), provided the new point is on its own object and
no probe from it hits a back face within r / 2, and it is not in a slot (two opposite probes meet
surfaces, of any side, less than SLOT x the texel size apart in all); else along the next probe. The
slot rule keeps a sample from being moved past a plate into a narrow gap behind it: on the wooden
staircase a post's fin, modelled as one sheet facing a wall 1 cm away, took the samples of the
post's lit face into that gap (black where the reference is lit). A covered sample with
no such position is invalid: bake/lightmap.py fills it from its neighbours on the same object.

Cut-outs. With the scene's alpha coverage (`coverage`, bake/alpha.py) every probe passes the
missing parts of MASK and BLEND materials as the bake's own rays do (BLEND where 1 - alpha > 1/2,
deterministically): a leaf card or a fence whose texels are cut out covers nothing there, where an
opaque probe moved or dropped the samples of the floor it stands in.

Enclosed samples (`enclosed`). A sample whose every direction meets a surface within ENCLOSED_REACH
texel sizes (half a metre at preview), most of them from the front, lies in a cavity: under a sofa,
behind the books on a shelf. Its light comes in through the cavity's openings, by paths that few of
its first paths find, each with a large weight: where a firefly is likeliest (all four of
living-room's were in such cavities). bake/lightmap.py gives such texels
more paths. The test is a fixed set of ENCLOSED_PROBES cosine-distributed rays around n, a function of
the geometry alone: the number of paths a texel gets does not depend on its own paths, so its estimate
stays unbiased.

Slivers. A sample that faces another surface closer than SLIVER x its texel size (a probe along n
hits anything, front or back, within it) lies in a gap far narrower than its footprint: the back of
a skirting board 1 mm off the wall, a book's side against the next. Its light comes through the gap's
mouth, a sliver of its hemisphere that few of its paths find, each with a large weight: the texel is a
firefly (measured: 2 x its converged value at 128 paths, docs/BAKE.md "Fireflies"), and no one sees
it but at grazing angles. Such a sample is invalid too, filled from its neighbours.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glint.bake.alpha import Coverage
from glint.bake.irradiance import R2_STEP
from glint.bake.raytrace import RayTracer
from glint.bake.scatter import frame

PROBES = 8  # tangent directions, 45 degrees apart
MIN_MARGIN_EPS = 4.0  # a moved point lies at least this many ray offsets beyond the surface it crossed
BATCH = 1 << 16  # samples probed at once: bounds memory (8 probes each)
SLIVER = 0.1  # texel sizes: a sample facing a surface closer than this is in a sliver (module docstring)
SLOT = 0.25  # texel sizes: a moved sample between two surfaces closer than this is in a slot (module docstring)
# A sample is enclosed when each of ENCLOSED_PROBES rays meets a surface within ENCLOSED_REACH texel sizes
# (half a metre at preview's 16 texels per metre; in texels, so that a scene scaled with its texel
# density bakes the same): a floor under a sofa, a book's end in a shelf (module docstring, "Enclosed samples").
ENCLOSED_PROBES = 16
ENCLOSED_REACH = 8.0


@dataclass
class SampleAdjustment:
    points: np.ndarray  # (K, 3) float64 sample points, moved where covered
    moved: np.ndarray  # (K,) bool: moved to a free position
    invalid: np.ndarray  # (K,) bool: covered with no free position within the texel's footprint, or in a sliver
    sliver: np.ndarray | None = None  # (K,) bool: of `invalid`, in a sliver


def _directions(n: np.ndarray) -> np.ndarray:
    """(K, PROBES, 3) unit tangent directions around each unit normal."""
    t, b = frame(n)
    angle = 2.0 * np.pi * np.arange(PROBES) / PROBES
    return np.cos(angle)[None, :, None] * t[:, None, :] + np.sin(angle)[None, :, None] * b[:, None, :]


def _first_hits(tracer: RayTracer, coverage: Coverage | None, origins, dirs, reach):
    """(prim (N,), t (N,)): the first surface along each ray up to reach (prim -1: none), through
    cut-out parts where `coverage` is given (module docstring, "Cut-outs")."""
    if coverage is None or not coverage.any:
        prim, _, _, t = tracer.intersect_raw(origins, dirs, reach)
        return prim, t
    rows, h = coverage.intersect_hits(origins, dirs, reach)
    prim, t = np.full(len(origins), -1, np.int64), np.full(len(origins), np.inf)
    prim[rows], t[rows] = h.prim, h.t
    return prim, t


def _probe(tracer: RayTracer, coverage: Coverage | None, origins: np.ndarray, dirs: np.ndarray, reach: np.ndarray):
    """Probes from origins (K, 3) along dirs (K, P, 3) up to reach (K,): (K, P) each the triangle hit
    (-1: none), its distance (inf: none) and whether the probe meets it from behind."""
    K, P = dirs.shape[:2]
    d = dirs.reshape(-1, 3)
    prim, t = _first_hits(tracer, coverage, np.repeat(origins, P, axis=0), d, np.repeat(reach, P))
    t = np.where(prim >= 0, t.astype(np.float64), np.inf)
    return prim.reshape(K, P), t.reshape(K, P), tracer.from_behind(prim, d).reshape(K, P)


def _back_hits(tracer: RayTracer, coverage: Coverage | None, origins: np.ndarray, dirs: np.ndarray,
               reach: np.ndarray):
    """`_probe`'s distance to the first hit when it is a back face, inf otherwise; and the triangle hit."""
    prim, t, behind = _probe(tracer, coverage, origins, dirs, reach)
    return np.where(behind, t, np.inf), prim


def _in_slot(tracer: RayTracer, coverage: Coverage | None, origins: np.ndarray, dirs: np.ndarray,
             width: np.ndarray) -> np.ndarray:
    """(K,) bool: some pair of opposite probes (dirs (K, PROBES, 3), the second half opposite the
    first) meets surfaces, front or back, less than `width` (K,) apart in all."""
    _, t, _ = _probe(tracer, coverage, origins, dirs, width)
    P = t.shape[1]
    return (t[:, :P // 2] + t[:, P // 2:] < width[:, None]).any(axis=1)


def _on_surface(tracer: RayTracer, coverage: Coverage | None, points: np.ndarray, normals: np.ndarray,
                objects: np.ndarray, lift: np.ndarray, skip: np.ndarray | None = None) -> np.ndarray:
    """(K,) bool: a ray from each point lifted 4 lift along n, back along -n, meets its own object
    within 8 lift (not where that object is cut out). `skip` (K,): a triangle per point the ray passes
    through (module docstring, "Curved surfaces")."""
    origins = points + 4.0 * lift[:, None] * normals
    reach = 8.0 * lift
    prim, t = _first_hits(tracer, coverage, origins, -normals, reach)
    if skip is not None:
        again = np.flatnonzero((prim >= 0) & (prim == skip))
        if len(again):
            # on past the skipped triangle: a quarter lift beyond it, well above float32's rounding there
            step = t[again] + 0.25 * lift[again]
            prim[again], _ = _first_hits(tracer, coverage, origins[again] - step[:, None] * normals[again],
                                         -normals[again], np.maximum(reach[again] - step, 0.0))
            prim[again[prim[again] == skip[again]]] = -1
    return (prim >= 0) & (tracer.tri_object[np.maximum(prim, 0)] == objects)


def adjust_samples(tracer: RayTracer, points, normals, sizes, objects,
                   coverage: Coverage | None = None) -> SampleAdjustment:
    """Sample points (K, 3) of texels of `objects` (K,) with unit normals (K, 3) of the baked side and
    world texel sizes (K,) moved out of covering geometry (module docstring); in batches of BATCH.
    `coverage`: the scene's alpha coverage, whose cut-out parts cover nothing."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    n = np.asarray(normals, np.float64).reshape(-1, 3)
    sizes = np.asarray(sizes, np.float64).reshape(-1)
    objects = np.asarray(objects, np.int64).reshape(-1)
    parts = [_adjust(tracer, coverage, p[i:i + BATCH], n[i:i + BATCH], sizes[i:i + BATCH], objects[i:i + BATCH])
             for i in range(0, len(p), BATCH)] or [_adjust(tracer, coverage, p, n, sizes, objects)]
    return SampleAdjustment(*(np.concatenate([getattr(a, f) for a in parts])
                              for f in ("points", "moved", "invalid", "sliver")))


def _adjust(tracer: RayTracer, coverage: Coverage | None, points, normals, sizes, objects) -> SampleAdjustment:
    p = np.asarray(points, np.float64).reshape(-1, 3)
    n = np.asarray(normals, np.float64).reshape(-1, 3)
    objects = np.asarray(objects, np.int64)
    K = len(p)
    moved, invalid = np.zeros(K, bool), np.zeros(K, bool)
    if K == 0:
        return SampleAdjustment(p.copy(), moved, invalid, invalid.copy())
    r = np.asarray(sizes, np.float64) / np.sqrt(2.0)
    lift = tracer.point_eps(p, n)
    dirs = _directions(n)
    t, crossed = _back_hits(tracer, coverage, p + lift[:, None] * n, dirs, r)

    # covered: some back-face hit beyond which the own surface goes on
    k, j = np.nonzero(np.isfinite(t))
    beyond = p[k] + dirs[k, j] * (t[k, j] + MIN_MARGIN_EPS * lift[k])[:, None]
    goes_on = _on_surface(tracer, coverage, beyond, n[k], objects[k], lift[k], skip=crossed[k, j])
    covered_pairs = np.zeros(t.shape, bool)
    covered_pairs[k[goes_on], j[goes_on]] = True
    covered = np.flatnonzero(covered_pairs.any(axis=1))
    out = p.copy()
    if len(covered):
        _move(tracer, coverage, p, n, objects, r, lift, dirs, t, covered, out, moved, invalid)
    sliver = _first_hits(tracer, coverage, out + lift[:, None] * n, n, SLIVER * np.asarray(sizes, np.float64))[0] >= 0
    return SampleAdjustment(out, moved, invalid | sliver, sliver)


def _move(tracer, coverage, p, n, objects, r, lift, dirs, t, covered, out, moved, invalid) -> None:
    """Moves the `covered` samples (indices) of p into `out`, marking them `moved` or `invalid`."""

    # candidates: along every probe of a covered sample that hit a back face, the middle of the free part
    tc = t[covered]
    rc = r[covered]
    step = np.maximum((tc + rc[:, None]) / 2.0, tc + MIN_MARGIN_EPS * lift[covered, None])
    usable = np.isfinite(tc) & (step < rc[:, None])
    ci, cj = np.nonzero(usable)
    rows = covered[ci]
    cand = p[rows] + dirs[rows, cj] * step[ci, cj][:, None]
    ok = _on_surface(tracer, coverage, cand, n[rows], objects[rows], lift[rows])
    if ok.any():
        sel = np.flatnonzero(ok)
        lifted, around = cand[sel] + lift[rows[sel], None] * n[rows[sel]], _directions(n[rows[sel]])
        again, _ = _back_hits(tracer, coverage, lifted, around, r[rows[sel]] / 2.0)
        size = np.sqrt(2.0) * r[rows[sel]]  # the texel's size (r is half its diagonal)
        ok[sel] = ~np.isfinite(again).any(axis=1) & ~_in_slot(tracer, coverage, lifted, around, SLOT * size)
    # the nearest good candidate per covered sample
    dist = np.where(ok, step[ci, cj], np.inf)
    best = np.full(len(covered), np.inf)
    np.minimum.at(best, ci, dist)
    pick = ok & (dist == best[ci])
    pi = np.flatnonzero(pick)
    first = np.unique(ci[pi], return_index=True)[1]
    pi = pi[first]
    out[rows[pi]] = cand[pi]
    moved[rows[pi]] = True
    invalid[covered] = ~moved[covered]


def enclosed(tracer: RayTracer, points: np.ndarray, normals: np.ndarray, sizes: np.ndarray,
             coverage: Coverage | None = None) -> np.ndarray:
    """(K,) bool: samples at points (K, 3) on the side of unit normals (K, 3), of world texel sizes
    (K,), whose every probe, of ENCLOSED_PROBES cosine-distributed directions (R2 points, the same for
    all), meets a surface within ENCLOSED_REACH texel sizes, most of them from the front (module
    docstring, "Enclosed samples"); in batches of BATCH."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    n = np.asarray(normals, np.float64).reshape(-1, 3)
    reach = ENCLOSED_REACH * np.asarray(sizes, np.float64).reshape(-1)
    u = (0.5 + np.arange(ENCLOSED_PROBES)[:, None] * R2_STEP) % 1.0
    radius, phi = np.sqrt(u[:, 0]), 2.0 * np.pi * u[:, 1]
    local = np.stack([radius * np.cos(phi), radius * np.sin(phi), np.sqrt(1.0 - u[:, 0])], axis=1)
    out = np.zeros(len(p), bool)
    for i in range(0, len(p), BATCH):
        q, m = p[i:i + BATCH], n[i:i + BATCH]
        t, b = frame(m)
        dirs = local[None, :, 0:1] * t[:, None] + local[None, :, 1:2] * b[:, None] + local[None, :, 2:3] * m[:, None]
        prim, _, behind = _probe(tracer, coverage, q + tracer.point_eps(q, m)[:, None] * m, dirs, reach[i:i + BATCH])
        hit = prim >= 0
        # the inside of a closed mesh (a solid's back side) is seen from behind: not a cavity anyone sees
        out[i:i + BATCH] = hit.all(axis=1) & (2 * (hit & ~behind).sum(axis=1) >= ENCLOSED_PROBES)
    return out
