"""The glTF BRDF fitted by the section 3.3 model: the table glTF materials are mapped through.

glTF's metallic-roughness BRDF (GGX, height-correlated Smith, Schlick; core/gltf_brdf.py) is not
the thesis' model (Kurt et al.'s Beckmann lobes, Eq. 3.3-3.4), so a glTF material's lobe cannot
be written down from its factors: with Kurt's alpha = 0 a narrow lobe's directional albedo falls
like F cos(theta_o) and a glossy floor lost most of its reflection at the angles a walkthrough sees
it (issue 24). As the thesis does with measured data (3.4.1), the lobes are *fitted* to the BRDF,
once, offline, by `python3 -m glint.bench.fit_gltf_table` (bake/brdf_fit.py on the reference), and
shipped as gltf_fit_table.npz next to this module; loading a scene only interpolates it.

The table holds, for glTF roughness r on the grid `roughness` and normal-incidence reflectance f0 on
the grid `f0`:
- `specular`: (F, R, LOBES, 4) one or three reflect lobes (ks, m, r0, alpha) fitted to glTF's specular
  BRDF weighted by Schlick's Fresnel with that f0 alone (kd held at 0). It is a dielectric's specular
  layer (f0 from its ior: 0.04 for glTF's default 1.5) and, as glTF's conductor_fresnel is the same
  Schlick term with f0 = base colour, a grey metal of that base colour (f0 = 1: a white metal). Rough
  metal rows have three, narrowest first, which together follow GGX's long tail that one Beckmann lobe
  cannot (issue 24; bench/fit_gltf_table.py, `MULTI_LOBE`); elsewhere lobes 2 and 3 have ks 0 (their
  shape a copy of lobe 1's), and `specular_lobes` leaves them out: every lobe costs the viewer
  samples per pixel. Lobes of one shape (a fit that put two at the widest m) are returned as one.
- `specular_albedo`: (F, R) that BRDF's albedo by the reference under uniform light (directional
  albedo weighted by cos(theta_o) over the hemisphere): what a rough dielectric's dropped lobe adds
  to kd (bake/material_mapping.py), the light it would have reflected of a diffuse room's.
- `diffuse`: (F,) the share of the base colour that fresnel_mix leaves to the diffuse term,
  averaged over view angles 0-80 degrees (it hardly depends on the angle: 0.960 to 0.944 for f0 0.04,
  and not on the roughness): kd = base colour x `diffuse`.
Between two rows, in r and then in f0: where both rows have three lobes (fitted in order of roughness,
each row from its neighbour, and ordered narrowest first, so lobe k of one row is lobe k of the
other), each lobe's parameters are interpolated linearly (m through sqrt(m), about linear in r as
m ~ r^2). Between a one-lobe and a three-lobe row (roughness 0.15 to 0.2 and 0.7 to 0.8 of a metal;
f0 0.12 to 0.2) the two rows' BRDFs are mixed: both rows' lobes, ks times 1 - t and t, continuous and
exact in albedo, for up to four lobes there (five between f0 0.12 and 0.2 at roughness 0.15-0.2). Between two one-lobe rows, where lobe 1 of both is
one solution of the fit (their alpha within SAME_ALPHA, their m in the ratio r^2 predicts within a
factor 2), its parameters are interpolated linearly. One-lobe rough rows have two solutions of similar
error (a narrow lobe with alpha ~ 0.5, a wide one with alpha ~ 0.2 and a large ks) and neighbouring
rows may hold different ones; a lobe halfway between the two is neither, so there the nearer row's
lobes are taken, their ks scaled to the interpolated albedo (`specular_albedo`). How well the table matches the reference, per
material and view angle: docs/bench/gltf-fit/table.md.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from importlib import resources

import numpy as np

from glint.core.errors import GlintError

TABLE_FILE = "gltf_fit_table.npz"
FORMAT = 3  # 2: two lobes per row; 3: three (issue 24)
LOBES = 3  # lobes per row of `specular`


@dataclass(frozen=True)
class FittedLobe:
    """One reflect lobe of Eq. 3.4 (isotropic: mx = my = m), ks grey."""

    ks: float
    m: float
    r0: float
    alpha: float


@dataclass(frozen=True)
class FitTable:
    roughness: np.ndarray  # (R,) increasing, 0 ... 1
    f0: np.ndarray  # (F,) increasing, up to 1
    specular: np.ndarray  # (F, R, LOBES, 4) ks, m, r0, alpha; narrowest first, ks 0 past a row's lobes
    specular_albedo: np.ndarray  # (F, R)
    diffuse: np.ndarray  # (F,)

    def specular_lobes(self, roughness: float, f0: float) -> tuple[FittedLobe, ...]:
        """The lobes (one to five, see the module docstring) of glTF's specular BRDF with Schlick's
        Fresnel of normal-incidence reflectance f0; below the grid's first f0, its row with r0 scaled by
        f0 / f0_row (the fitted r0 follows f0). A lobe whose ks is 0 is left out, lobes of one shape are one."""
        i, j, t = _bracket(self.f0, f0)
        a, albedo_a = self._along_roughness(i, roughness)
        b, albedo_b = self._along_roughness(j, roughness)
        lobes = _between(a, b, t, albedo_a, albedo_b, 1.0)
        row = float(np.clip(f0, self.f0[0], self.f0[-1]))
        if row != f0:
            lobes = tuple(FittedLobe(lb.ks, lb.m, float(np.clip(lb.r0 * f0 / row, 0.0, 1.0)), lb.alpha)
                          for lb in lobes)
        return _merged(lobes)

    def _along_roughness(self, f: int, roughness: float) -> tuple[tuple[FittedLobe, ...], float]:
        """Row f0[f]'s lobes at `roughness` (those with ks > 0), and their albedo."""
        k, l, u = _bracket(self.roughness, roughness)
        a, b = (tuple(FittedLobe(*map(float, lobe)) for lobe in self.specular[f, n] if lobe[0] > 0)
                or (FittedLobe(*map(float, self.specular[f, n, 0])),) for n in (k, l))
        albedo_a, albedo_b = self.specular_albedo[f, k], self.specular_albedo[f, l]
        r_a, r_b = self.roughness[k], self.roughness[l]
        m_ratio = (r_b / r_a) ** 2 if r_a > 0 else b[0].m / a[0].m  # the rows below FITTED[0] scale m so
        return _between(a, b, u, albedo_a, albedo_b, m_ratio), float((1 - u) * albedo_a + u * albedo_b)

    def specular_albedo_at(self, roughness: float, f0: float) -> float:
        """That BRDF's albedo under uniform light, `specular_albedo` interpolated (below the grid's first
        f0: scaled by f0 / f0_row)."""
        i, j, t = _bracket(self.f0, f0)
        k, l, u = _bracket(self.roughness, roughness)
        rows = self.specular_albedo
        value = (1 - t) * ((1 - u) * rows[i, k] + u * rows[i, l]) + t * ((1 - u) * rows[j, k] + u * rows[j, l])
        row = float(np.clip(f0, self.f0[0], self.f0[-1]))
        return float(value * f0 / row)

    def diffuse_share(self, f0: float) -> float:
        i, j, t = _bracket(self.f0, f0)
        return float((1 - t) * self.diffuse[i] + t * self.diffuse[j])

    def save(self, path) -> None:
        with open(path, "wb") as f:  # a file, so that numpy adds no suffix of its own
            np.savez(f, format=np.array(FORMAT), **{k: getattr(self, k) for k in FIELDS})


