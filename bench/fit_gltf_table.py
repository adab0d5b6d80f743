"""Fit the section 3.3 model to the glTF BRDF and write the table glint maps glTF materials through.

    python3 -m glint.bench.fit_gltf_table [--out bake/gltf_fit_table.npz] [--report docs/bench/gltf-fit/table.md]
        [--jobs N]

The reference is core/gltf_brdf.py (the glTF specification's Appendix B, written without glint's
model); the fit is bake/brdf_fit.py (thesis 3.4.1: albedo per view angle plus lobe shape, multi-start
least squares; rough metal rows by Eq. 3.7, below). What the table holds and how it is read: bake/gltf_fit_table.py. Rows:

- glTF's specular BRDF with Schlick's Fresnel of normal-incidence reflectance f0 alone, kd held at 0,
  for each f0 of F0 and each roughness of FITTED: a metal of grey base colour f0 (conductor_fresnel),
  which for f0 < 1 is also the specular layer of a dielectric of that f0 (base colour 0);
- rough rows have two solutions of similar error (a narrow Beckmann lobe with alpha ~ 0.5, or a wide
  one with alpha ~ 0.2 and a large ks), and the search takes the better, so that neighbouring rows may
  be different solutions (white metal: m 0.22 at roughness 0.5, 0.71 at 0.6): bake/gltf_fit_table.py
  interpolates only between rows of one solution. Following one solution instead (each row's search
  started from its neighbour's) kept the narrow lobe to roughness 1, 15 % off the albedo there;
- three lobes where one Beckmann lobe cannot follow GGX's long tail: the rows of roughness MULTI_LOBE
  (0.2 to 0.7) with f0 at least MULTI_LOBE_F0 (0.2: metals) get LOBES lobes fitted by bake/brdf_fit.py
  `fit_transfer`, all at once, to Eq. 3.7's transfer error (the light each view sends the wrong way)
  with its albedo held within 2.8 % (brdf_fit.py TRANSFER_ALBEDO_TOLERANCE); each row starts, besides the fixed
  starts, from the row below's solution (m scaled by the roughness squared), so that a row's lobe k is
  its neighbour's lobe k and the table interpolates lobe by lobe. Why: the least-squares fit of one or
  two lobes (a narrow lobe and a tail) matched the albedo within 2 % but sent 26-33 % of a rough metal's
  light the wrong way (the tail 1.5 to 3.9 times GGX's past 45 degrees), and the glTF metal floor of
  roughness 0.3 read 12 % too bright in its room, path traced (docs/BENCHMARKS.md, "Issue 24: three
  lobes fitted to Eq. 3.7"). Two lobes fitted to Eq. 3.7 leave about 10 % of the light misplaced at
  every view and read that floor 8 % dark; three, 3-5 % up to 70 degrees. A dielectric's specular layer
  (f0 0.02-0.12) keeps one lobe (a lobe costs samples per pixel on every glossy floor and painted wall,
  and its layer is a few per cent of what it reflects); above 0.7 one lobe too: the fit puts two of the
  three lobes at m = 1, the widest Beckmann lobe it allows;
- below FITTED[0] (GGX alpha 0.0025) the lobe is a mirror at any screen resolution, and narrower
  than the fit's quadrature resolves (its directional albedo came out 10 % low at roughness 0): those
  rows keep FITTED[0]'s ks, r0 and alpha, with m scaled by (r / FITTED[0])^2 (Beckmann m ~ GGX alpha);
- the specular layer's albedo by the reference under uniform light (its directional albedo weighted
  by cos(theta_o) over the hemisphere), per row (MIRRORS' rows: FITTED[0]'s);
- the diffuse share of each f0: the reference's directional albedo of base colour 1 minus that of
  base colour 0 (the diffuse term of fresnel_mix alone), averaged over view angles 0 to 80 degrees.

The report lists, per row, the fit's error, the directional albedo of the fitted lobes by core/bsdf.py
against the reference's at 0, 45, 60, 70 and 80 degrees, and the worst miss of the one-lobe fit beside
that of the row as shipped, and each row's transfer error (Eq. 3.7) at those angles. Takes about
6 minutes with --jobs 2 on the 2-core machine (144 one-lobe fits of a few seconds; for 5 f0, 8 three-lobe
fits of 3 to 25 s in a row).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from glint.bake.brdf_fit import BrdfData, fit, fit_transfer, transfer_error
from glint.bake.gltf_fit_table import LOBES, TABLE_FILE, FitTable
from glint.core import bsdf
from glint.core.atomic import atomic_path, atomic_write_text
from glint.core.gltf_brdf import GltfMaterialParams, directional_albedo, evaluate
from glint.parallel.executor import LocalExecutor

FITTED = (0.05, 0.075, 0.1, 0.125, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
MIRRORS = (0.0, 0.025)  # rows derived from FITTED[0] (module docstring)
F0 = (0.02, 0.04, 0.07, 0.12, 0.2, 0.35, 0.5, 0.7, 1.0)
CHECK_DEGREES = (0, 45, 60, 70, 80)
# Where r0 is searched: within 15 % of the Fresnel reflectance the reference has at normal incidence,
# f0. Unbounded, rough rows traded a small r0 for a large ks (white metal, roughness 0.8: ks 15.8,
# r0 0.09), which matched the albedo, but rows of neighbouring f0 then disagreed (r0 0.39 and 1.0 at
# f0 0.7 and 1, roughness 0.6): a lobe between them reflected 1.5 at normal incidence.
R0_RANGE = (0.85, 1.15)  # times f0, at most 1
# Beckmann m searched within these factors of r^2 (GGX alpha): unbounded, the roughest white metal
# row went to m 0.11 with alpha 0.75 while its neighbour kept m 0.93 (the same albedo, another shape).
M_RANGE = (0.5, 2.0)
MULTI_LOBE = (0.2, 0.7)  # rows of roughness in this range get LOBES lobes fitted to Eq. 3.7 ...
MULTI_LOBE_F0 = 0.2  # ... where f0 is at least this: a dielectric's layer (f0 0.02-0.12) keeps one lobe (module docstring)
DIFFUSE_DEGREES = tuple(range(0, 81, 5))
HEMISPHERE_NODES = 12
ROOT = Path(__file__).resolve().parents[1]


def ior_for(f0: float) -> float:
    """The ior whose normal-incidence reflectance ((n - 1) / (n + 1))^2 is f0."""
    s = np.sqrt(f0)
    return float((1 + s) / (1 - s))


def specular_layer(roughness: float, f0: float) -> GltfMaterialParams:
    """glTF's specular BRDF with Schlick's f0 alone: a grey metal of base colour f0 (module docstring)."""
    return GltfMaterialParams(base_color=(f0, f0, f0), metallic=1.0, roughness=roughness)


def dielectric(f0: float, base: float) -> GltfMaterialParams:
    return GltfMaterialParams(base_color=(base, base, base), metallic=0.0, roughness=0.5, ior=ior_for(f0))


def bounds_of(f0: float, r: float) -> dict:
    """Where a row's r0 and m are searched (R0_RANGE, M_RANGE)."""
    return dict(r0_range=(R0_RANGE[0] * f0, min(R0_RANGE[1] * f0, 1.0)), m_range=(M_RANGE[0] * r * r, M_RANGE[1] * r * r))


