"""Fitting the section 3.3 material model to BRDF data (thesis 3.4.1; issue 24).

The model (Eq. 3.6) is kd/pi plus lobes ks f_lobe(wi, wo; m, r0, alpha) (Eq. 3.3-3.5). A fit
finds kd (RGB) and one or two reflection lobes (ks RGB, m = mx = my: isotropic data, r0,
alpha), and a transmission lobe when the data transmits.

Data (`BrdfData`): the BRDF on a fixed quadrature of the incident hemisphere for each of a set
of view angles theta_o (0 to 85 degrees, phi_o = 0): its directions, RGB values (NaN where the
data has none) and each sample's weight, cos(theta_i) times its solid angle, so that
sum(value x weight) over a view is that view's directional albedo. `BrdfData.from_function`
fills it from any callable `brdf(wi, wo) -> (..., 3)` (a MERL table's lookup, bake/merl.py; a
reference BRDF). The quadrature is laid out around the mirror direction: the half vector h at
Gauss-Legendre nodes of u in [0, 1] with theta_h = pi/2 u^2 (dense near the specular peak, as the
MERL table's theta_h axis) and phi_h at midpoints of [0, pi] (isotropic data is symmetric about
the plane of incidence: weights doubled); wi = 2 (wo.h) h - wo, d(wi) = 4 (wo.h) d(h).

Error. Eq. 3.7 (L1 of cos-weighted transfer probabilities) weighs the bulk of the hemisphere;
issue 24 asks instead for the light a walkthrough sees: each view angle's directional albedo,
and where that light goes (lobe shape). The error here is least squares over two kinds of rows,
both per view angle j and divided by the data's (grey) albedo a_j there, so every view angle
counts the same however dark it is:
  shape rows, one per sample k: (model_jk - data_jk) w_jk / a_j (the energy each direction
  receives, which keeps a narrow peak narrow),
  albedo rows, one per view: sqrt(ALBEDO_WEIGHT) (sum_k (model_jk - data_jk) w_jk) / a_j.
Being least squares it is quadratic in the linear parameters (kd, every lobe's ks per channel),
which are solved in closed form by non-negative least squares for each candidate (m, r0, alpha)
of the lobe being searched: the search is 3-dimensional whatever the number of lobes.

Search. `hierarchical`: the thesis' hierarchical brute force (3.4.1, Fig. 3.8): n = 9 values of
each of log m, r0 and alpha, then the box shrunk to +-one step around the best, 5 times.
`multistart`: a coarse grid's best few points polished by L-BFGS-B (scipy.optimize.minimize).
`multistart` is the default: it recovered 20 of 20 random known lobes in 2.1 s a fit, the
hierarchical search 17 of 20 (its misses trade r0 against alpha at the same albedo) in 4.2 s.
Two lobes (`two_lobe="joint"`, the default with `multistart`): lobe 1 alone first (the one-lobe
fit); then lobe 2 on the residual: with lobe 1's shape fixed (every ks solved again with lobe 2's), a
grid over lobe 2's (r0, alpha) at each of TWO_LOBE_M values of its m, wider than lobe 1's; and a grid
over both widths (the joint optimum's lobe 1 is often narrower than the one-lobe fit's); the residual
grid's best and the best others (TWO_LOBE_STARTS in all) polished jointly over both shapes (six
parameters, L-BFGS-B). The polish keeps lobe 1 the narrow one: lobe 2's log m is
lobe 1's plus d >= 0, so the pair is ordered and a table of fitted rows interpolates lobe by lobe.
As the residual grid's best start has the one-lobe optimum's shape (NNLS may switch lobe 2 off), the
two-lobe error is never above the one-lobe error. `two_lobe="in-turn"` (and the hierarchical search) fit them
in turn as the thesis does (3.4.1): lobe 1, then lobe 2 with lobe 1's shape fixed, then lobe 1
again with lobe 2's; it stops short of the joint optimum (docs/BENCHMARKS.md, "Fitting the material
model": how often each recovers a known two-lobe BRDF). Which search finds the global minimum how
often and how fast: the same section. Deterministic: fixed grids and nodes, no random numbers.
"""
from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from glint.core import bsdf
from glint.core.errors import GlintError
from glint.core.scene import Lobe

VIEW_DEGREES = tuple(range(0, 90, 5))  # theta_o of the fit: 0 to 85 degrees
ALBEDO_DEGREES = 80.0  # the albedo must match up to here (issue 24); 85 is fitted but not reported
NU = 40  # Gauss-Legendre nodes of u (theta_h = pi/2 u^2)
NPHI = 32  # midpoints of phi_h in [0, pi]
ALBEDO_WEIGHT = 4.0  # albedo rows against shape rows (module docstring)
M_RANGE = (0.001, 1.0)  # Beckmann m searched (log-spaced): down to glTF roughness 0.05 (GGX alpha 0.0025)
GRID_N = 9  # values per parameter of one hierarchical step (thesis Fig. 3.8)
LEVELS = 5  # hierarchical refinements
METHODS = ("multistart", "hierarchical")  # the first is the default: docs/BENCHMARKS.md
ROUNDS = 2  # in-turn passes over the lobes when fitting two (thesis 3.4.1)
ALBEDO_FLOOR = 1e-4  # a view's grey albedo below this: the data is black there (no division by ~0)