FIELDS = ("roughness", "f0", "specular", "specular_albedo", "diffuse")


SAME_ALPHA = 0.15  # two rows whose alpha differ by more are two solutions (module docstring)
SAME_SHAPE = 1e-3  # two lobes whose m (relative), r0 and alpha differ by less are one shape (`_merged`)


def _lerp(a: FittedLobe, b: FittedLobe, t: float) -> FittedLobe:
    """Each parameter linearly, m through sqrt(m) (about linear in r: m ~ r^2)."""
    root_m = (1 - t) * np.sqrt(a.m) + t * np.sqrt(b.m)
    return FittedLobe(float((1 - t) * a.ks + t * b.ks), float(root_m * root_m),
                      float((1 - t) * a.r0 + t * b.r0), float((1 - t) * a.alpha + t * b.alpha))


def _between(a: tuple[FittedLobe, ...], b: tuple[FittedLobe, ...], t: float, albedo_a: float, albedo_b: float,
             m_ratio: float) -> tuple[FittedLobe, ...]:
    """The lobes a fraction t from row a to row b (module docstring; each row's lobes with ks > 0,
    narrowest first); `m_ratio`: b.m / a.m of lobe 1 expected of one solution."""
    if t <= 0.0 or t >= 1.0:
        return a if t <= 0.0 else b
    if len(a) > 1 and len(a) == len(b):  # ordered lobes on both sides: lobe by lobe
        return tuple(_lerp(x, y, t) for x, y in zip(a, b))
    if len(a) != len(b):  # one lobe and three: the two BRDFs mixed
        return tuple(FittedLobe(lb.ks * w, lb.m, lb.r0, lb.alpha) for lbs, w in ((a, 1 - t), (b, t)) for lb in lbs)
    (a1,), (b1,) = a, b
    if abs(a1.alpha - b1.alpha) <= SAME_ALPHA and 0.5 <= (b1.m / a1.m) / m_ratio <= 2.0:  # one solution
        return (_lerp(a1, b1, t),)
    near, albedo_near = (a, albedo_a) if t < 0.5 else (b, albedo_b)
    scale = ((1 - t) * albedo_a + t * albedo_b) / max(albedo_near, 1e-9)
    return tuple(FittedLobe(float(lb.ks * scale), lb.m, lb.r0, lb.alpha) for lb in near)


