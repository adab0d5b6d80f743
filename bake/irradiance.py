"""Irradiance at light-map texels by path tracing (wavefront: every path of a batch advances at once).

Estimated quantity, per texel at x with normal n:  E(x) = integral over the hemisphere of L_i(w) cos(w, n) dw
(W/m^2, RGB), so that the viewer's diffuse radiance is kd / pi x E (Eq. 4.1).

Transport (the light map stores irradiance; the view-dependent part of what a texel's own lobes
reflect is the viewer's, but light that reaches the texel via other surfaces' lobes is in E):
- At the texel: next-event estimation (NEE) with one area-light sample, MIS against the
  cosine-weighted direction sample by the power heuristic; every punctual and directional light
  by a deterministic shadow ray; one sky-map sample (MIS against the cosine sample). A constant
  sky is reached by the direction samples alone. Then a cosine-weighted direction: the texel's
  "BSDF" is 1 (E integrates L cos), so the throughput is pi.
- At every later vertex: the whole section 3.3 BSDF (Eq. 3.6: kd / pi plus the reflection lobes,
  bake/scatter.py): NEE as at the texel, the light sample's value f cos / p_light with f the whole
  BSDF and its MIS weight against the one-sample mixture pdf of the direction sampling; then one
  component (diffuse or a lobe, by luminance(kd) against luminance(ks_j) F_j) is sampled (cosine,
  Eq. 4.5-4.8) and the throughput multiplied by f cos / p with p the mixture pdf. Lobes are widened
  to m >= scatter.M_REGULARISE (path regularisation: every lobe vertex follows the diffuse texel;
  bias measured in docs/BAKE.md).
- Emission reached by a direction sample counts with the complementary MIS weight (the mixture pdf
  of the vertex that sampled it); emitters emit from the front face unless their material is
  double-sided.
- Thin transmissive surfaces (materials with transmit lobes): at a hit the path either
  scatters by the BSDF (above) or passes straight through (weight
  T = sum of the transmit lobes' ks x (1 - Schlick F(cos))), chosen with probability
  proportional to luminance (luminance(kd) + sum_j luminance(ks_j) F_j against luminance(T)).
  Passing straight through is the narrow transmit lobe's limit (bake/scatter.py); a rough one
  (frosted glass) is approximated by it. Shadow rays pass such surfaces multiplied by T (up to
  MAX_FILTERS of them). Transmissive surfaces count as two-sided.
- Glass solids (volume materials, core/volume.py): the same straight-through passage, with the
  exact Fresnel of their ior in place of Schlick's at each of the two interfaces, and where the
  ray leaves the solid (a back-face hit) the Beer-Lambert absorption over the refracted length
  inside, the slab model's h.t c / cos_t for the distance h.t the ray crossed. The direction is
  not bent: exact for panes (parallel faces), and irradiance averages over the directions a
  curved solid would bend.
- MASK and BLEND materials (glTF alpha coverage): path rays, shadow rays and the back-face
  statistic pass through their missing parts (bake/alpha.py).
- A path that hits the back face of a single-sided, non-transmissive material ends (black), like
  Mitsuba's one-sided diffuse. The fraction of the texel's own hemisphere rays whose first hit is
  such a back face is returned as `backface` (texels inside walls, under boxes). The back of a
  double-sided or transmissive surface does not count: it is a surface like its front (a room
  whose double-sided walls face outwards is seen from behind, not from inside a wall).
- Russian roulette from depth 3 on the throughput (survival max(beta) / pi, at most 0.95),
  `max_depth` as a safety cap.

Random numbers: counter-based, so each texel's stream depends only on (seed, global texel
index, sample index) and a result does not depend on how texels are chunked across jobs.
The texel's own 2D samples (its hemisphere direction, its light and sky samples) are the R2
low-discrepancy sequence, Cranley-Patterson rotated per texel, the light and sky sets paired
with the direction by a per-texel random permutation (unbiased, and less per-texel noise than
independent samples: docs/BAKE.md, "Sample pairing"); deeper vertices use a hash (splitmix64) of
(path, dimension).

Adaptive sampling: a batch returns each texel's sums of the paths' L and luminance squared (the
standard error's second moment); refine_irradiance traces more paths for chosen texels, those that
follow the ones they have (R2 points and path hashes continued; bake/lightmap.py chooses which, never
from a texel's own paths); E is the sum over all of them divided by their number.

Speed: most of the time is numpy around Embree, not Embree itself (docs/BAKE.md, "The integrator's
speed").
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from glint.bake.alpha import MAX_CUTOUTS, Coverage
from glint.bake.lights import LightSet, luminance
from glint.bake.raytrace import RayTracer
from glint.bake.scatter import LobeTable, Vertex, frame
from glint.core.bsdf import dot3
from glint.core.image_io import sample_texture
from glint.core.scene import Scene
from glint.core.volume import fresnel_dielectric, refracted_cos

BATCH_PATHS = 1 << 16  # paths traced together: bounds memory (~1 kB per path); speed is flat around it (docs/BAKE.md, "The integrator's speed")
MAX_FILTERS = 8  # transmissive surfaces a shadow ray may pass before it counts as blocked (two closed thin-walled glass objects: 4 interfaces each)
RR_DEPTH = 3
RR_MAX = 0.95
INV_PI = 1.0 / np.pi
UP = np.array([0.0, 1.0, 0.0])

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_R2 = 1.32471795724474602596  # plastic number: R2 sequence x_n = frac(n / g, n / g^2)
R2_STEP = np.array([1.0 / _R2, 1.0 / _R2 ** 2])  # the R2 sequence's step (bake/sample_points.py too)


@dataclass
class IrradianceResult:
    total: np.ndarray  # (K, 3) float64 sum over the paths of their L (RGB)
    square: np.ndarray  # (K,) float64 sum over the paths of their luminance squared (the error's second moment)
    samples: np.ndarray  # (K,) int64 paths traced per point (more than asked where adaptive sampling added)
    backface: np.ndarray  # (K,) float32 fraction of the first pass's hemisphere rays that hit a single-sided back face
    rays: int  # rays traced (for statistics)

    @property
    def irradiance(self) -> np.ndarray:
        """(K, 3) float32 E = integral of L_i cos over the hemisphere around n (W/m^2), RGB: the mean of the paths."""
        return mean_irradiance(self.total, self.samples)


# -- random numbers ----------------------------------------------------------------------------
def _mix(x: np.ndarray) -> np.ndarray:
    """splitmix64 finaliser (uint64 -> uint64, a bijection with good avalanche)."""
    x = x ^ (x >> np.uint64(30))
    x = x * _M1
    x = x ^ (x >> np.uint64(27))
    x = x * _M2
    return x ^ (x >> np.uint64(31))


def _uniform2(key: np.ndarray, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Two independent uniforms in [0, 1) from one 64-bit hash of (path key, dimension)."""
    h = _mix(key + np.uint64((dim + 1) * 0x632BE59BD9B4E019 % (1 << 64)))
    return ((h >> np.uint64(32)).astype(np.float64) * 2.0 ** -32,
            (h & np.uint64(0xFFFFFFFF)).astype(np.float64) * 2.0 ** -32)