# ----------------------------------------------------------------------------- data

@dataclass
class BrdfData:
    """A BRDF on the fit's quadrature (module docstring). Shapes: V views, K samples per view
    (2 x NU x NPHI with transmission: the reflection samples, then the same mirrored below)."""

    theta_o: np.ndarray  # (V,) radians
    wo: np.ndarray  # (V, 3)
    wi: np.ndarray  # (V, K, 3)
    weight: np.ndarray  # (V, K): cos(theta_i) x solid angle; 0 where wi is not a valid direction
    rgb: np.ndarray  # (V, K, 3): the BRDF; NaN where the data has no value
    transmission: bool = False
    name: str = ""

    @classmethod
    def from_function(cls, brdf: Callable[[np.ndarray, np.ndarray], np.ndarray], *, transmission: bool = False,
                      name: str = "", views=VIEW_DEGREES) -> "BrdfData":
        """The callable `brdf(wi, wo) -> (..., 3)` (wi, wo (..., 3) unit vectors in the local frame, z the
        normal, both away from the surface) on the quadrature. Negative or non-finite values are
        missing data (MERL's convention: negative = not measured)."""
        theta_o, wo, wi, weight = quadrature(views, transmission)
        rgb = np.asarray(brdf(wi, np.broadcast_to(wo[:, None, :], wi.shape)), dtype=float)
        if rgb.shape != wi.shape:
            raise GlintError(f"{name or 'the BRDF'}: expected RGB values of shape {wi.shape}, got {rgb.shape}")
        rgb = np.where(np.isfinite(rgb) & (rgb >= 0.0), rgb, np.nan)
        data = cls(theta_o, wo, wi, weight, rgb, transmission, name)
        if not np.any(data.valid & (data.weight > 0)):
            raise GlintError(f"{name or 'the BRDF'}: no valid (non-negative, finite) value to fit")
        return data

    @property
    def valid(self) -> np.ndarray:
        """(V, K): where every channel has a value."""
        return np.all(np.isfinite(self.rgb), axis=-1)

    @property
    def mask_weight(self) -> np.ndarray:
        """The weights with missing samples at 0: model and data are compared on the same samples."""
        return np.where(self.valid, self.weight, 0.0)

    def albedo(self) -> np.ndarray:
        """(V, 3) directional albedo of the data over its valid samples (reflection + transmission)."""
        return np.einsum("vkc,vk->vc", np.nan_to_num(self.rgb), self.mask_weight)


def quadrature(views=VIEW_DEGREES, transmission: bool = False):
    """(theta_o (V,), wo (V, 3), wi (V, K, 3), weight (V, K)): the module docstring's quadrature."""
    theta_o = np.radians(np.asarray(views, dtype=float))
    wo = np.stack([np.sin(theta_o), np.zeros_like(theta_o), np.cos(theta_o)], axis=-1)
    x, gw = np.polynomial.legendre.leggauss(NU)
    u, du = 0.5 * (x + 1.0), 0.5 * gw  # nodes and weights on [0, 1]
    th = 0.5 * np.pi * u * u
    dth = np.pi * u * du  # d(theta_h) = pi u du
    ph = (np.arange(NPHI) + 0.5) * np.pi / NPHI
    dph = 2.0 * np.pi / NPHI  # [0, pi] with weight doubled: the mirror half (isotropic data)
    th, ph = (a.ravel() for a in np.meshgrid(th, ph, indexing="ij"))
    dwh = (np.sin(th) * np.meshgrid(dth, np.ones(NPHI), indexing="ij")[0].ravel()) * dph
    h = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)  # (K, 3)
    oh = wo @ h.T  # (V, K)
    wi = 2.0 * oh[..., None] * h[None] - wo[:, None, :]  # Eq. 4.8
    wi /= np.linalg.norm(wi, axis=-1, keepdims=True)
    ok = (oh > 0.0) & (wi[..., 2] > 0.0)
    weight = np.where(ok, 4.0 * oh * dwh[None] * wi[..., 2], 0.0)  # cos(theta_i) d(wi), d(wi) = 4 (wo.h) d(h)
    if transmission:  # the same directions mirrored below the surface (Eq. 3.5's wi')
        wi = np.concatenate([wi, bsdf.mirror(wi)], axis=1)
        weight = np.concatenate([weight, weight], axis=1)
    return theta_o, wo, wi, weight


# ----------------------------------------------------------------------------- result