def _merged(lobes: tuple[FittedLobe, ...]) -> tuple[FittedLobe, ...]:
    """`lobes` with ks > 0, those of one shape (m, r0, alpha within SAME_SHAPE) summed into one: a fit may
    put two lobes at the widest m, and a lobe costs the viewer samples per pixel."""
    out: list[FittedLobe] = []
    for lb in lobes:
        if lb.ks <= 0.0:
            continue
        twin = next((k for k, o in enumerate(out) if abs(o.m - lb.m) <= SAME_SHAPE * o.m
                     and abs(o.r0 - lb.r0) <= SAME_SHAPE and abs(o.alpha - lb.alpha) <= SAME_SHAPE), None)
        if twin is None:
            out.append(lb)
        else:
            o = out[twin]
            out[twin] = FittedLobe(o.ks + lb.ks, o.m, o.r0, o.alpha)
    return tuple(out) or lobes[:1]


def _bracket(grid: np.ndarray, x: float) -> tuple[int, int, float]:
    """Indices i <= j around x on `grid` and the weight of j (clamped at the ends)."""
    x = float(np.clip(x, grid[0], grid[-1]))
    j = int(np.clip(np.searchsorted(grid, x), 1, len(grid) - 1))
    i = j - 1
    t = (x - grid[i]) / (grid[j] - grid[i])
    return i, j, float(t)


@cache
def fit_table() -> FitTable:
    """The shipped table (read once)."""
    try:
        with resources.files("glint.bake").joinpath(TABLE_FILE).open("rb") as f:
            data = np.load(f)
            if int(data["format"]) != FORMAT:
                raise GlintError(f"{TABLE_FILE}: format {int(data['format'])}, expected {FORMAT}; reinstall glint")
            return FitTable(*(np.array(data[k], np.float64) for k in FIELDS))
    except (OSError, KeyError, ValueError) as e:
        raise GlintError(f"glint's fitted glTF table {TABLE_FILE} cannot be read ({e}); reinstall glint") from None