def multi_lobe(f0: float, r: float) -> bool:
    return MULTI_LOBE[0] <= r <= MULTI_LOBE[1] and f0 >= MULTI_LOBE_F0


def fit_row(params: GltfMaterialParams, below: tuple[np.ndarray, float] | None = None) -> tuple[np.ndarray, dict]:
    """One row: the fitted lobes (LOBES, 4) of (ks, m, r0, alpha), ks 0 past the lobes it has (their
    shape a copy of lobe 1's), and its errors. `below`: the row of the next smaller roughness and that
    roughness (a start of a multi-lobe fit, module docstring)."""
    data = BrdfData.from_function(lambda wi, wo: evaluate(params, wi, wo))
    r, f0 = params.roughness, params.base_color[0]
    bounds = bounds_of(f0, r)
    one = fit(data, lobes=1, method="multistart", diffuse=False, ks_max=1.0, **bounds)
    result = one
    if multi_lobe(f0, r):
        starts = []
        if below is not None and below[0][-1, 0] > 0:  # the row below's lobes, m scaled as GGX alpha = r^2
            starts.append([(ks, m * (r / below[1]) ** 2, r0, alpha) for ks, m, r0, alpha in below[0]])
        result = fit_transfer(data, LOBES, width=r * r, ks_max=1.0, starts=starts,
                              m_range=(bounds["m_range"][0], 1.0), r0_range=bounds["r0_range"])
    lobes = [np.array([float(np.mean(lb.ks)), lb.mx, lb.r0, lb.alpha]) for lb in result.lobes]
    while len(lobes) < LOBES:
        lobes.append(np.array([0.0, *lobes[0][1:]]))
    transfer = transfer_error(data, result.lobes)
    return np.stack(lobes), {"error": result.error, "albedo_error": result.albedo_error,
                             "one_lobe_error": one.error, "one_lobe_albedo_error": one.albedo_error,
                             "transfer": np.interp(np.radians(CHECK_DEGREES), data.theta_o, transfer).tolist()}