@dataclass
class FitResult:
    """A fitted material (Eq. 3.6) and how well it matches."""

    kd: tuple[float, float, float]
    lobes: list[Lobe]
    error: float  # the objective (module docstring), relative to the data's: 0 perfect, 1 as bad as black
    theta_o: np.ndarray  # (V,) radians
    albedo_data: np.ndarray  # (V, 3)
    albedo_fit: np.ndarray  # (V, 3), by core/bsdf.py on the same samples
    method: str = METHODS[0]
    evaluations: int = 0  # candidates (m, r0, alpha) whose linear parameters were solved
    seconds: float = 0.0

    @property
    def albedo_error(self) -> float:
        """Largest relative error of the grey directional albedo at view angles up to ALBEDO_DEGREES."""
        keep = np.degrees(self.theta_o) <= ALBEDO_DEGREES + 1e-9
        a, b = self.albedo_data[keep].mean(axis=-1), self.albedo_fit[keep].mean(axis=-1)
        return float(np.max(np.abs(b - a) / np.maximum(a, ALBEDO_FLOOR)))


def model_values(data: BrdfData, kd, lobes: list[Lobe]) -> np.ndarray:
    """(V, K, 3): the model by core/bsdf.py (the reference, not the fit's fast path) on the data's samples."""
    wo = np.broadcast_to(data.wo[:, None, :], data.wi.shape)
    return bsdf.bsdf(data.wi, wo, kd, lobes)


def model_albedo(data: BrdfData, kd, lobes: list[Lobe]) -> np.ndarray:
    """(V, 3) directional albedo of the model on the data's valid samples."""
    return np.einsum("vkc,vk->vc", model_values(data, kd, lobes), data.mask_weight)


# ----------------------------------------------------------------------------- the linear part

class _Problem:
    """The least-squares rows of the module docstring for one data set, with every sample's
    geometry precomputed so that a candidate lobe's column costs two exp() per sample."""

    def __init__(self, data: BrdfData, albedo_weight: float = ALBEDO_WEIGHT, diffuse: bool = True,
                 ks_max: float | None = None):
        self.data = data
        self.ks_max = ks_max
        w = data.mask_weight.copy()
        a = data.albedo().mean(axis=-1)
        scale = 1.0 / np.maximum(a, ALBEDO_FLOOR)  # per view
        self.w = w
        self.scale = scale
        self.lam = albedo_weight
        self.y = np.nan_to_num(data.rgb)  # (V, K, 3)
        V, K = w.shape
        nr = data.wi.shape[1] if not data.transmission else data.wi.shape[1] // 2
        self.nr = nr
        # the data's own row norm: the error is reported relative to it (a black model scores 1)
        yw = self.y * w[..., None] * scale[:, None, None]
        self.yy = float(np.sum(yw ** 2) + self.lam * np.sum(yw.sum(axis=1) ** 2))
        wo = np.broadcast_to(data.wo[:, None, :], data.wi.shape)
        self.geometry = {kind: self._geometry(data.wi, wo, kind) for kind in bsdf.KINDS}
        # kd/pi on the same side only; a material without a diffuse part (a metal) has kd = 0: a zero
        # column, which the non-negative solve leaves at 0
        self.diffuse = np.where(data.wi[..., 2] >= 0.0, 1.0 / np.pi, 0.0) * w * float(diffuse)

    @staticmethod
    def _geometry(wi, wo, kind):
        """The parts of Eq. 3.4 that do not depend on (m, r0, alpha), with core/bsdf.py's guards."""
        wr = bsdf.mirror(wi) if kind == "transmit" else wi
        h, ok = bsdf.half_vector(wr, wo)
        ci, co = wr[..., 2], wo[..., 2]
        oh = bsdf.dot3(wo, h)
        hz = np.maximum(h[..., 2], bsdf.HZ_MIN)
        t2 = (h[..., 0] ** 2 + h[..., 1] ** 2) / (hz * hz)  # tan^2(theta_h) (Eq. 3.3)
        valid = ok & (ci >= 0.0) & (co >= 0.0) & (oh > 0.0) & (h[..., 2] > 0.0)
        S = (1.0 - np.clip(oh, 0.0, 1.0)) ** 5  # Schlick: F = r0 + (1 - r0) S (Eq. 2.9)
        log_shadow = np.log(np.maximum(ci, bsdf.COS_MIN) * np.maximum(co, bsdf.COS_MIN))
        base = np.where(valid, 1.0 / (np.pi * hz ** 4 * 4.0 * np.maximum(oh, bsdf.DOT_MIN)), 0.0)
        return t2, S, log_shadow, base

    def lobe_columns(self, kind: str, m, r0, alpha) -> np.ndarray:
        """(C, V, K): f_lobe x weight for C candidates (m, r0, alpha arrays of shape (C,)); Eq. 3.3-3.5."""
        t2, S, log_shadow, base = self.geometry[kind]
        m = np.maximum(np.asarray(m, float), bsdf.M_MIN)[:, None, None]
        r0 = np.asarray(r0, float)[:, None, None]
        alpha = np.asarray(alpha, float)[:, None, None]
        F = r0 + (1.0 - r0) * S
        if kind == "transmit":
            F = 1.0 - F
        D = np.exp(-t2 / (m * m)) / (m * m)  # Eq. 3.3 without 1/(pi cos^4), which is in `base`
        return F * D * np.exp(-alpha * log_shadow) * base * self.w

    def solve(self, columns: np.ndarray):
        """Non-negative least squares of the rows for every candidate: columns (C, P, V, K) ->
        (x (C, P, 3), error (C,)). P <= 4: every active set is tried (2^P solves of P x P)."""
        s = self.scale[None, None, :, None]
        A = columns * s  # shape rows
        Y = self.y * self.w[..., None] * self.scale[:, None, None]
        G = np.einsum("cpvk,cqvk->cpq", A, A)
        b = np.einsum("cpvk,vkn->cpn", A, Y)
        As = A.sum(axis=-1)  # albedo rows (C, P, V)
        Ys = Y.sum(axis=1)  # (V, 3)
        G += self.lam * np.einsum("cpv,cqv->cpq", As, As)
        b += self.lam * np.einsum("cpv,vn->cpn", As, Ys)
        C, P = G.shape[:2]
        ridge = 1e-12 * np.maximum(np.trace(G, axis1=1, axis2=2), 1e-300)
        G = G + ridge[:, None, None] * np.eye(P)
        best_x = np.zeros((C, P, 3))
        best_e = np.zeros((C, 3))  # error of x = 0: 0 relative to yy
        for active in itertools.product((False, True), repeat=P):
            idx = [p for p in range(P) if active[p]]
            if not idx:
                continue
            Gs = G[:, idx][:, :, idx]
            bs = b[:, idx]
            x = np.linalg.solve(Gs, bs)  # (C, s, 3)
            e = -2.0 * np.einsum("csn,csn->cn", x, bs) + np.einsum("csn,cst,ctn->cn", x, Gs, x)
            ok = np.all(x >= 0.0, axis=1) & (e < best_e)
            if np.any(ok):
                full = np.zeros((C, P, 3))
                full[:, idx] = x
                best_x = np.where(ok[:, None, :], full, best_x)
                best_e = np.where(ok, e, best_e)
        if self.ks_max is not None:  # the lobes' ks capped, and the error of that (feasible) solution
            best_x[:, 1:] = np.minimum(best_x[:, 1:], self.ks_max)
            best_e = -2.0 * np.einsum("cpn,cpn->cn", best_x, b) + np.einsum("cpn,cpq,cqn->cn", best_x, G, best_x)
        return best_x, (self.yy + best_e.sum(axis=-1)) / self.yy


