"""Scattering at a bake path's vertex by the whole section 3.3 BSDF (Eq. 3.6): kd / pi plus the
reflection lobes (Eq. 3.4), one-sample MIS over the components.

At a vertex with outgoing direction wo (back along the arriving ray) the path picks one component
c: the diffuse part with probability q_d proportional to luminance(kd), reflection lobe j with q_j
proportional to luminance(ks_j) x F_j(cos theta_o) (Schlick: the lobe's directional albedo
tends to F cos^(1 - 2 alpha) as m -> 0, so F is a cheap estimate of it). It then samples wi from c:
cosine-weighted for the diffuse part, Eq. 4.5-4.8 for a lobe (core/bsdf.py). The density of the
whole procedure is the mixture
    p(wi) = q_d cos(theta_i) / pi + sum_j q_j p_j(wi)        (p_j: Eq. 4.9)
and the path's throughput is multiplied by f(wi, wo) cos(theta_i) / p(wi) with f the whole BSDF
(Eq. 3.6, reflection part). Next-event estimation evaluates the same f and p for the light's
direction, so MIS (power heuristic) weighs a light sample against this mixture and emission reached
by a sampled direction against the light sample (bake/irradiance.py).

Transmit lobes are not scattered here: a thin transmissive surface lets a path pass straight
through with weight sum_l k_t,l (1 - F_l(cos)) (bake/irradiance.py), the limit of a narrow Eq. 3.5
lobe (its sample, a reflection mirrored through the surface plane, is the arriving direction
itself), which is also what shadow rays do. A rough transmit lobe (frosted glass) is thus
approximated by passing straight through.

Lobe parameters per vertex: ks, r0, alpha the material's factors; a lobe marked by the material's
metallic-roughness texture (`Lobe.mr`) takes ks x M' ("metal") or ks x (1 - M') ("dielectric") with
M' the texel's metallic (the texture is already read for kd); the roughness is the factor's (the
texture's G is not read by the bake). An anisotropic lobe is taken isotropic with m = sqrt(mx my)
(the bake has no tangent frame; the lobe's solid angle is kept).

Path regularisation (the rule against fireflies): every lobe vertex of a bake path follows a
diffuse vertex (the texel, which integrates L cos), and a near-mirror lobe there turns a small or
delta light into a caustic that a few paths of a texel find with a huge weight (NEE through
Eq. 3.4 with m = 1e-4 gives D ~ 3e7). The bake therefore widens every lobe to m >= M_REGULARISE
(in both the sampled direction and the evaluated f and p, so the estimator is exact for the widened
BSDF). It blurs caustics of a polished surface over ~M_REGULARISE radians and leaves the energy a
lobe reflects unchanged up to the lobe's shape near grazing angles. Its bias is within the noise
with an area lamp and a few percent with a point light: the light of the point light's mirror image
in the floor, which the unregularised estimator all but misses (bench/measure_regularisation.py;
figures: docs/BAKE.md, "Scattering by the whole BSDF", "Path regularisation").
"""
from __future__ import annotations

import numpy as np

from glint.bake.lights import luminance
from glint.core.bsdf import dot3, lobe_pdf, reflect_lobe, sample_lobe, schlick_F

M_REGULARISE = 0.02  # smallest Beckmann m of a lobe in the bake's transport (module docstring)
INV_PI = 1.0 / np.pi
_MR_CODES = {"": 0, "metal": 1, "dielectric": 2}



def _local(w, t, b, n):
    """World directions w in the frames (t, b, n)."""
    return np.stack([dot3(w, t), dot3(w, b), dot3(w, n)], axis=1)


