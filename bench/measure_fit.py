"""How reliably each search of bake/brdf_fit.py finds the global minimum (docs/BENCHMARKS.md, "Fitting
the material model"): N random known one-lobe materials (fixed seed), each fitted by every method;
a fit recovers its material when m is within 3 %, r0 within 0.02, alpha within 0.03, kd within 0.01,
ks within 3 % and the directional albedo within 2 % at 0-80 degrees.

    python3 -m glint.bench.measure_fit [--n 20] [--seed 24]
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=20)
    parser.add_argument("--seed", type=int, default=24)
    args = parser.parse_args()
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