# ----------------------------------------------------------------------------- the search

@dataclass
class _Slot:
    kind: str
    params: tuple[float, float, float] = (0.1, 0.04, 0.0)  # (m, r0, alpha)


@dataclass
class _Search:
    problem: _Problem
    progress: Callable[[int], None] | None = None
    evaluations: int = 0
    chunk: int = 96
    fixed: list = field(default_factory=list)  # columns (V, K) of the lobes held fixed
    bounds: np.ndarray = field(default_factory=lambda: BOUNDS.copy())  # (log m, r0, alpha) x (lo, hi)

    def evaluate(self, kind: str, cand: np.ndarray):
        """Errors (C,) and linear solutions of candidates cand (C, 3) = (log m, r0, alpha)."""
        errs, xs = [], []
        base = [self.problem.diffuse] + self.fixed
        for start in range(0, len(cand), self.chunk):
            c = cand[start:start + self.chunk]
            cols = self.problem.lobe_columns(kind, np.exp(c[:, 0]), c[:, 1], c[:, 2])
            stack = np.concatenate([np.broadcast_to(np.stack(base)[None], (len(c), len(base)) + cols.shape[1:]),
                                    cols[:, None]], axis=1)
            x, e = self.problem.solve(stack)
            errs.append(e)
            xs.append(x)
            self.evaluations += len(c)
            if self.progress:
                self.progress(len(c))
        return np.concatenate(errs), np.concatenate(xs)


BOUNDS = np.array([[math.log(M_RANGE[0]), math.log(M_RANGE[1])], [0.0, 1.0], [0.0, 1.0]])


def _grid(lo, hi, n=GRID_N):
    axes = [np.linspace(lo[d], hi[d], n) for d in range(3)]
    return np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=-1)


def _hierarchical(search: _Search, kind: str) -> np.ndarray:
    bounds = search.bounds
    lo, hi = bounds[:, 0].copy(), bounds[:, 1].copy()
    best, best_e = None, np.inf
    for _ in range(LEVELS):
        cand = _grid(lo, hi)
        e, _ = search.evaluate(kind, cand)
        k = int(np.argmin(e))
        if e[k] < best_e:
            best, best_e = cand[k], e[k]
        step = (hi - lo) / (GRID_N - 1)
        lo = np.maximum(best - step, bounds[:, 0])
        hi = np.minimum(best + step, bounds[:, 1])
    return best


