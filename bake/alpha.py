"""Coverage of MASK and BLEND materials (glTF 3.9.4 "Alpha Coverage") for the bake's rays and texels.

alpha at a surface point = Material.alpha (baseColorFactor[3]) x the base colour texture's alpha,
bilinear and repeating at the point's TEXCOORD_0 (the viewer's sampler; `_Transport.albedo` reads kd
the same way). MASK: the surface is not there where alpha < alpha_cutoff; BLEND: it covers the
fraction alpha of its area, the rest lets light through unchanged.

embreex exposes no intersection-filter callbacks, so a ray that hits a missing part is traced again
from just past the hit (`RayTracer.offset`), MAX_CUTOUTS times at most; after that the surface
counts as there. Every query costs nothing extra in a scene without MASK or BLEND materials.

- Path rays (`Coverage.intersect_hits`): a MASK surface is passed where cut out; a BLEND surface
  with probability 1 - alpha (a uniform per ray and layer from the caller), which is unbiased:
  it scatters with probability alpha, i.e. in proportion to its coverage.
- Shadow rays (`Coverage.open_fraction`): the light passing is weighted by 1 for a cut-out
  MASK point and by 1 - alpha for BLEND (no random choice: less noise for the same mean).
- Texels (`cut_out_texels`): light-map texels in the cut-out parts of MASK surfaces are never
  seen, so they are not path traced: dilation fills them from their visible neighbours.
"""
from __future__ import annotations

import numpy as np

from glint.bake.raytrace import Hits, RayTracer
from glint.core.image_io import sample_texture
from glint.core.scene import Scene

MAX_CUTOUTS = 16  # cut-out layers a ray may pass (a tree crown seen through); then the surface counts
MODES = {"OPAQUE": 0, "MASK": 1, "BLEND": 2}


class _Tables:
    """Per-material alpha mode, cutoff, factor and alpha texture."""

    def __init__(self, scene: Scene):
        mats = scene.materials
        M = max(len(mats), 1)
        self.mode = np.zeros(M, np.int64)
        self.cutoff = np.zeros(M)
        self.factor = np.ones(M)
        self.textures: dict[int, np.ndarray] = {}
        self.samplers: dict[int, tuple[tuple[str, str], bool]] = {}
        for i, m in enumerate(mats):
            if not m.has_coverage:
                continue
            self.mode[i] = MODES[m.alpha_mode]
            self.cutoff[i] = float(m.alpha_cutoff)
            self.factor[i] = float(np.clip(np.nan_to_num(m.alpha), 0.0, 1.0))
            if m.alpha_texture is not None:
                self.textures[i] = np.clip(np.nan_to_num(np.asarray(m.alpha_texture, np.float64)), 0.0, 1.0)
                self.samplers[i] = (tuple(m.kd_wrap), bool(m.kd_nearest))
        self.cut = self.mode > 0
        self.any = bool(self.cut.any())

    def alpha(self, mat: np.ndarray, uv_of) -> np.ndarray:
        """alpha of points on materials `mat`; uv_of(sel) gives the texture coordinates of points sel."""
        a = np.take(self.factor, mat)
        for m, tex in self.textures.items():
            sel = np.flatnonzero(mat == m)
            if len(sel):
                a[sel] *= sample_texture(tex, uv_of(sel), *self.samplers[m])
        return a

    def open_fraction(self, mat: np.ndarray, uv_of) -> np.ndarray:
        """Fraction of the light that passes the surface at these points: MASK 1 where alpha < cutoff,
        else 0; BLEND 1 - alpha; OPAQUE 0."""
        out = np.zeros(len(mat))
        sel = np.flatnonzero(self.cut[mat])
        if not len(sel):
            return out
        m = mat[sel]
        a = self.alpha(m, lambda s: uv_of(sel[s]))
        mode = self.mode[m]
        out[sel] = np.where(mode == MODES["MASK"], (a < self.cutoff[m]).astype(np.float64), 1.0 - a)
        return out


class Coverage(_Tables):
    """The alpha tables of `scene` with the ray queries that pass through missing parts."""

    def __init__(self, scene: Scene, tracer: RayTracer):
        super().__init__(scene)
        self.tracer = tracer

    def hit_open_fraction(self, h: Hits) -> np.ndarray:
        """`open_fraction` at hits `h`."""
        tr = self.tracer
        return self.open_fraction(h.material, lambda s: tr.texcoords(h.prim[s], h.b1[s], h.b2[s]))

    def intersect_hits(self, origins, directions, tmax=None, uniform=None) -> tuple[np.ndarray, Hits]:
        """`RayTracer.intersect_hits` where cut-out points let the ray through (module docstring).

        uniform(rays, k) -> uniforms in [0, 1) for the rays `rays` (indices into origins) at their
        k-th surface with coverage: a BLEND surface is passed where the uniform < 1 - alpha (without
        `uniform`, where 1 - alpha > 1/2). Hit distances t stay measured from the original origins."""
        tr = self.tracer
        rows, h = tr.intersect_hits(origins, directions, tmax)
        if not self.any or not len(rows):
            return rows, h
        o = np.asarray(origins, np.float64)
        d = np.asarray(directions, np.float64)
        limit = None if tmax is None else np.broadcast_to(np.asarray(tmax, np.float64), (len(o),))
        fields = list(Hits.__dataclass_fields__)
        fresh = np.ones(len(rows), bool)  # hits not yet tested (a surface that stays is tested once)
        for k in range(MAX_CUTOUTS):
            sel = np.flatnonzero(fresh & self.cut[h.material])
            if not len(sel):
                break
            sub = Hits(*(getattr(h, f)[sel] for f in fields))
            u = np.full(len(sel), 0.5) if uniform is None else uniform(rows[sel], k)
            sel = sel[self.hit_open_fraction(sub) > u]
            if not len(sel):
                break
            r = rows[sel]
            dr = np.take(d, r, axis=0)
            start = tr.offset(h.position[sel], h.ng[sel], dr, h.eps[sel])
            advanced = np.einsum("ij,ij->i", start - np.take(o, r, axis=0), dr)
            hit, h2 = tr.intersect_hits(start, dr, None if limit is None else np.maximum(limit[r] - advanced, 0.0))
            h2.t = h2.t + advanced[hit]
            for f in fields:
                getattr(h, f)[sel[hit]] = getattr(h2, f)
            fresh[:] = False
            fresh[sel[hit]] = True
            keep = np.ones(len(rows), bool)
            keep[sel] = False
            keep[sel[hit]] = True
            if not keep.all():
                keep = np.flatnonzero(keep)
                rows, fresh = rows[keep], fresh[keep]
                h = Hits(*(getattr(h, f)[keep] for f in fields))
        return rows, h


def cut_out_texels(scene: Scene, objects: np.ndarray, uvs: np.ndarray) -> np.ndarray:
    """(K,) bool: texels of objects `objects` at texture coordinates `uvs` that lie in the cut-out
    parts of MASK materials (alpha < alphaCutoff)."""
    tables = _Tables(scene)
    out = np.zeros(len(objects), bool)
    if not tables.any or not len(objects):
        return out
    mat = np.array([o.material for o in scene.objects], np.int64)[objects]
    mask = np.flatnonzero(tables.mode[mat] == MODES["MASK"])
    if len(mask):
        out[mask] = tables.open_fraction(mat[mask], lambda s: uvs[mask[s]]) > 0
    return out