def with_mirrors(rows: list[np.ndarray]) -> np.ndarray:
    """FITTED's rows with MIRRORS' in front (module docstring)."""
    first = rows[0]  # (LOBES, 4): one lobe at FITTED[0] (below MULTI_LOBE)
    mirrors = []
    for r in MIRRORS:
        row = first.copy()
        row[:, 1] = np.maximum(first[:, 1] * (r / FITTED[0]) ** 2, bsdf.M_MIN)
        mirrors.append(row)
    return np.stack(mirrors + rows)


def mean_albedo(params: GltfMaterialParams) -> float:
    """The reference's grey directional albedo averaged over DIFFUSE_DEGREES."""
    return float(np.mean([np.mean(directional_albedo(params, np.radians(d))) for d in DIFFUSE_DEGREES]))


def hemispherical_albedo(params: GltfMaterialParams) -> float:
    """The reference's grey albedo under uniform light, 2 int A(mu) mu dmu over mu = cos(theta_o) in
    [0, 1] (Gauss-Legendre, HEMISPHERE_NODES): the share of diffuse light it reflects."""
    mu, w = np.polynomial.legendre.leggauss(HEMISPHERE_NODES)
    mu, w = 0.5 * (mu + 1.0), 0.5 * w
    return float(sum(2.0 * wk * mk * np.mean(directional_albedo(params, np.arccos(mk))) for mk, wk in zip(mu, w)))


def diffuse_share(f0: float) -> float:
    """(f0 = 1 has no diffuse term: an ior of infinity.)"""
    if f0 >= 1.0:
        return 0.0
    return mean_albedo(dielectric(f0, 1.0)) - mean_albedo(dielectric(f0, 0.0))


def lobe_check(row: np.ndarray, params: GltfMaterialParams) -> tuple[list[float], list[float]]:
    """Directional albedo of the fitted lobes (core/bsdf.py) and of the reference at CHECK_DEGREES."""
    ours, ref = [], []
    for degrees in CHECK_DEGREES:
        t = np.radians(degrees)
        wo = np.array([np.sin(t), 0.0, np.cos(t)])
        ours.append(float(sum(ks * bsdf.lobe_albedo(wo, m, m, r0, alpha, "reflect")
                              for ks, m, r0, alpha in row if ks > 0)))
        ref.append(float(np.mean(directional_albedo(params, t))))
    return ours, ref


def _no_state():
    return None


def _fit_task(_state, task):
    """Rows on a worker (parallel/executor.py): task (f0, (roughness, ...)) -> [(row, info), ...], the
    multi-lobe rows of one f0 in one task, in order of roughness (each starts from the one before)."""
    f0, roughnesses = task
    out, below = [], None
    for r in roughnesses:
        row, info = fit_row(specular_layer(r, f0), below)
        below = (row, r)
        out.append((row, info))
    return out


