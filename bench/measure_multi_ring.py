"""The measurement behind the multi-ring pattern of planar reflectors (viewer/lobe_patterns.py,
"Planar reflectors"): a pattern's step response across a straight edge in the reflected scene.

    python3 -m glint.bench.measure_multi_ring          # about 10 minutes on 2 cores

Set-up: a lobe (isotropic Beckmann, m = 0.02, 0.05, 0.1, 0.2; r0 = 0.04, alpha = 0) seen at
theta_o = 0, 30, 60, 75 deg; the reflected scene is the plane perpendicular to the lobe centre
at unit distance, radiance 1 beyond a straight edge and 0 before it (8 edge orientations, the
edge swept over -1.5 .. 1.5 lobe radii, radius = sqrt(A / pi), A = lobe_ellipse_area).
Exact: the lobe's f cos integral beyond the edge over its whole integral (QMC, 2^14 importance
samples). Estimate: Eq. 4.25 over the pattern, each sample's radiance filtered as its MIP
level filters it, by a disk of area A / n around it, normalised by the same estimate of
radiance 1. Printed: the mean absolute difference of the two responses (%) per m.
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from glint.core import bsdf
from glint.viewer import lobe_patterns as lp

ROUGHNESS = (0.02, 0.05, 0.1, 0.2)
VIEWS = (0.0, 30.0, 60.0, 75.0)
EDGES = np.linspace(0.0, np.pi, 8, endpoint=False) + 0.1
QMC = np.stack(bsdf.qmc_points(1 << 14), -1)


def rings(n: int, count: int, outer: float) -> np.ndarray:
    """Centre + `count` rings evenly spaced in theta_h out to `outer` x theta_thresh, each ring
    turned by j / count of its sample spacing (count = 2, outer = 0.8 is "multi_ring")."""
    rest = n - 1
    count = max(1, min(count, rest))
    xi = [(1.0, 0.0)]
    for j in range(count):
        k = rest // count + (1 if j < rest % count else 0)
        radius = outer * (j + 1) / count
        xi += [(1.0 - radius, (i / k + j / count / k) % 1.0) for i in range(k)]
    return np.array(xi)


def disk_fraction(t):
    """Share of a unit disk beyond a line at signed distance t from its centre."""
    t = np.clip(t, -1.0, 1.0)
    return 0.5 + (t * np.sqrt(1.0 - t * t) + np.arcsin(t)) / np.pi


def error(m: float, theta_o: float, xi: np.ndarray) -> float:
    th = np.radians(theta_o)
    wo = np.array([np.sin(th), 0.0, np.cos(th)])
    c = np.array([-wo[0], -wo[1], wo[2]])
    a = np.cross(c, [0.0, 0.0, 1.0])
    a = a / np.linalg.norm(a) if np.linalg.norm(a) > 1e-6 else np.array([1.0, 0.0, 0.0])
    b = np.cross(c, a)

    def on_plane(w):
        w = w / (w @ c)[..., None]
        return np.stack([w @ a, w @ b], -1)

    wi = bsdf.sample_lobe(wo, QMC[:, 0], QMC[:, 1], m, m, "reflect")
    f, p = bsdf.lobe_value(wi, wo, m, m, 0.04, 0.0, "reflect"), bsdf.lobe_pdf(wi, wo, m, m, "reflect")
    ok = (wi[:, 2] > 0) & (p > 0)
    weight = np.where(ok, f * np.maximum(wi[:, 2], 0.0) / np.where(ok, p, 1.0), 0.0)
    x_exact = on_plane(np.where(ok[:, None], wi, c))
    n = len(xi)
    wp, fp, pp, cp = lp.pattern_samples(wo, xi, m, m, 0.04, 0.0, "reflect")
    area = lp.lobe_ellipse_area(wo, m, m, "reflect")
    radius = np.sqrt(area / n / np.pi)
    x_pattern = on_plane(wp)
    offsets = np.linspace(-1.5, 1.5, 61) * np.sqrt(area / np.pi)
    errors = []
    for psi in EDGES:
        e = np.array([np.cos(psi), np.sin(psi)])
        exact = np.array([(weight * ((x_exact @ e) > s)).sum() / weight.sum() for s in offsets])
        L = disk_fraction(((x_pattern @ e)[None, :] - offsets[:, None]) / radius)
        est = lp.pattern_estimate(L[..., None], fp[None], pp[None], cp[None])[..., 0]
        one = lp.pattern_estimate(np.ones_like(L)[..., None], fp[None], pp[None], cp[None])[..., 0]
        errors.append(np.mean(np.abs(est / one - exact)))
    return float(np.mean(errors))


def score(xi: np.ndarray) -> np.ndarray:
    return 100.0 * np.array([np.mean([error(m, t, xi) for t in VIEWS]) for m in ROUGHNESS])


def main() -> None:
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args()  # no options; --help
    print("mean |estimate - exact| of the edge response (%), per m =", ROUGHNESS)
    for n in (5, 7, 10, 13, 16):
        print(f"n = {n}")
        print("  ring (curved)           ", np.round(score(lp.pattern_xi("ring", n)), 2))
        print("  multi_ring (2 rings .4/.8)", np.round(score(lp.pattern_xi("multi_ring", n)), 2))
        for count in (2, 3):
            for outer in (0.6, 0.7, 0.8, 0.9):
                if (n - 1) / count >= 2:
                    print(f"  {count} rings out to {outer}     ", np.round(score(rings(n, count, outer)), 2))
        sys.stdout.flush()


if __name__ == "__main__":
    main()