# -- array helpers -----------------------------------------------------------------------------
# np.take(a, i, axis=0) gathers (N, 3) rows faster than a[i], and a flat 1-D scatter beats
# L[rows] += c; these two and the dot product carry most of the wavefront's numpy time
# (docs/BAKE.md, "The integrator's speed").
def _take(i, *arrays):
    if len(i) == len(arrays[0]):  # i is sorted and unique (from flatnonzero): all rows, nothing to do
        return arrays
    return tuple(np.take(a, i, axis=0) for a in arrays)


def _add_rows(L: np.ndarray, rows: np.ndarray, c: np.ndarray) -> None:
    """L[rows] += c for (N, 3) L and unique rows."""
    flat = (rows[:, None] * 3 + np.arange(3)).ravel()
    Lf = L.reshape(-1)
    Lf[flat] += c.reshape(-1)



def _cosine_sample(n: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cosine-weighted directions around unit n (Malley: concentric disk, Shirley-Chiu, lifted).

    Returns (directions, cos theta); the density is cos / pi.
    """
    a, b = 2.0 * u1 - 1.0, 2.0 * u2 - 1.0
    first = np.abs(a) > np.abs(b)
    r = np.where(first, a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(first, (np.pi / 4) * (b / a), np.pi / 2 - (np.pi / 4) * (a / b))
    phi = np.where(r == 0, 0.0, phi)
    x, y = r * np.cos(phi), r * np.sin(phi)
    z = np.sqrt(np.maximum(0.0, 1.0 - x * x - y * y))
    t, b = frame(n)
    return x[:, None] * t + y[:, None] * b + z[:, None] * n, z


def _power_weight(p_this, p_other):
    """Power heuristic (beta = 2), 0 where both densities are 0."""
    a, b = p_this * p_this, p_other * p_other
    s = a + b
    return np.where(s > 0, a / np.where(s > 0, s, 1.0), 0.0)


# -- per-scene tables --------------------------------------------------------------------------
class _Transport:
    """Material tables and lights for one tracer (built once per process)."""

    def __init__(self, scene: Scene, tracer: RayTracer):
        self.tracer = tracer
        self.lights = LightSet(scene, tracer)
        mats = scene.materials
        M = max(len(mats), 1)
        self.kd = np.zeros((M, 3))
        self.textures = {}
        self.metallic = {}  # metallic-roughness textures' M' per texel: kd x (1 - M')
        self.samplers = {}
        L = max([len(m.transmit_lobes) for m in mats] + [1])
        self.t_ks = np.zeros((M, L, 3))
        self.t_r0 = np.zeros((M, L))
        for i, m in enumerate(mats):
            self.kd[i] = np.clip(np.nan_to_num(np.asarray(m.kd, np.float64).reshape(3)), 0.0, 1.0)
            if m.kd_texture is not None:
                self.textures[i] = np.clip(np.nan_to_num(np.asarray(m.kd_texture, np.float64)[..., :3]),
                                           0.0, 1.0)
                self.samplers[i] = (tuple(m.kd_wrap), bool(m.kd_nearest))
            if m.metallic_roughness_texture is not None:
                self.metallic[i] = np.clip(np.nan_to_num(
                    np.asarray(m.metallic_roughness_texture, np.float64)[..., 2:3]), 0.0, 1.0)
                self.samplers[i] = (tuple(m.kd_wrap), bool(m.kd_nearest))
            for j, lobe in enumerate(m.transmit_lobes):
                self.t_ks[i, j] = np.clip(np.nan_to_num(np.asarray(lobe.ks, np.float64)), 0.0, 1.0)
                self.t_r0[i, j] = np.clip(float(lobe.r0), 0.0, 1.0)
        self.transmissive = self.t_ks.reshape(M, -1).max(axis=1) > 0
        # glass solids: index and absorption (core/volume.py)
        self.volume = np.array([m.has_volume for m in mats] or [False], bool) & self.transmissive
        self.any_volume = bool(self.volume.any())
        self.ior = np.array([max(float(m.ior), 1.0) for m in mats] or [1.5])
        self.sigma = np.array([m.absorption if m.has_volume else np.zeros(3) for m in mats] or [np.zeros(3)])
        self.any_transmissive = bool(self.transmissive.any())
        self.two_sided = self.transmissive.copy()
        for i, m in enumerate(mats):
            self.two_sided[i] |= bool(m.double_sided)
        self.emit_two_sided = np.array([m.double_sided for m in mats] or [False], bool)
        self.emission = self.lights.area.material_emission if len(mats) else np.zeros((1, 3))
        self.emissive = self.emission.max(axis=1) > 0 if len(mats) else np.zeros(1, bool)
        self.emitter_pdf_area = self.lights.area.tri_pdf_area  # by prim (per triangle: textures)
        self.coverage = Coverage(scene, tracer)
        self.lobes = LobeTable(mats)

    def transmittance(self, mat: np.ndarray, cos: np.ndarray, front: np.ndarray | None = None,
                      length: np.ndarray | None = None) -> np.ndarray:
        """Straight-through weight of a transmissive surface hit at `cos` to its normal: thin, sum_l ks_l
        (1 - Schlick F_l(cos)); a glass solid's interface, sum_l ks_l (1 - F(cos)) with the exact
        Fresnel of its ior, and where the ray leaves it (`front` False) times the absorption over
        the `length` it crossed inside (module docstring)."""
        c = np.clip(cos, 0.0, 1.0)
        r0 = self.t_r0[mat]  # (N, L)
        F = r0 + (1.0 - r0) * ((1.0 - c) ** 5)[:, None]
        vol = self.volume[mat] if self.any_volume else None
        if vol is not None and vol.any():
            F = np.where(vol[:, None], fresnel_dielectric(c, self.ior[mat])[:, None], F)
        T = np.einsum("nlc,nl->nc", self.t_ks[mat], 1.0 - F)
        if vol is not None and front is not None:
            out = np.flatnonzero(vol & ~front)
            if len(out):
                m, co = mat[out], c[out]
                inside = length[out] * co / np.maximum(refracted_cos(co, self.ior[m]), 1e-6)
                T[out] *= np.exp(-self.sigma[m] * inside[:, None])
        return T

    def albedo(self, mat: np.ndarray, prim: np.ndarray, b1: np.ndarray, b2: np.ndarray):
        """(kd, M'): kd x base-colour texture x (1 - M') x vertex colour (glTF COLOR_0), and M' (N,), the
        metallic of a metallic-roughness texture (None when no material has one; 0 for materials
        without); the textures through the material's glTF sampler (wrap per axis, bilinear or
        nearest; uv (0, 0) = the image's top-left)."""
        kd = np.take(self.kd, mat, axis=0)
        metallic = np.zeros(len(mat)) if self.metallic else None
        for m, tex in self.textures.items():
            sel = np.nonzero(mat == m)[0]
            if len(sel):
                kd[sel] *= sample_texture(tex, self.tracer.texcoords(prim[sel], b1[sel], b2[sel]), *self.samplers[m])
        for m, tex in self.metallic.items():
            sel = np.nonzero(mat == m)[0]
            if len(sel):
                mm = sample_texture(tex, self.tracer.texcoords(prim[sel], b1[sel], b2[sel]), *self.samplers[m])
                kd[sel] *= 1.0 - mm
                metallic[sel] = mm[:, 0]
        if self.tracer.has_vertex_colors:  # glTF: COLOR_0 x baseColorFactor x texture
            kd = kd * self.tracer.colors(prim, b1, b2)
        return kd, metallic

    # -- shadow rays -------------------------------------------------------------------------
    def visibility(self, o: np.ndarray, d: np.ndarray, tmax: np.ndarray):
        """Which segments o + t d, 0 < t < tmax, let light through: (mask (N,) bool, T (N, 3) or None).

        T multiplies the light where it passed thin transmissive surfaces (each re-shot from just past
        it, MAX_FILTERS at most) and the missing parts of MASK and BLEND surfaces (weight: the open
        fraction c, MAX_CUTOUTS more; a surface both is c + (1 - c) T); it is None when the scene has
        neither (a plain occlusion query)."""
        tr, cov = self.tracer, self.coverage
        if not self.any_transmissive and not cov.any:
            return ~tr.occluded(o, d, tmax), None
        T = np.ones((len(o), 3))
        clear = np.ones(len(o), bool)
        live = np.arange(len(o))
        filters = np.zeros(len(o), np.int64)  # transmissive surfaces passed so far
        o, tmax = o.copy(), tmax.copy()
        rounds = MAX_FILTERS + (MAX_CUTOUTS if cov.any else 0)
        for k in range(rounds + 1):
            rows, h = tr.intersect_hits(o[live], d[live], tmax[live])
            live = live[rows]
            glass = self.transmissive[h.material] & (filters[live] < MAX_FILTERS) & (k < rounds)
            passes = glass.copy()
            if cov.any:
                c = cov.hit_open_fraction(h) if k < rounds else np.zeros(len(live))
                passes |= c > 0
            clear[live[~passes]] = False
            p = np.flatnonzero(passes)
            live = live[p]
            if not len(live):
                break
            dl = d[live]
            ng = h.ng[p]
            w = np.where(glass[p, None], self.transmittance(h.material[p], np.abs(dot3(dl, ng)), h.front[p],
                                                            h.t[p]), 0.0)
            if cov.any:
                c = c[p]
                w = c[:, None] + (1.0 - c)[:, None] * w
                filters[live] += glass[p] & (c < 1.0)
            else:
                filters[live] += 1
            T[live] *= w
            new_o = tr.offset(h.position[p], ng, dl, h.eps[p])
            tmax[live] -= dot3(new_o - o[live], dl)
            o[live] = new_o
            live = live[tmax[live] > 0]
        return clear, T

    def next_event(self, x, x_up, eps, ng, ns, beta, vertex: Vertex, u_light, u_sky) -> list[tuple[np.ndarray, np.ndarray]]:
        """Direct light at vertices x (x_up: x lifted eps along ng; ng, ns: geometric and shading
        normals on the path's side; beta: throughput; vertex: the BSDF there, bake/scatter.py, whose
        f and mixture pdf give the light sample's value and MIS weight).

        Returns [(rows, contributions)] with rows unique within each pair (one pair per light kind)."""
        lights = self.lights
        rows, dirs, tmaxs, values = [], [], [], []

        area = lights.area
        if area.count:
            y, nl, Le, two, pdf_a, eps_l = area.sample(*u_light)
            v = y - x
            d2 = dot3(v, v)
            dist = np.sqrt(d2)
            l = v / np.maximum(dist, 1e-30)[:, None]
            cos_x = dot3(ns, l)
            cos_l = -dot3(nl, l)
            ok = (cos_x > 0) & (dot3(ng, l) > 0) & ((cos_l > 0) | (two & (cos_l < 0)))
            sel = np.flatnonzero(ok)
            if len(sel):
                y, nl, Le, xu, b, ls = _take(sel, y, nl, Le, x_up, beta, l)
                cx, cl, d2 = cos_x[sel], cos_l[sel], d2[sel]
                f, pdf_b = vertex.evaluate(sel, ls)
                fb = b * f
                pdf_l = pdf_a[sel] * d2 / np.abs(cl)  # area -> solid angle
                w = _power_weight(pdf_l, pdf_b)
                # the shadow ray runs from x_up to the light point lifted eps off its own triangle towards x
                seg = y + (eps_l[sel] * np.sign(cl))[:, None] * nl - xu
                length = np.sqrt(dot3(seg, seg))
                rows.append(sel)
                dirs.append(seg / np.maximum(length, 1e-30)[:, None])
                tmaxs.append(length)
                values.append((fb * Le) * (cx * w / pdf_l)[:, None])

        if lights.delta.count:
            for l, dist, E in lights.delta.evaluate(x):
                cos_x = dot3(ns, l)
                sel = np.flatnonzero((cos_x > 0) & (dot3(ng, l) > 0) & (E.max(axis=1) > 0))
                if len(sel):
                    ls, Es, b = _take(sel, l, E, beta)
                    fb = b * vertex.evaluate(sel, ls)[0]
                    rows.append(sel)
                    dirs.append(ls)
                    tmaxs.append(dist[sel] - eps[sel])
                    values.append(fb * Es * cos_x[sel][:, None])

        sky = lights.sky
        if sky is not None and not sky.constant and sky.samplable:
            l, pdf_s = sky.sample(*u_sky)
            cos_x = dot3(ns, l)
            sel = np.flatnonzero((cos_x > 0) & (dot3(ng, l) > 0) & (pdf_s > 0))
            if len(sel):
                cx, ps = cos_x[sel], pdf_s[sel]
                ls, b = _take(sel, l, beta)
                f, pdf_b = vertex.evaluate(sel, ls)
                fb = b * f
                w = _power_weight(ps, pdf_b)
                rows.append(sel)
                dirs.append(ls)
                tmaxs.append(np.full(len(sel), np.inf))
                values.append(fb * sky.radiance(ls) * (cx * w / ps)[:, None])

        if not rows:
            return []
        allrows = np.concatenate(rows) if len(rows) > 1 else rows[0]
        clear, T = self.visibility(np.take(x_up, allrows, axis=0), np.concatenate(dirs) if len(dirs) > 1 else dirs[0],
                                   np.clip(np.concatenate(tmaxs), 0.0, 1e30))
        out, start = [], 0
        for r, v in zip(rows, values):
            c = clear[start:start + len(r)]
            if T is not None:
                v = v * T[start:start + len(r)]
            c = np.flatnonzero(c)
            out.append((r[c], np.take(v, c, axis=0)))
            start += len(r)
        return out


_CACHE: "weakref.WeakKeyDictionary[RayTracer, _Transport]" = weakref.WeakKeyDictionary()


def _transport(scene: Scene, tracer: RayTracer) -> _Transport:
    t = _CACHE.get(tracer)
    if t is None:
        t = _CACHE[tracer] = _Transport(scene, tracer)
    return t


# -- the integrator ----------------------------------------------------------------------------
def compute_irradiance(scene: Scene, tracer: RayTracer, points, normals, samples: int, seed: int = 0,
                       max_depth: int = 64, progress=None, first_index: int = 0) -> IrradianceResult:
    """E at K points with unit normals: `samples` paths each; deterministic per (seed, first_index + k).

    progress, when given, is called with the number of texels finished after each batch.
    """
    points = np.asarray(points, np.float64).reshape(-1, 3)
    normals = np.asarray(normals, np.float64).reshape(-1, 3)
    K = len(points)
    samples = max(int(samples), 1)
    total = np.zeros((K, 3))
    square = np.zeros(K)
    back = np.zeros(K, np.float32)
    rays_before = tracer.rays
    ids = np.arange(first_index, first_index + K, dtype=np.uint64)
    if K:
        tp = _transport(scene, tracer)
        per_batch = max(1, BATCH_PATHS // samples)
        for start in range(0, K, per_batch):
            stop = min(K, start + per_batch)
            e, q, b = _trace_batch(tp, points[start:stop], normals[start:stop], ids[start:stop], 0, samples,
                                   seed, max_depth)
            total[start:stop], square[start:stop], back[start:stop] = e, q, b
            if progress is not None:
                progress(stop - start)
    return IrradianceResult(total, square, np.full(K, samples, np.int64), back, int(tracer.rays - rays_before))


def refine_irradiance(scene: Scene, tracer: RayTracer, points, normals, ids: np.ndarray, total: np.ndarray,
                      square: np.ndarray, count: np.ndarray, max_samples: int, seed: int = 0,
                      max_depth: int = 64) -> None:
    """More paths for points `ids` (global texel indices, which seed their random numbers; points and
    normals theirs) until each has `max_samples`: the paths that follow the `count` it has in its own
    sequence (R2 points and path hashes continued), traced in rounds that double the count. The sums
    `total`, `square` and `count` (of the paths' L, luminance squared, number) are updated in place;
    E = total / count weighs every path the same. How many paths a point ends with is the caller's
    choice: for E to stay unbiased, it must not depend on the point's own paths (bake/lightmap.py)."""
    if not len(ids):
        return
    tp = _transport(scene, tracer)
    points = np.asarray(points, np.float64).reshape(-1, 3)
    normals = np.asarray(normals, np.float64).reshape(-1, 3)
    while (more := np.flatnonzero(count < max_samples)).size:
        for n in np.unique(count[more]):  # a round per count (each point continues its own sequence)
            rows = more[count[more] == n]
            add = int(min(n, max_samples - n))
            per_batch = max(1, BATCH_PATHS // add)
            for start in range(0, len(rows), per_batch):
                r = rows[start:start + per_batch]
                e, q, _ = _trace_batch(tp, points[r], normals[r], ids[r], int(n), add, seed, max_depth)
                total[r] += e
                square[r] += q
            count[rows] += add


def mean_irradiance(total: np.ndarray, count: np.ndarray) -> np.ndarray:
    """(K, 3) float32 E: the sums of the paths' L over their number (every path weighs the same)."""
    return np.clip(total / np.maximum(count, 1)[:, None], 0.0, np.finfo(np.float32).max).astype(np.float32)


def relative_error(total: np.ndarray, square: np.ndarray, count: np.ndarray, floor: float) -> np.ndarray:
    """(K,) the standard error of each texel's mean luminance over its `count` paths (from the sums of
    L and of luminance squared), relative to max(mean luminance, floor); 0 for a texel black in every
    path, inf for one path."""
    mean = luminance(total) / count
    var = np.maximum(square / count - mean * mean, 0.0) * count / np.maximum(count - 1, 1)
    se = np.where(count > 1, np.sqrt(var / count), np.inf)
    scale = np.maximum(mean, floor)
    return np.where(scale > 0, se / np.where(scale > 0, scale, 1.0), 0.0)


def _texel_qmc(texel_key: np.ndarray, samples: int, tag: int, permute: bool,
               first_sample: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """R2 points first_sample .. first_sample + samples - 1 for every (texel, sample) (texel-major),
    rotated per texel, optionally permuted per texel within that run of points (a later pass of an
    adaptive texel continues the sequence where the earlier one ended)."""
    nt = len(texel_key)
    index = np.broadcast_to(np.arange(first_sample, first_sample + samples, dtype=np.float64), (nt, samples))
    if permute:
        keys = _mix(texel_key[:, None] * _GOLDEN
                    + np.arange(first_sample, first_sample + samples, dtype=np.uint64)[None, :] + np.uint64(tag))
        index = first_sample + np.argsort(keys, axis=1).astype(np.float64)
    shift = _uniform2(texel_key, 1000 + tag)
    u = np.mod(shift[0][:, None] + index * R2_STEP[0], 1.0).ravel()
    v = np.mod(shift[1][:, None] + index * R2_STEP[1], 1.0).ravel()
    return u, v


def _trace_batch(tp: _Transport, points, normals, texel_ids, first_sample, samples, seed, max_depth):
    """Paths first_sample .. first_sample + samples - 1 of the texels `texel_ids` (global indices, which
    seed their random numbers): (sum of the paths' L (nt, 3), sum of their luminance squared (nt,),
    back-face share (nt,))."""
    tr = tp.tracer
    sky = tp.lights.sky
    nt = len(points)
    N = nt * samples
    texel_key = _mix(np.asarray(texel_ids, np.uint64) + _mix(np.full(1, seed, dtype=np.uint64)))
    key = _mix(np.repeat(texel_key, samples) * _GOLDEN
               + np.tile(np.arange(first_sample, first_sample + samples, dtype=np.uint64), nt))

    n = normals.copy()
    length = np.sqrt(dot3(n, n))
    good = (length > 1e-12) & np.isfinite(points).all(axis=1) & np.isfinite(n).all(axis=1)
    n[good] /= length[good, None]
    points = np.where(good[:, None], points, 0.0)
    n = np.where(good[:, None], n, UP)
    eps = tr.point_eps(points, n)
    a = np.flatnonzero(np.repeat(good, samples))  # paths of usable texels (others stay black)
    texel = a // samples
    x, n, eps = (np.take(v, texel, axis=0) for v in (points, n, eps))
    key = key[a]
    L = np.zeros((N, 3))
    backface = np.zeros(N)

    # vertex 0, the texel: its BSDF is 1 (E integrates L cos): NEE, then a cosine direction (QMC)
    x_up = x + eps[:, None] * n
    u_light = [u[a] for u in _texel_qmc(texel_key, samples, 1, True, first_sample)]
    u_sky = [u[a] for u in _texel_qmc(texel_key, samples, 2, True, first_sample)]
    texel_bsdf = Vertex(np.full((len(a), 3), np.pi), n, None)  # f = pi / pi = 1, pdf = cos / pi
    for rows, c in tp.next_event(x, x_up, eps, n, n, np.ones((len(a), 3)), texel_bsdf, u_light, u_sky):
        _add_rows(L, a[rows], c)
    d, cos = _cosine_sample(n, *[u[a] for u in _texel_qmc(texel_key, samples, 0, False, first_sample)])
    s = np.flatnonzero(cos > 0)
    idx, o, d, prev_pos, prev_pdf, key = _take(s, a, x_up, d, x, cos * INV_PI, key)
    beta = np.full((len(s), 3), np.pi)  # f cos / pdf = 1 x cos / (cos / pi)

    for depth in range(max_depth):
        if not len(idx):
            break

        rows, h = tp.coverage.intersect_hits(  # a uniform per (path, depth, cut-out layer) for BLEND
            o, d, uniform=lambda r, k: _uniform2(np.take(key, r), (1 << 20) + 64 * depth + k)[0])
        if depth == 0:  # "inside geometry": the back of a surface that is dark on that side
            backface[idx[rows]] = ~h.front & ~tp.two_sided[h.material]
        if len(rows) < len(idx):
            if sky is not None:  # escaped: sky radiance, MIS against the previous vertex's sky sample
                m = np.ones(len(idx), bool)
                m[rows] = False
                m = np.flatnonzero(m)
                dm = np.take(d, m, axis=0)
                Ls = sky.radiance(dm)
                if not sky.constant and sky.samplable:
                    Ls *= _power_weight(prev_pdf[m], sky.pdf(dm))[:, None]
                _add_rows(L, idx[m], np.take(beta, m, axis=0) * Ls)
            idx, d, beta, prev_pos, prev_pdf, key = _take(rows, idx, d, beta, prev_pos, prev_pdf, key)
        mat, pos, ngeo, front = h.material, h.position, h.ng, h.front

        # emission reached by the direction sample: MIS against the light sample of the previous vertex
        em = np.flatnonzero(tp.emissive[mat] & (front | tp.emit_two_sided[mat]))
        if len(em):
            me, pr = mat[em], h.prim[em]
            pe, ppe, ne, de, be = _take(em, pos, prev_pos, ngeo, d, beta)
            v = pe - ppe
            pdf_l = tp.emitter_pdf_area[pr] * dot3(v, v) / np.maximum(np.abs(dot3(ne, de)), 1e-12)
            # factor x emissive texture at the hit (glTF 3.9.3)
            Le = tp.lights.area.emission_at(me, pr, h.b1[em], h.b2[em])
            _add_rows(L, idx[em], be * Le * _power_weight(prev_pdf[em], pdf_l)[:, None])
        if depth + 1 >= max_depth:
            break

        kd, metallic = tp.albedo(mat, h.prim, h.b1, h.b2)
        ok = front | tp.two_sided[mat]  # the back face of a single-sided surface ends the path
        if tp.any_transmissive:
            cos_in = np.abs(dot3(d, ngeo))
            lum_s = luminance(kd) + tp.lobes.reflectance(mat, metallic, cos_in)  # what scattering reflects
            # scatter (by the BSDF) or pass straight through (weight T), chosen by luminance
            T = np.where(tp.transmissive[mat][:, None], tp.transmittance(mat, cos_in, front, h.t), 0.0)
            lum_T = luminance(T)
            total = lum_s + lum_T
            ok &= total > 0
            p_t = np.where(total > 0, lum_T / np.where(total > 0, total, 1.0), 0.0)
            through = ok & (_uniform2(key, 8 * (depth + 1) + 6)[0] < p_t)
            ok &= ~through
            t = np.flatnonzero(through)
            # same direction from the far side; MIS state (prev_pos, prev_pdf) unchanged
            ti, tpos, tng, td, teps, tbeta, tT, tp_t, tprev, tpdf, tkey = _take(
                t, idx, pos, ngeo, d, h.eps, beta, T, p_t, prev_pos, prev_pdf, key)
            t_state = (ti, tr.offset(tpos, tng, td, teps), td, tbeta * (tT / tp_t[:, None]), tprev, tpdf, tkey)
            p_s = 1.0 - p_t
            beta = beta * np.where(p_s > 0, 1.0 / np.where(p_s > 0, p_s, 1.0), 0.0)[:, None]
        else:
            ok &= (kd.max(axis=1) > 0) | tp.lobes.has[mat]
            t_state = None
        keep = np.flatnonzero(ok)
        idx, pos, ngeo, ns, eps, front, beta, key, kd, d, mat = _take(keep, idx, pos, ngeo, h.ns, h.eps,
                                                                      front, beta, key, kd, d, mat)
        if metallic is not None:
            metallic = np.take(metallic, keep)

        # scattering, normals turned to the side the path arrived from
        flip = np.where(front, 1.0, -1.0)[:, None]
        ngeo = ngeo * flip
        ns = ns * flip
        bad = np.flatnonzero(dot3(ns, ngeo) <= 0)
        if len(bad):
            ns[bad] = ngeo[bad]
        x_up = pos + eps[:, None] * ngeo
        vertex = Vertex(kd, ns, -d, tp.lobes, mat, metallic)
        for rows, c in tp.next_event(pos, x_up, eps, ngeo, ns, beta, vertex,
                                     _uniform2(key, 8 * (depth + 1)), _uniform2(key, 8 * (depth + 1) + 1)):
            _add_rows(L, idx[rows], c)
        d, f, pdf = vertex.sample(_uniform2(key, 8 * (depth + 1) + 4)[0], *_uniform2(key, 8 * (depth + 1) + 2),
                                  _cosine_sample)
        cos = dot3(d, ns)
        go = (pdf > 0) & (cos > 0) & (dot3(d, ngeo) > 0)
        beta = beta * np.where(go[:, None], f * (cos / np.where(go, pdf, 1.0))[:, None], 0.0)  # f cos / p
        if depth + 1 >= RR_DEPTH:  # Russian roulette on the throughput (relative to the texel's pi)
            q = np.minimum(beta.max(axis=1) * INV_PI, RR_MAX)
            go &= _uniform2(key, 8 * (depth + 1) + 3)[0] < q
            beta /= np.where(go, q, 1.0)[:, None]
        idx, o, d, beta, prev_pos, prev_pdf, key = _take(np.flatnonzero(go), idx, x_up, d, beta, pos, pdf, key)
        if t_state is not None:
            idx, o, d, beta, prev_pos, prev_pdf, key = (np.concatenate(pair) for pair in
                                                        zip(t_state, (idx, o, d, beta, prev_pos, prev_pdf, key)))

    L = np.clip(np.nan_to_num(L, nan=0.0, posinf=0.0, neginf=0.0), 0.0, np.finfo(np.float32).max)
    Y = luminance(L).reshape(nt, samples)
    return (L.reshape(nt, samples, 3).sum(axis=1), (Y * Y).sum(axis=1),
            backface.reshape(nt, samples).mean(axis=1))
