"""Fit the section 3.3 model to the glTF BRDF and write the table glint maps glTF materials through.

    python3 -m glint.bench.fit_gltf_table [--out bake/gltf_fit_table.npz] [--report docs/bench/gltf-fit/table.md]
        [--jobs N]

The reference is core/gltf_brdf.py (the glTF specification's Appendix B, written without glint's
model); the fit is bake/brdf_fit.py (thesis 3.4.1: albedo per view angle plus lobe shape, multi-start
least squares). What the table holds and how it is read: bake/gltf_fit_table.py. Rows:

- glTF's specular BRDF with Schlick's Fresnel of normal-incidence reflectance f0 alone, kd held at 0,
  for each f0 of F0 and each roughness of FITTED: a metal of grey base colour f0 (conductor_fresnel),
  which for f0 < 1 is also the specular layer of a dielectric of that f0 (base colour 0);
- rough rows have two solutions of similar error (a narrow Beckmann lobe with alpha ~ 0.5, or a wide
  one with alpha ~ 0.2 and a large ks), and the search takes the better, so that neighbouring rows may
  be different solutions (white metal: m 0.22 at roughness 0.5, 0.71 at 0.6): bake/gltf_fit_table.py
  interpolates only between rows of one solution. Following one solution instead (each row's search
  started from its neighbour's) kept the narrow lobe to roughness 1, 15 % off the albedo there;
- a second lobe, the tail (bake/brdf_fit.py's joint two-lobe search; lobe 1 kept the narrow one),
  where one Beckmann lobe cannot follow GGX's long tail: a row of roughness TWO_LOBES (0.2 to 0.7)
  gets it when the two-lobe fit's error is at most TWO_LOBES_GAIN (2/3) of the one-lobe fit's and
  its f0 is at least TWO_LOBES_F0 (0.2: metals; a dielectric's specular layer, f0 0.02-0.12, keeps
  one lobe: the tail made its albedo 1.0 % instead of 1.2 % off the specification's, for a lobe of
  samples per pixel more on every glossy floor and painted wall, and it took the staircase from
  96.5 % to 95.1 % of blocks within half a stop: docs/BAKE.md);
  elsewhere one lobe (every lobe costs the viewer samples per pixel; below 0.2 the smooth metal floor
  already reads Mitsuba's within 1 % bias). Lobe 2's m is searched in TAIL_M: from 4 r^2 (at most
  0.5) to 1, its r0 in lobe 1's range. A tail lobe, not the narrower second lobe the fit's error
  alone prefers (m2 ~ 2 m1; error 3.9e-5 against 5.9e-5 for the white metal at roughness 0.3): with
  that one the glTF metal floor of roughness 0.3 stayed 14 % dark against Mitsuba, with the tail
  lobe 1.5 % (converged) and 3.7 % (walkthrough) (docs/BENCHMARKS.md, issue 24). Above 0.7 one lobe: lobe 1 is already near m = 1, the
  widest Beckmann lobe the fit allows, the gain is small and patchy (white metal at 0.8 two lobes,
  0.7 and 0.9 of f0 one), and between a two-lobe row and a one-lobe row whose lobe 1 differs (m 0.52
  and 0.83) a grey 0.9 metal of roughness 0.8 read 6 % bright at normal view (docs/SCENES.md);
- below FITTED[0] (GGX alpha 0.0025) the lobe is a mirror at any screen resolution, and narrower
  than the fit's quadrature resolves (its directional albedo came out 10 % low at roughness 0): those
  rows keep FITTED[0]'s ks, r0 and alpha, with m scaled by (r / FITTED[0])^2 (Beckmann m ~ GGX alpha);
- the specular layer's albedo by the reference under uniform light (its directional albedo weighted
  by cos(theta_o) over the hemisphere), per row (MIRRORS' rows: FITTED[0]'s);
- the diffuse share of each f0: the reference's directional albedo of base colour 1 minus that of
  base colour 0 (the diffuse term of fresnel_mix alone), averaged over view angles 0 to 80 degrees.

The report lists, per row, the fit's error, the directional albedo of the fitted lobes by core/bsdf.py
against the reference's at 0, 45, 60, 70 and 80 degrees, and the worst miss of the one-lobe fit beside
that of the row as shipped. Takes about 25 minutes with --jobs 2 on the 2-core machine under load (144
one-lobe fits of a few seconds, 72 two-lobe fits of 5 to 30 s).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from glint.bake.brdf_fit import BrdfData, fit
from glint.bake.gltf_fit_table import TABLE_FILE, FitTable
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
TWO_LOBES = (0.2, 0.7)  # rows of roughness in this range try lobe 2 (module docstring) ...
TWO_LOBES_GAIN = 2.0 / 3.0  # ... and keep it when the two-lobe fit's error is at most this share of one lobe's
TWO_LOBES_F0 = 0.2  # ... and f0 is at least this: a dielectric's layer (f0 0.02-0.12) keeps one lobe (module docstring)
TAIL_M = (4.0, 0.5)  # lobe 2's m from min(4 r^2, 0.5) to 1 (module docstring)
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


def fit_row(params: GltfMaterialParams, r0_range: tuple[float, float]) -> tuple[np.ndarray, dict]:
    """One row: the fitted lobes (2, 4) of (ks, m, r0, alpha), lobe 2's ks 0 where one lobe is kept
    (its shape then lobe 1's), and the fits' errors (module docstring: when a row gets lobe 2)."""
    data = BrdfData.from_function(lambda wi, wo: evaluate(params, wi, wo))
    r = params.roughness
    bounds = dict(method="multistart", diffuse=False, r0_range=r0_range,
                  m_range=(M_RANGE[0] * r * r, M_RANGE[1] * r * r), ks_max=1.0)
    result = one = fit(data, lobes=1, **bounds)
    if TWO_LOBES[0] <= r <= TWO_LOBES[1] and params.base_color[0] >= TWO_LOBES_F0:
        two = fit(data, lobes=2, wide_m_range=(min(TAIL_M[0] * r * r, TAIL_M[1]), 1.0), **bounds)
        if len(two.lobes) == 2 and two.error <= TWO_LOBES_GAIN * one.error:
            result = two
    lobes = [np.array([float(np.mean(lb.ks)), lb.mx, lb.r0, lb.alpha]) for lb in result.lobes]
    if len(lobes) == 1:
        lobes.append(np.array([0.0, *lobes[0][1:]]))
    return np.stack(lobes), {"error": result.error, "albedo_error": result.albedo_error,
                             "one_lobe_error": one.error, "one_lobe_albedo_error": one.albedo_error}


def with_mirrors(rows: list[np.ndarray]) -> np.ndarray:
    """FITTED's rows with MIRRORS' in front (module docstring)."""
    first = rows[0]  # (2, 4): one lobe at FITTED[0] (below TWO_LOBES)
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
    """One row on a worker (parallel/executor.py): task (f0, roughness) -> (row, info)."""
    f0, r = task
    return fit_row(specular_layer(r, f0), (R0_RANGE[0] * f0, min(R0_RANGE[1] * f0, 1.0)))


def build(progress=print, jobs: int = 1) -> tuple[FitTable, list[str]]:
    started = time.perf_counter()
    tasks = [(f0, r) for f0 in F0 for r in FITTED]
    results: dict[int, tuple[np.ndarray, dict]] = {}
    with LocalExecutor(jobs) as executor:  # rows on `jobs` processes, as they finish
        for index, result in executor.run(_no_state, (), _fit_task, tasks):
            results[index] = result
            f0, r = tasks[index]
            progress(f"[{len(results)}/{len(tasks)}, {time.perf_counter() - started:.0f} s] f0 {f0}, roughness {r}: "
                     f"lobes {np.round(result[0], 4).tolist()}, fit error {result[1]['one_lobe_error']:.2e} (one "
                     f"lobe) / {result[1]['error']:.2e}")
    lines = []
    rows = {}
    for index, (f0, r) in enumerate(tasks):
        row, info = results[index]
        params = specular_layer(r, f0)
        ours, ref = lobe_check(row, params)
        worst = max(abs(a - b) / max(b, 1e-6) for a, b in zip(ours, ref))
        (ks, m, r0, alpha), (ks2, m2, r02, alpha2) = row
        second = f"{ks2:.4f} / {m2:.4f} / {r02:.4f} / {alpha2:.3f}" if ks2 > 0 else "-"
        lines.append(f"| f0 {f0}, roughness {r} | {ks:.4f} | {m:.5f} | {r0:.4f} | {alpha:.3f} | {second} | "
                     f"{info['one_lobe_error']:.2e} / {info['error']:.2e} | "
                     + " | ".join(f"{a:.3f} / {b:.3f}" for a, b in zip(ours, ref)) + f" | {100 * worst:.1f} % | "
                     f"{100 * info['one_lobe_albedo_error']:.1f} % / {100 * info['albedo_error']:.1f} % |")
        rows.setdefault(f0, []).append(row)
    specular = [with_mirrors(rows[f0]) for f0 in F0]
    roughness = MIRRORS + FITTED
    albedo = np.array([[hemispherical_albedo(specular_layer(max(r, FITTED[0]), f0)) for r in roughness]
                       for f0 in F0])
    table = FitTable(roughness=np.array(roughness), f0=np.array(F0), specular=np.stack(specular),
                     specular_albedo=albedo, diffuse=np.array([diffuse_share(f0) for f0 in F0]))
    return table, lines


def report(table: FitTable, lines: list[str], command: str) -> str:
    head = ("| material | ks | m | r0 | alpha | lobe 2: ks / m / r0 / alpha | fit error | "
            + " | ".join(f"{d} deg fit / ref" for d in CHECK_DEGREES)
            + " | worst | fit's albedo miss, one lobe / shipped |\n|" + "---|" * (9 + len(CHECK_DEGREES)) + "\n")
    shares = ", ".join(f"f0 {f0}: {s:.4f}" for f0, s in zip(table.f0, table.diffuse))
    return (f"# The glTF BRDF fitted by the section 3.3 model\n\nMade by `{command}` (bench/fit_gltf_table.py; "
            "what the columns mean: its docstring). Directional albedo: the fitted lobe by core/bsdf.py "
            "`lobe_albedo` against core/gltf_brdf.py `directional_albedo` (grey mean), the row's lobes summed. "
            f"A row of roughness {TWO_LOBES[0]} to {TWO_LOBES[1]} has lobe 2 (the tail) where the two-lobe fit's error is at most "
            f"{TWO_LOBES_GAIN:.2f} of the one-lobe fit's (the column `fit error`: one lobe / shipped); the last column: "
            "the worst albedo miss on the fit's quadrature (0-80 degrees), one-lobe fit / shipped row.\n\n"
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