def frame(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tangent and bitangent of an orthonormal basis around unit n (Duff et al. 2017, branchless)."""
    nx, ny, nz = n[:, 0], n[:, 1], n[:, 2]
    sign = np.where(nz >= 0, 1.0, -1.0)
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    t = np.stack([1.0 + sign * nx * nx * a, sign * b, -sign * nx], axis=1)
    bt = np.stack([b, sign + ny * ny * a, -ny], axis=1)
    return t, bt


class LobeTable:
    """The reflection lobes of every material, padded to the most any material has."""

    def __init__(self, materials):
        M = max(len(materials), 1)
        R = max([sum(lobe.kind == "reflect" for lobe in m.lobes) for m in materials] + [1])
        self.ks = np.zeros((M, R, 3))
        self.m = np.full((M, R), M_REGULARISE)
        self.r0 = np.zeros((M, R))
        self.alpha = np.zeros((M, R))
        self.mr = np.zeros((M, R), np.int8)
        for i, mat in enumerate(materials):
            for j, lobe in enumerate(lobe for lobe in mat.lobes if lobe.kind == "reflect"):
                self.ks[i, j] = np.clip(np.nan_to_num(np.asarray(lobe.ks, np.float64)), 0.0, 1.0)
                m = np.sqrt(max(float(lobe.mx), 0.0) * max(float(lobe.my), 0.0))
                self.m[i, j] = max(m if np.isfinite(m) else 1.0, M_REGULARISE)
                self.r0[i, j] = np.clip(float(lobe.r0), 0.0, 1.0)
                self.alpha[i, j] = np.clip(float(lobe.alpha), 0.0, 1.0)
                self.mr[i, j] = _MR_CODES.get(lobe.mr, 0)
        self.has = self.ks.reshape(M, -1).max(axis=1) > 0
        self.any = bool(self.has.any())

    def reflectance(self, mat: np.ndarray, metallic: np.ndarray | None, cos: np.ndarray) -> np.ndarray:
        """(N,) estimate of what the lobes reflect at vertices of materials `mat` seen at `cos` to the
        normal: sum_j luminance(ks_j) x Schlick F_j(cos) (the module docstring)."""
        out = np.zeros(len(mat))
        g = np.flatnonzero(np.take(self.has, mat)) if self.any else np.zeros(0, np.int64)
        if len(g):
            ks = self.ks_at(mat[g], None if metallic is None else metallic[g])
            out[g] = (luminance(ks) * schlick_F(cos[g, None], np.take(self.r0, mat[g], axis=0))).sum(axis=1)
        return out

    def ks_at(self, mat: np.ndarray, metallic: np.ndarray | None) -> np.ndarray:
        """(N, R, 3) ks at vertices of materials `mat`, the `mr` lobes scaled by the texel's M'."""
        ks = np.take(self.ks, mat, axis=0)
        if metallic is not None:
            code = np.take(self.mr, mat, axis=0)
            scale = np.where(code == 1, metallic[:, None], np.where(code == 2, 1.0 - metallic[:, None], 1.0))
            ks = ks * scale[..., None]
        return ks


class Vertex:
    """The BSDF of a batch of path vertices: kd, the reflection lobes, the local frame around the
    shading normal ns (on the side the path arrived from) and the component probabilities. The
    lobe arrays hold only the vertices whose material has lobes (`slot` maps a vertex to its row
    there, -1 for none), so diffuse vertices cost what they did before lobes were scattered."""

    def __init__(self, kd: np.ndarray, ns: np.ndarray, wo: np.ndarray | None, lobes: LobeTable | None = None,
                 mat: np.ndarray | None = None, metallic: np.ndarray | None = None):
        self.kd, self.n = kd, ns
        w_d = luminance(kd)
        self.q_d = np.where(w_d > 0, 1.0, 0.0)
        self.slot = None
        if lobes is None or not lobes.any:
            return
        glossy = np.flatnonzero(np.take(lobes.has, mat))
        if not len(glossy):
            return
        self.glossy = glossy
        self.slot = np.full(len(kd), -1)
        self.slot[glossy] = np.arange(len(glossy))
        m = mat[glossy]
        self.t, self.b = frame(ns[glossy])
        self.wo = _local(wo[glossy], self.t, self.b, ns[glossy])
        self.ks = lobes.ks_at(m, None if metallic is None else metallic[glossy])
        self.m, self.r0, self.alpha = (np.take(a, m, axis=0) for a in (lobes.m, lobes.r0, lobes.alpha))
        # lobes need wo above the shading plane (core/bsdf.py convention)
        up = (self.wo[:, 2] > 0)[:, None]
        w_l = np.where(up, luminance(self.ks) * schlick_F(self.wo[:, 2:3], self.r0), 0.0)
        total = w_d[glossy] + w_l.sum(axis=1)
        inv = np.where(total > 0, 1.0 / np.where(total > 0, total, 1.0), 0.0)
        self.q_d[glossy] = w_d[glossy] * inv
        self.q = w_l * inv[:, None]

    def evaluate(self, rows: np.ndarray, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(f (n, 3) RGB, mixture pdf (n,)) for world directions wi at vertices `rows` (Eq. 3.6, module doc)."""
        cos = dot3(wi, np.take(self.n, rows, axis=0))
        above = cos > 0
        f = np.where(above[:, None], np.take(self.kd, rows, axis=0) * INV_PI, 0.0)
        pdf = np.where(above, np.take(self.q_d, rows) * cos * INV_PI, 0.0)
        if self.slot is not None:
            k = np.flatnonzero(self.slot[rows] >= 0)
            if len(k):
                s = self.slot[rows[k]]
                wl = _local(wi[k], self.t[s], self.b[s], self.n[rows[k]])[:, None, :]
                wo = self.wo[s][:, None, :]
                m, r0, alpha = self.m[s], self.r0[s], self.alpha[s]
                f[k] += np.einsum("nr,nrc->nc", reflect_lobe(wl, wo, m, m, r0, alpha), self.ks[s])
                pdf[k] += (self.q[s] * lobe_pdf(wl, wo, m, m, "reflect")).sum(axis=1)
        return f, pdf

    def sample(self, u_choice: np.ndarray, u1: np.ndarray, u2: np.ndarray, cosine_sample):
        """Directions wi (N, 3) from the mixture, and (f (N, 3), p (N,)) at them; p = 0 marks a sample
        to drop. `cosine_sample(n, u1, u2)` draws the diffuse part's directions."""
        d, _ = cosine_sample(self.n, u1, u2)
        if self.slot is not None:
            g = self.glossy
            pick = np.flatnonzero(u_choice[g] >= self.q_d[g])  # (in the lobe rows) the rest stay diffuse
            if len(pick):
                u = u_choice[g[pick]] - self.q_d[g[pick]]
                cdf = np.cumsum(self.q[pick], axis=1)
                j = np.minimum((u[:, None] >= cdf).sum(axis=1), cdf.shape[1] - 1)
                m = self.m[pick, j]
                wl = sample_lobe(self.wo[pick], u1[g[pick]], u2[g[pick]], m, m, "reflect")
                d[g[pick]] = wl[:, 0:1] * self.t[pick] + wl[:, 1:2] * self.b[pick] + wl[:, 2:3] * self.n[g[pick]]
        f, p = self.evaluate(np.arange(len(d)), d)
        return d, f, p