MULTISTART_GRID = 5  # 5^3 coarse candidates ...
MULTISTART_STARTS = 4  # ... the best few polished


def _multistart(search: _Search, kind: str) -> np.ndarray:
    from scipy.optimize import minimize

    cand = _grid(search.bounds[:, 0], search.bounds[:, 1], MULTISTART_GRID)
    e, _ = search.evaluate(kind, cand)
    best, best_e = None, np.inf
    for k in np.argsort(e)[:MULTISTART_STARTS]:
        res = minimize(lambda p: float(search.evaluate(kind, p[None])[0][0]), cand[k], method="L-BFGS-B",
                       bounds=search.bounds, options={"maxiter": 60})
        if res.fun < best_e:
            best, best_e = res.x, res.fun
    return best


TWO_LOBE_M = 8  # lobe 2's m values of the residual search, log-spaced from lobe 1's to its range's top
TWO_LOBE_GRID = 5  # lobe 2's r0 and alpha values at each m
TWO_LOBE_STARTS = 3  # starts polished jointly: the residual search's best and the best others
TWO_LOBE_MIN_STEP = math.log(1.5)  # lobe 2's m at least 1.5 x lobe 1's in the residual grid (it is the wide one)
TWO_LOBE_MODES = ("joint", "in-turn")


