"""Measures fireflies and adaptive sampling (issue 25): per scene, the light maps' outliers and
fireflies (bench/fireflies.py) and the light-map stage's time, with adaptive sampling off
(`adaptive_samples` 1) and on; and the bias of adaptive sampling's stopping rule.

    python -m glint.bench.measure_fireflies [--scenes living-room cornell-box PATH.glb ...]
        [--quality preview] [--adaptive 1 16]
    python -m glint.bench.measure_fireflies --bias [--seeds 32]

The bias (`--bias`) of the rule the bake does not use: a texel's own first paths decide whether it
gets more (relative error over OWN_RULE_ERROR, or its value over OWN_RULE_OUTLIER x its neighbourhood's,
here its converged value), and it is refined until its own error is below OWN_RULE_TARGET or
OWN_RULE_CAP x samples. Its mean over seeds differs from the plain estimator's, which is unbiased:
measured at living-room's four texels that were fireflies at preview (the sofa foot in the gap behind
the sofa, the book's end) and RANDOM_TEXELS texels drawn from its light maps, `--seeds` seeds each
way, against the converged value (REFERENCE paths, another seed). The bake's rule (bake/lightmap.py)
lets a texel's neighbours decide, never its own paths, so it adds no bias.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

FIREFLY_TEXELS = ((0, 232, 326), (0, 233, 326), (0, 234, 326), (0, 310, 135))  # living-room, preview: (page, y, x)
RANDOM_TEXELS = 40
REFERENCE = 16384
LIVING_ROOM_MEDIAN = 0.62  # W/m^2, living-room's median lit texel at preview (measured): the floor's scale
# the rejected rule (module docstring)
OWN_RULE_ERROR = 0.7  # relative standard error
OWN_RULE_OUTLIER = 3.0
OWN_RULE_TARGET = 0.2
OWN_RULE_CAP = 16


def _scene(name: str):
    from glint.bake.gltf_loader import load_scene
    from glint.scenes import builtin_path

    return load_scene(Path(name) if name.endswith((".glb", ".gltf")) else builtin_path(name))


def count(args) -> None:
    from glint.bench.fireflies import count_fireflies

    for name in args.scenes:
        scene = _scene(name)
        for adaptive in args.adaptive:
            r = count_fireflies(scene, args.quality, adaptive_samples=adaptive)
            lm = r.lightmaps
            print(f"{name} {args.quality} adaptive_samples {adaptive}: {len(r.outliers)} outliers, "
                  f"{len(r.fireflies)} fireflies; light maps {r.seconds:.1f} s wall, {r.cpu_seconds:.1f} s CPU "
                  f"(jobs 1); {lm.texels} texels, {lm.refined} refined ({lm.enclosed} in cavities), +{lm.refined_paths} paths "
                  f"(+{100 * lm.refined_paths / max(lm.texels * r.lightmaps_samples, 1):.1f} %), "
                  f"{lm.rays / 1e6:.1f} M rays", flush=True)
            for o in r.fireflies:
                print(f"    firefly page {o.page} ({o.y}, {o.x}): {o.value:.4f} against converged {o.converged:.4f} "
                      f"(5 x 5 median {o.median:.4f})")


def bias(args) -> None:
    from glint.bake import lightmap as LM
    from glint.bake.alpha import Coverage
    from glint.bake.irradiance import compute_irradiance, refine_irradiance, relative_error
    from glint.bake.lights import luminance
    from glint.bake.raytrace import RayTracer
    from glint.bake.sample_points import adjust_samples
    from glint.bake.settings import resolve_settings
    from glint.bake.texels import rasterize_texels
    from glint.bake.unwrap import unwrap

    scene = _scene("living-room")
    s = resolve_settings(scene.bake_settings, quality="preview")
    pages = rasterize_texels(scene.objects, unwrap(scene.objects, s.texels_per_metre, s.padding, s.max_page_size))
    tracer = RayTracer(scene)
    rng = np.random.default_rng(1)
    page = pages[0]
    ys, xs = np.nonzero(page.object >= 0)
    picked = rng.choice(len(ys), RANDOM_TEXELS, replace=False)
    yx = np.array([t[1:] for t in FIREFLY_TEXELS] + [(int(ys[i]), int(xs[i])) for i in picked])
    normals = page.normal[yx[:, 0], yx[:, 1]].astype(np.float64)
    moved = adjust_samples(tracer, page.position[yx[:, 0], yx[:, 1]], normals, page.size[yx[:, 0], yx[:, 1]],
                           page.object[yx[:, 0], yx[:, 1]], Coverage(scene, tracer))
    keep = np.flatnonzero(~moved.invalid)
    points, normals, yx = moved.points[keep], normals[keep], yx[keep]
    former = keep < len(FIREFLY_TEXELS)
    reference = luminance(compute_irradiance(scene, tracer, points, normals, REFERENCE, seed=777).total) / REFERENCE
    floor = LM.FLOOR_SHARE * LIVING_ROOM_MEDIAN
    cap = s.samples * OWN_RULE_CAP
    plain, own, paths = [], [], []
    for seed in range(args.seeds):
        r = compute_irradiance(scene, tracer, points, normals, s.samples, seed=1000 + seed)
        total, square, n = r.total.copy(), r.square.copy(), r.samples.copy()
        plain.append(luminance(total) / n)
        # the rejected rule: a texel's own error (or its value against the neighbourhood's, here its
        # converged value) decides, and it is refined until its own error is below OWN_RULE_TARGET
        go = (relative_error(total, square, n, floor) > OWN_RULE_ERROR) | \
            (luminance(total) / n > np.maximum(OWN_RULE_OUTLIER * reference, floor))
        while (pick := np.flatnonzero(go & (n < cap))).size:
            t, q, c = total[pick], square[pick], n[pick]
            refine_irradiance(scene, tracer, points[pick], normals[pick], pick.astype(np.uint64), t, q, c,
                              int(2 * c[0]) if len(set(c)) == 1 else int(c.max()), 1000 + seed)
            total[pick], square[pick], n[pick] = t, q, c
            go = relative_error(total, square, n, floor) > OWN_RULE_TARGET
        own.append(luminance(total) / n)
        paths.append(n)
    plain, own, paths = np.array(plain), np.array(own), np.array(paths)
    rows = [[k] for k in np.flatnonzero(former)] + [list(np.flatnonzero(~former))]
    for r in rows:
        label = f"texel {tuple(int(v) for v in yx[r[0]])} (a former firefly)" if len(r) == 1 else \
            f"{len(r)} random texels"
        p, a, ref = plain[:, r].mean(), own[:, r].mean(), reference[r].mean()
        se = plain[:, r].mean(axis=1).std(ddof=1) / np.sqrt(args.seeds)
        print(f"{label}: mean over {args.seeds} seeds: plain {p:.4f} (standard error {se:.4f}), own-error rule "
              f"{a:.4f} ({paths[:, r].mean():.0f} paths on average), converged {ref:.4f} ({REFERENCE} paths); "
              f"the rule's bias (own - plain) / converged {100 * (a - p) / ref:+.1f} %", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", default=["living-room", "cornell-box"])
    ap.add_argument("--quality", default="preview")
    ap.add_argument("--adaptive", nargs="+", type=int, default=[1, 16], help="adaptive_samples values")
    ap.add_argument("--bias", action="store_true", help="the stopping rule's bias (module docstring)")
    ap.add_argument("--seeds", type=int, default=32)
    args = ap.parse_args()
    bias(args) if args.bias else count(args)


if __name__ == "__main__":
    main()
