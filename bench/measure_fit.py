"""How reliably each search of bake/brdf_fit.py finds the global minimum (docs/BENCHMARKS.md, "Fitting
the material model"): N random known one-lobe materials (fixed seed), each fitted by every method;
a fit recovers its material when m is within 3 %, r0 within 0.02, alpha within 0.03, kd within 0.01,
ks within 3 % and the directional albedo within 2 % at 0-80 degrees.

`--lobes 2`: N random known two-lobe materials (a narrow lobe, m 0.01 to 0.2, and a wide one, 3 to 10
times wider, each with its own ks, r0 and alpha; kd), written from those two lobes by core/bsdf.py and
fitted with two lobes by the multistart search, joint (the default) and in turn (the thesis' 3.4.1);
recovered when, the fitted lobes ordered by m, each lobe's m is within 5 %, r0 within 0.03, alpha
within 0.05 and ks within 5 %, kd within 0.01, and the directional albedo within 2 % at 0-80 degrees.
Also printed: the fit's error against the error of the true parameters (0 up to the quadrature), and
whether the two-lobe fit's error is below the one-lobe fit's.

    python3 -m glint.bench.measure_fit [--n 20] [--seed 24] [--lobes 1|2]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from glint.bake import brdf_fit
from glint.core import bsdf
from glint.core.scene import Lobe


def random_material(rng):
    m = float(np.exp(rng.uniform(np.log(0.01), np.log(0.5))))
    lobe = Lobe(ks=tuple(rng.uniform(0.2, 1.0, 3)), mx=m, my=m, r0=float(rng.uniform(0, 1)),
                alpha=float(rng.uniform(0, 1)))
    return tuple(rng.uniform(0.0, 0.5, 3)), lobe


def albedo(kd, lobes, theta):
    wo = np.stack([np.sin(theta), 0 * theta, np.cos(theta)], axis=-1)
    return np.asarray(kd) + sum(np.asarray(lb.ks) * bsdf.lobe_albedo(wo, lb.mx, lb.my, lb.r0, lb.alpha, lb.kind)[:, None]
                                for lb in lobes)


def recovered(result, kd, lobe) -> tuple[bool, float]:
    theta = np.radians(np.arange(0.0, 81.0, 5.0))
    rel = float(np.max(np.abs(albedo(result.kd, result.lobes, theta) / albedo(kd, [lobe], theta) - 1)))
    got = result.lobes[0]
    ok = (abs(got.mx / lobe.mx - 1) < 0.03 and abs(got.r0 - lobe.r0) < 0.02 and abs(got.alpha - lobe.alpha) < 0.03
          and np.allclose(result.kd, kd, atol=0.01) and np.allclose(got.ks, lobe.ks, rtol=0.03) and rel < 0.02)
    return ok, rel


def random_two_lobe_material(rng):
    """kd and (narrow, wide) lobes: the docstring's ranges."""
    m1 = float(np.exp(rng.uniform(np.log(0.01), np.log(0.2))))
    m2 = min(m1 * float(rng.uniform(3.0, 10.0)), 1.0)
    lobes = tuple(Lobe(ks=tuple(rng.uniform(0.2, 1.0, 3)), mx=m, my=m, r0=float(rng.uniform(0, 1)),
                       alpha=float(rng.uniform(0, 1))) for m in (m1, m2))
    return tuple(rng.uniform(0.0, 0.5, 3)), lobes


def recovered_two(result, kd, lobes) -> tuple[bool, float]:
    theta = np.radians(np.arange(0.0, 81.0, 5.0))
    rel = float(np.max(np.abs(albedo(result.kd, result.lobes, theta) / albedo(kd, list(lobes), theta) - 1)))
    got = sorted(result.lobes, key=lambda lb: lb.mx)
    ok = len(got) == 2 and np.allclose(result.kd, kd, atol=0.01) and rel < 0.02 and all(
        abs(g.mx / w.mx - 1) < 0.05 and abs(g.r0 - w.r0) < 0.03 and abs(g.alpha - w.alpha) < 0.05
        and np.allclose(g.ks, w.ks, rtol=0.05) for g, w in zip(got, lobes))
    return ok, rel


def main_two(n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    materials = [random_two_lobe_material(rng) for _ in range(n)]
    print("| # | m1 / m2 | search | recovered | albedo error | error (one lobe) | s |")
    print("|---|---|---|---|---|---|---|")
    totals = {}
    for k, (kd, lobes) in enumerate(materials):
        data = brdf_fit.BrdfData.from_function(lambda wi, wo: bsdf.bsdf(wi, wo, kd, list(lobes)))
        one = brdf_fit.fit(data, 1)
        for mode in brdf_fit.TWO_LOBE_MODES:
            t0 = time.perf_counter()
            result = brdf_fit.fit(data, 2, two_lobe=mode)
            seconds = time.perf_counter() - t0
            ok, rel = recovered_two(result, kd, lobes)
            got = sorted(result.lobes, key=lambda lb: lb.mx)
            t = totals.setdefault(mode, [0, 0.0, 0.0, 0])
            t[0] += ok
            t[1] += seconds
            t[2] = max(t[2], rel)
            t[3] += result.error < one.error
            print(f"| {k} | {lobes[0].mx:.3f} / {lobes[1].mx:.3f} ({' / '.join(f'{g.mx:.3f}' for g in got)}) | {mode} | "
                  f"{'yes' if ok else 'no'} | {rel:.2%} | {result.error:.1e} ({one.error:.1e}) | {seconds:.1f} |",
                  flush=True)
    for mode, (n_ok, seconds, worst, below) in totals.items():
        print(f"{mode}: {n_ok}/{n} recovered, {seconds / n:.1f} s per fit, largest albedo error {worst:.2%}, "
              f"error below the one-lobe fit's in {below}/{n}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=20)
    parser.add_argument("--seed", type=int, default=24)
    parser.add_argument("--lobes", type=int, choices=(1, 2), default=1)
    args = parser.parse_args()
    if args.lobes == 2:
        main_two(args.n, args.seed)
        return
    rng = np.random.default_rng(args.seed)
    materials = [random_material(rng) for _ in range(args.n)]
    print("| # | m | r0 | alpha | method | recovered | albedo error | error | candidates | s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    totals = {}
    for k, (kd, lobe) in enumerate(materials):
        data = brdf_fit.BrdfData.from_function(lambda wi, wo: bsdf.bsdf(wi, wo, kd, [lobe]))
        for method in brdf_fit.METHODS:
            t0 = time.perf_counter()
            result = brdf_fit.fit(data, 1, method=method)
            seconds = time.perf_counter() - t0
            ok, rel = recovered(result, kd, lobe)
            got = result.lobes[0]
            t = totals.setdefault(method, [0, 0.0, 0.0])
            t[0] += ok
            t[1] += seconds
            t[2] = max(t[2], rel)
            print(f"| {k} | {lobe.mx:.3f} ({got.mx:.3f}) | {lobe.r0:.2f} ({got.r0:.2f}) | {lobe.alpha:.2f} "
                  f"({got.alpha:.2f}) | {method} | {'yes' if ok else 'no'} | {rel:.2%} | {result.error:.1e} | "
                  f"{result.evaluations} | {seconds:.1f} |", flush=True)
    for method, (n_ok, seconds, worst) in totals.items():
        print(f"{method}: {n_ok}/{args.n} recovered, {seconds / args.n:.1f} s per fit, "
              f"largest albedo error {worst:.2%}")


if __name__ == "__main__":
    main()