def _two_lobes_joint(search: _Search, m2_range: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """(lobe 1, lobe 2) as (log m, r0, alpha), lobe 1 the narrow one (module docstring)."""
    from scipy.optimize import minimize

    problem = search.problem
    search.fixed = []
    first = _multistart(search, "reflect")
    lo2, hi2 = math.log(m2_range[0]), math.log(m2_range[1])
    # the joint parameters q = (log m1, r0_1, alpha_1, d, r0_2, alpha_2), log m2 = log m1 + d (d >= 0)
    bounds = np.concatenate([search.bounds, [[0.0, max(hi2 - search.bounds[0, 0], 1e-6)]],
                             search.bounds[1:]])

    def unpack(q):
        m2 = float(np.clip(q[0] + q[3], lo2, hi2))
        return q[:3], np.array([m2, q[4], q[5]])

    def pack(p1, p2):
        return np.clip(np.concatenate([p1, [p2[0] - p1[0]], p2[1:]]), bounds[:, 0], bounds[:, 1])

    # starts (a): the residual, lobe 2 over a grid of (log m, r0, alpha) with lobe 1's shape fixed at the
    # one-lobe optimum; NNLS may switch lobe 2 off, so the best of these is no worse than one lobe
    search.fixed = [problem.lobe_columns("reflect", *_params(first))[0]]
    grid_m = np.linspace(min(max(first[0] + TWO_LOBE_MIN_STEP, lo2), hi2), hi2, TWO_LOBE_M)
    r0s = np.linspace(search.bounds[1, 0], search.bounds[1, 1], TWO_LOBE_GRID)
    alphas = np.linspace(search.bounds[2, 0], search.bounds[2, 1], TWO_LOBE_GRID)
    cand = np.stack([a.ravel() for a in np.meshgrid(grid_m, r0s, alphas, indexing="ij")], axis=-1)
    e, _ = search.evaluate("reflect", cand)
    search.fixed = []
    residual = [(float(e[k]), pack(first, cand[k])) for k in np.argsort(e)[:TWO_LOBE_STARTS]]
    # starts (b): both widths over a grid (the optimum's lobe 1 is often narrower than one lobe alone),
    # r0 and alpha_1 of the one-lobe optimum, alpha_2 at three values
    pairs = []
    for m1 in np.linspace(search.bounds[0, 0], search.bounds[0, 1], TWO_LOBE_GRID - 1):
        for m2 in np.linspace(lo2, hi2, TWO_LOBE_M):
            if m2 >= m1 + TWO_LOBE_MIN_STEP or m2 >= hi2:
                for a2 in np.linspace(search.bounds[2, 0], search.bounds[2, 1], 3):
                    pairs.append(pack(np.array([m1, first[1], first[2]]), np.array([m2, first[1], a2])))
    pair_e = _joint_errors(problem, [unpack(q) for q in pairs], search)
    grid = [(float(pair_e[k]), pairs[k]) for k in np.argsort(pair_e)[:TWO_LOBE_STARTS]]
    starts = residual[:1] + sorted(residual[1:] + grid, key=lambda s: s[0])[:TWO_LOBE_STARTS]

    cache: dict[int, tuple[tuple, np.ndarray]] = {}

    def column(slot, p):  # a finite-difference step moves one lobe: the other's column is reused
        key = tuple(float(v) for v in p)
        if slot not in cache or cache[slot][0] != key:
            cache[slot] = key, problem.lobe_columns("reflect", *_params(p))[0]
        return cache[slot][1]

    def error(q):
        p1, p2 = unpack(q)
        cols = np.stack([problem.diffuse, column(0, p1), column(1, p2)])
        search.evaluations += 1
        if search.progress:
            search.progress(1)
        return float(problem.solve(cols[None])[1][0])

    # the polish sees the error relative to the one-lobe fit's: L-BFGS-B's tolerances are absolute below
    # 1, and errors of 1e-4 .. 1e-8 stopped it at its first steps
    norm = max(residual[0][0], 1e-300)
    best, best_e = None, np.inf
    for e0, q0 in starts:
        res = minimize(lambda q: error(q) / norm, q0, method="L-BFGS-B", bounds=bounds, options={"maxiter": 200})
        q, f = (res.x, res.fun * norm) if res.fun * norm <= e0 else (q0, e0)
        if f < best_e:
            best, best_e = q, f
    return unpack(best)


def _joint_errors(problem: _Problem, shapes: list, search: _Search, chunk: int = 24) -> np.ndarray:
    """The error of each pair of reflect-lobe shapes ((log m, r0, alpha) x 2), every ks solved."""
    out = []
    for start in range(0, len(shapes), chunk):
        part = shapes[start:start + chunk]
        c1 = problem.lobe_columns("reflect", *(np.exp([p[0][0] for p in part]), [p[0][1] for p in part],
                                               [p[0][2] for p in part]))
        c2 = problem.lobe_columns("reflect", *(np.exp([p[1][0] for p in part]), [p[1][1] for p in part],
                                               [p[1][2] for p in part]))
        d = np.broadcast_to(problem.diffuse[None], c1.shape)
        out.append(problem.solve(np.stack([d, c1, c2], axis=1))[1])
        search.evaluations += len(part)
    return np.concatenate(out) if out else np.zeros(0)


def expected_evaluations(lobes: int, transmission: bool, method: str = "hierarchical") -> int | None:
    """Candidates a fit evaluates (for a progress bar): known ahead for the hierarchical search only."""
    if method != "hierarchical":
        return None
    searches = (1 if lobes == 1 else 1 + 2 * (ROUNDS - 1) + 1) + (1 if transmission else 0)
    return searches * LEVELS * GRID_N ** 3


def fit(data: BrdfData, lobes: int = 1, *, method: str = METHODS[0],
        progress: Callable[[int], None] | None = None, albedo_weight: float = ALBEDO_WEIGHT,
        diffuse: bool = True, r0_range: tuple[float, float] = (0.0, 1.0), m_range: tuple[float, float] = M_RANGE,
        ks_max: float | None = None, two_lobe: str = TWO_LOBE_MODES[0],
        wide_m_range: tuple[float, float] = M_RANGE) -> FitResult:
    """Fit kd and `lobes` (1 or 2) reflection lobes, plus a transmission lobe when the data has
    transmission (module docstring). `diffuse=False`: kd is held at 0 (a metal). `r0_range`,
    `m_range`: where Schlick's r0 and Beckmann's m are searched (known physics, e.g. a metal's r0 near 1,
    keeps the search from trading r0 against ks: the albedo alone cannot tell a large ks of a small r0
    from the reverse). `ks_max`: the lobes' ks at most this (glint clamps ks to 1 where it renders and
    bakes, bake/validate.py): the search then finds the shape that needs no more. `two_lobe`: how two
    lobes are searched (module docstring; "joint" with the multistart search only), `wide_m_range`:
    where the joint search looks for lobe 2's m (never below lobe 1's). Deterministic."""
    if lobes not in (1, 2):
        raise GlintError(f"--lobes must be 1 or 2, not {lobes}")
    if method not in METHODS:
        raise GlintError(f"fit method must be one of {', '.join(METHODS)}, not {method!r}")
    t0 = time.perf_counter()
    problem = _Problem(data, albedo_weight, diffuse, ks_max)
    search = _Search(problem, progress)
    search.bounds[0] = np.log(np.clip(m_range, M_RANGE[0], M_RANGE[1]))
    search.bounds[1] = np.clip(r0_range, 0.0, 1.0)
    if two_lobe not in TWO_LOBE_MODES:
        raise GlintError(f"two-lobe search must be one of {', '.join(TWO_LOBE_MODES)}, not {two_lobe!r}")
    find = _hierarchical if method == "hierarchical" else _multistart
    slots = [_Slot("reflect") for _ in range(lobes)] + ([_Slot("transmit")] if data.transmission else [])
    found: dict[int, np.ndarray] = {}
    joint = lobes == 2 and method == "multistart" and two_lobe == "joint"
    if joint:
        wide = (max(wide_m_range[0], M_RANGE[0]), min(wide_m_range[1], M_RANGE[1]))
        found[0], found[1] = _two_lobes_joint(search, wide)
    order = [0] if lobes == 1 else ([] if joint else [0, 1] + [0, 1] * (ROUNDS - 1))
    order += [len(slots) - 1] if data.transmission else []
    for s in order:
        search.fixed = [problem.lobe_columns(slots[o].kind, *_params(found[o]))[0]
                        for o in sorted(found) if o != s]
        found[s] = find(search, slots[s].kind)
    # the final linear solve with every lobe's shape, in slot order
    cols = [problem.diffuse] + [problem.lobe_columns(slots[s].kind, *_params(found[s]))[0]
                                for s in range(len(slots))]
    x, err = problem.solve(np.stack(cols)[None])
    x = x[0]
    kd = tuple(float(v) for v in x[0])
    out = []
    for s in range(len(slots)):
        m, r0, alpha = (float(v[0]) for v in _params(found[s]))
        out.append(Lobe(kind=slots[s].kind, ks=tuple(float(v) for v in x[s + 1]), mx=m, my=m, r0=r0, alpha=alpha))
    out = [lobe for lobe in out if max(lobe.ks) > 0.0] or out[:1]  # a lobe NNLS switched off is dropped
    return FitResult(kd=kd, lobes=out, error=float(err[0]), theta_o=data.theta_o, albedo_data=data.albedo(),
                     albedo_fit=model_albedo(data, kd, out), method=method, evaluations=search.evaluations,
                     seconds=time.perf_counter() - t0)


def _params(p):
    """(log m, r0, alpha) -> arrays (m,), (r0,), (alpha,) for lobe_columns."""
    return np.array([math.exp(p[0])]), np.array([p[1]]), np.array([p[2]])


# ----------------------------------------------------------------------------- Eq. 3.7's transfer error

TRANSFER_ALBEDO_WEIGHT = 100.0  # fit_transfer: the albedo term against the transfer term, at first ...
TRANSFER_ALBEDO_TOLERANCE = 0.028  # ... then x TRANSFER_WEIGHT_STEP from the solution while the albedo misses by more
TRANSFER_WEIGHT_STEP = 3.0  # (a weight of 1000 from the start stalled L-BFGS-B on another solution: twice the
TRANSFER_WEIGHT_MAX = 1e4  # transfer error of the rough metal rows)
TRANSFER_RAISE_COST = 1.5  # ... and stops where the transfer error would grow past this factor of the first solution's
TRANSFER_KEEP = 1.1  # the caller's starts win unless another start's objective is below 1 / TRANSFER_KEEP of theirs
TRANSFER_SMOOTH = 1e-4  # |x| taken as sqrt(x^2 + (TRANSFER_SMOOTH w)^2): L-BFGS-B needs gradients
TRANSFER_KS_MIN = 1e-4  # a lobe's ks searched from here (log-spaced) to ks_max
# The starts of fit_transfer besides the caller's: lobe i's m at the given width x TRANSFER_SPREAD^i x
# the start's factor, its alpha the start's, its ks TRANSFER_KS[i == 0] (deterministic: no random numbers)
TRANSFER_SPREAD = 3.0
TRANSFER_STARTS = ((1.0, 0.3), (0.75, 0.4), (1.35, 0.2))  # (m factor, alpha)
TRANSFER_KS = (0.2, 0.6)  # (other lobes, lobe 1)


def transfer_error(data: BrdfData, lobes: list[Lobe], kd=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(V,) Eq. 3.7 per view on the grey data: sum_k |model - data| (cos theta_i dw)_k over the view's
    directional albedo. Unlike the least-squares rows of `fit`, every misplaced unit of light counts the
    same wherever it goes: the relative error of the light reflected from a room of any radiance
    distribution is at most this (an environment of radiance within [L, 2L] reflects within
    error x L of the truth), so a long tail's light sent the wrong way is no cheaper than the peak's."""
    w = data.mask_weight
    y = np.nan_to_num(data.rgb).mean(axis=-1)
    f = model_values(data, kd, lobes).mean(axis=-1)
    a = np.maximum((y * w).sum(axis=1), ALBEDO_FLOOR)
    return (np.abs(f - y) * w).sum(axis=1) / a


def fit_transfer(data: BrdfData, lobes: int, *, width: float, r0_range: tuple[float, float] = (0.0, 1.0),
                 m_range: tuple[float, float] = M_RANGE, ks_max: float = 1.0, starts: list = (),
                 albedo_weight: float = TRANSFER_ALBEDO_WEIGHT) -> FitResult:
    """`lobes` grey, isotropic reflect lobes (kd held at 0: a glTF specular layer or a metal) that minimise
    Eq. 3.7's transfer error (`transfer_error`, averaged over the views) plus albedo_weight x the mean
    square of each view's relative albedo error (issue 24: the albedo within 3 %), all parameters at once
    (L-BFGS-B, log ks and log m); the best of TRANSFER_STARTS around `width` (lobe 1's m; lobe i's
    TRANSFER_SPREAD^i wider) and of the caller's `starts` (lists of (ks, m, r0, alpha), e.g. the
    neighbouring row's solution, which keeps a table's rows one solution: preferred unless another
    start does TRANSFER_KEEP better). Where the albedo still misses by more than
    TRANSFER_ALBEDO_TOLERANCE (up to ALBEDO_DEGREES), the albedo weight is raised by TRANSFER_WEIGHT_STEP
    and the solution polished again, up to TRANSFER_WEIGHT_MAX, as long as the transfer error stays
    within TRANSFER_RAISE_COST of the first solution's (a dark metal, f0 0.2, whose Schlick rise to
    grazing the lobes' r0 near f0 cannot follow, collapsed to one lobe of three times the transfer
    error to gain its last per cent of albedo). The lobes come narrowest first.
    Why not `fit`'s least squares: on the energy each direction receives, a narrow peak's samples outweigh
    the tail's, and a rough metal's fitted tail lobe sent 26-33 % of the light the wrong way (Eq. 3.7 of
    the glTF metal of roughness 0.3), which a room's floor showed as 12 % too bright (docs/BENCHMARKS.md)."""
    from scipy.optimize import minimize

    t0 = time.perf_counter()
    problem = _Problem(data, diffuse=False)
    w, a = problem.w, np.maximum(data.albedo().mean(axis=-1), ALBEDO_FLOOR)
    y = problem.y.mean(axis=-1) * w / a[:, None]  # (V, K) the data's transfer, per unit albedo
    scale = 1.0 / a[:, None]
    smooth = (TRANSFER_SMOOTH * w * scale) ** 2
    m_lo, m_hi = (math.log(max(v, bsdf.M_MIN)) for v in m_range)
    r0_lo, r0_hi = float(np.clip(r0_range[0], 0.0, 1.0)), float(np.clip(r0_range[1], 0.0, 1.0))
    bounds = [(math.log(TRANSFER_KS_MIN), math.log(ks_max)), (m_lo, m_hi), (r0_lo, r0_hi), (0.0, 1.0)] * lobes
    evaluations = 0

    def lobes_of(x):
        p = np.asarray(x, float).reshape(lobes, 4)
        return np.exp(p[:, 0]), np.exp(p[:, 1]), p[:, 2], p[:, 3]

    keep = np.degrees(data.theta_o) <= ALBEDO_DEGREES + 1e-9

    def residual(x):
        ks, m, r0, alpha = lobes_of(x)
        return np.einsum("c,cvk->vk", ks, problem.lobe_columns("reflect", m, r0, alpha)) * scale - y

    def objective(x, weight):
        nonlocal evaluations
        evaluations += 1
        d = residual(x)
        return float(np.sqrt(d * d + smooth).sum(axis=1).mean() + weight * np.mean(d.sum(axis=1) ** 2))

    def polish(x0, weight):
        return minimize(objective, np.array(x0), args=(weight,), method="L-BFGS-B", bounds=bounds,
                        options={"maxiter": 400})

    def start(ks, m, r0, alpha):
        return [v for k in range(lobes) for v in (math.log(np.clip(ks[k], TRANSFER_KS_MIN, ks_max)),
                                                    float(np.clip(math.log(max(m[k], bsdf.M_MIN)), m_lo, m_hi)),
                                                    float(np.clip(r0[k], r0_lo, r0_hi)), float(np.clip(alpha[k], 0, 1)))]

    r0_mid = 0.5 * (r0_lo + r0_hi)
    x0s = [start([TRANSFER_KS[k == 0] for k in range(lobes)], [width * factor * TRANSFER_SPREAD ** k for k in range(lobes)],
                 [r0_mid] * lobes, [alpha] * lobes) for factor, alpha in TRANSFER_STARTS]
    own = [polish(x0, albedo_weight) for x0 in x0s]
    given = [polish(start(*zip(*lobes_given)), albedo_weight) for lobes_given in starts if len(lobes_given) == lobes]
    best = min(own + given, key=lambda r: r.fun)
    if given and min(r.fun for r in given) <= TRANSFER_KEEP * best.fun:
        best = min(given, key=lambda r: r.fun)
    def figures(x):
        """Eq. 3.7 averaged over the views, and the worst albedo miss up to ALBEDO_DEGREES."""
        d = residual(x)
        return float(np.abs(d).sum(axis=1).mean()), float(np.max(np.abs(d.sum(axis=1)[keep])))

    weight, (first, miss) = albedo_weight, figures(best.x)
    while miss > TRANSFER_ALBEDO_TOLERANCE and weight < TRANSFER_WEIGHT_MAX:
        weight *= TRANSFER_WEIGHT_STEP
        raised = polish(best.x, weight)
        transfer, raised_miss = figures(raised.x)
        if transfer > TRANSFER_RAISE_COST * first:
            break
        best, miss = raised, raised_miss
    ks, m, r0, alpha = lobes_of(best.x)
    order = np.argsort(m, kind="stable")
    out = [Lobe("reflect", (float(ks[k]),) * 3, float(m[k]), float(m[k]), float(r0[k]), float(alpha[k]))
           for k in order]
    kd = (0.0, 0.0, 0.0)
    return FitResult(kd=kd, lobes=out, error=float(transfer_error(data, out).mean()), theta_o=data.theta_o,
                     albedo_data=data.albedo(), albedo_fit=model_albedo(data, kd, out), method="transfer",
                     evaluations=evaluations, seconds=time.perf_counter() - t0)