def build(progress=print, jobs: int = 1) -> tuple[FitTable, list[str]]:
    started = time.perf_counter()
    multi = [(f0, tuple(r for r in FITTED if multi_lobe(f0, r))) for f0 in F0]
    tasks = [task for task in multi if task[1]] + [(f0, (r,)) for f0 in F0 for r in FITTED if not multi_lobe(f0, r)]
    results: dict[tuple[float, float], tuple[np.ndarray, dict]] = {}
    with LocalExecutor(jobs) as executor:  # tasks on `jobs` processes, as they finish
        for index, rows_done in executor.run(_no_state, (), _fit_task, tasks):
            f0 = tasks[index][0]
            for r, result in zip(tasks[index][1], rows_done):
                results[(f0, r)] = result
                progress(f"[{len(results)}/{len(F0) * len(FITTED)}, {time.perf_counter() - started:.0f} s] f0 {f0}, "
                         f"roughness {r}: lobes {np.round(result[0], 4).tolist()}, fit error "
                         f"{result[1]['one_lobe_error']:.2e} (one lobe) / {result[1]['error']:.2e}")
    lines = []
    rows = {}
    for f0, r in [(f0, r) for f0 in F0 for r in FITTED]:
        row, info = results[(f0, r)]
        params = specular_layer(r, f0)
        ours, ref = lobe_check(row, params)
        worst = max(abs(a - b) / max(b, 1e-6) for a, b in zip(ours, ref))
        (ks, m, r0, alpha), others = row[0], row[1:]
        more = "; ".join(f"{k2:.4f} / {m2:.4f} / {r2:.4f} / {a2:.3f}" for k2, m2, r2, a2 in others if k2 > 0) or "-"
        lines.append(f"| f0 {f0}, roughness {r} | {ks:.4f} | {m:.5f} | {r0:.4f} | {alpha:.3f} | {more} | "
                     f"{info['one_lobe_error']:.2e} / {info['error']:.2e} | "
                     + " | ".join(f"{a:.3f} / {b:.3f}" for a, b in zip(ours, ref)) + f" | {100 * worst:.1f} % | "
                     f"{100 * info['one_lobe_albedo_error']:.1f} % / {100 * info['albedo_error']:.1f} % | "
                     + " / ".join(f"{t:.2f}" for t in info["transfer"]) + " |")
        rows.setdefault(f0, []).append(row)
    specular = [with_mirrors(rows[f0]) for f0 in F0]
    roughness = MIRRORS + FITTED
    albedo = np.array([[hemispherical_albedo(specular_layer(max(r, FITTED[0]), f0)) for r in roughness]
                       for f0 in F0])
    table = FitTable(roughness=np.array(roughness), f0=np.array(F0), specular=np.stack(specular),
                     specular_albedo=albedo, diffuse=np.array([diffuse_share(f0) for f0 in F0]))
    return table, lines


def report(table: FitTable, lines: list[str], command: str) -> str:
    head = ("| material | ks | m | r0 | alpha | lobes 2, 3: ks / m / r0 / alpha | fit error | "
            + " | ".join(f"{d} deg fit / ref" for d in CHECK_DEGREES)
            + " | worst | fit's albedo miss, one lobe / shipped | transfer error (Eq. 3.7) at "
            + ", ".join(str(d) for d in CHECK_DEGREES) + " deg |\n|" + "---|" * (10 + len(CHECK_DEGREES)) + "\n")
    shares = ", ".join(f"f0 {f0}: {s:.4f}" for f0, s in zip(table.f0, table.diffuse))
    return (f"# The glTF BRDF fitted by the section 3.3 model\n\nMade by `{command}` (bench/fit_gltf_table.py; "
            "what the columns mean: its docstring). Directional albedo: the fitted lobe by core/bsdf.py "
            "`lobe_albedo` against core/gltf_brdf.py `directional_albedo` (grey mean), the row's lobes summed. "
            f"A row of roughness {MULTI_LOBE[0]} to {MULTI_LOBE[1]} and f0 of at least {MULTI_LOBE_F0} has {LOBES} lobes "
            "fitted to Eq. 3.7 (the column `fit error`: the one-lobe fit's least squares / the shipped row's error, "
            "Eq. 3.7's mean over the views for those rows); `fit's albedo miss`: the worst on the fit's quadrature "
            "(0-80 degrees), one-lobe fit / shipped row; the last column: the share of each view's light the shipped "
            "row sends the wrong way (core/gltf_brdf.py against core/bsdf.py).\n\n"
            f"Diffuse share (kd = base colour x share): {shares}.\n\n" + head + "\n".join(lines) + "\n")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python3 -m glint.bench.fit_gltf_table", description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "bake" / TABLE_FILE)
    parser.add_argument("--report", type=Path, default=ROOT / "docs" / "bench" / "gltf-fit" / "table.md")
    parser.add_argument("--jobs", type=int, default=1, help="rows fitted on this many processes (default 1)")
    args = parser.parse_args(argv)
    table, lines = build(jobs=args.jobs)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(args.out) as tmp:
        table.save(tmp)
    args.report.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.report, report(table, lines, "python3 -m glint.bench.fit_gltf_table"))
    print(f"wrote {args.out} and {args.report}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
