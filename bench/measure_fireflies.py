"""Measures fireflies and adaptive sampling (issue 25): per scene, the light maps' outliers and
fireflies (bench/fireflies.py) and the light-map stage's time, with adaptive sampling off
(`adaptive_samples` 1) and on; and the bias of adaptive sampling's stopping rule.

    python -m glint.bench.measure_fireflies [--scenes living-room cornell-box PATH.glb ...]
        [--quality preview] [--adaptive 1 16]
    python -m glint.bench.measure_fireflies --bias [--seeds 32]

The bias: adaptive sampling decides from a texel's own first paths whether it gets more, so its mean
over seeds can differ from the plain estimator's (unbiased). At living-room's four texels that were
fireflies at preview (the sofa foot in the gap behind the sofa, the book's end) and RANDOM_TEXELS
texels drawn from its light maps, each estimated with `--seeds` seeds both ways, the bake's rule
(bake/lightmap.py: relative error over SELECT_ERROR, or over SELECT_OUTLIER x the neighbourhood's
value, here the texel's converged value; then refined to TARGET_ERROR or the cap): the mean over
seeds of each, and the converged value (REFERENCE paths, another seed).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

FIREFLY_TEXELS = ((0, 232, 326), (0, 233, 326), (0, 234, 326), (0, 310, 135))  # living-room, preview: (page, y, x)
RANDOM_TEXELS = 40
REFERENCE = 16384


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
                  f"(jobs 1); {lm.texels} texels, {lm.refined} refined, +{lm.refined_paths} paths "
                  f"(+{100 * lm.refined_paths / max(lm.texels * r.lightmaps_samples, 1):.1f} %), "
                  f"{lm.rays / 1e6:.1f} M rays", flush=True)
            for o in r.fireflies:
                print(f"    firefly page {o.page} ({o.y}, {o.x}): {o.value:.4f} against converged {o.converged:.4f} "
                      f"(5 x 5 median {o.median:.4f})")


def bias(args) -> None:
    from glint.bake import lightmap as LM
    from glint.bake.irradiance import AdaptiveSampling, compute_irradiance, refine_irradiance, relative_error
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
    texels = list(FIREFLY_TEXELS)
    ys, xs = np.nonzero(pages[0].object >= 0)
    texels += [(0, int(ys[i]), int(xs[i])) for i in rng.choice(len(ys), RANDOM_TEXELS, replace=False)]
    page = pages[0]
    yx = np.array([t[1:] for t in texels])
    normals = page.normal[yx[:, 0], yx[:, 1]].astype(np.float64)
    moved = adjust_samples(tracer, page.position[yx[:, 0], yx[:, 1]], normals, page.size[yx[:, 0], yx[:, 1]],
                           page.object[yx[:, 0], yx[:, 1]])
    keep = ~moved.invalid
    points, normals = moved.points[keep], normals[keep]
    kinds = np.array([k < len(FIREFLY_TEXELS) for k in range(len(texels))])[keep]
    reference = luminance(compute_irradiance(scene, tracer, points, normals, REFERENCE, seed=777).total) / REFERENCE
    floor = LM.FLOOR_SHARE * 0.62  # living-room's median lit texel at preview (0.62 W/m^2, measured)
    rule = AdaptiveSampling(LM.TARGET_ERROR, s.samples * s.adaptive_samples, floor)
    plain, adaptive, paths = [], [], []
    for seed in range(args.seeds):
        r = compute_irradiance(scene, tracer, points, normals, s.samples, seed=1000 + seed)
        total, square, n = r.total.copy(), r.square.copy(), r.samples.copy()
        plain.append(luminance(total) / n)
        pick = np.flatnonzero((relative_error(total, square, n, floor) > LM.SELECT_ERROR)
                              | (luminance(total) / n > np.maximum(LM.SELECT_OUTLIER * reference, floor)))
        t, q, c = total[pick], square[pick], n[pick]
        refine_irradiance(scene, tracer, points[pick], normals[pick], pick.astype(np.uint64), t, q, c, rule,
                          1000 + seed)
        total[pick], n[pick] = t, c
        adaptive.append(luminance(total) / n)
        paths.append(n)
    plain, adaptive, paths = np.array(plain), np.array(adaptive), np.array(paths)
    for label, sel in (("former fireflies", kinds), ("random texels", ~kinds)):
        for k in np.flatnonzero(sel) if label == "former fireflies" else [None]:
            rows = [k] if k is not None else np.flatnonzero(sel)
            p, a, ref = plain[:, rows].mean(axis=0), adaptive[:, rows].mean(axis=0), reference[rows]
            se = np.sqrt(plain[:, rows].var(axis=0, ddof=1) / args.seeds).mean()
            worst = np.max(np.abs(adaptive[:, rows] / np.maximum(ref, 1e-12) - 1.0), axis=1).mean()
            print(f"{label}{'' if k is None else f' {texels[np.flatnonzero(keep)[k]]}'}: mean over {args.seeds} seeds, "
                  f"plain {p.mean():.4f} (its standard error {se:.4f}), adaptive {a.mean():.4f}, converged "
                  f"{ref.mean():.4f}; bias of the rule (adaptive - plain) / converged "
                  f"{100 * (a.mean() - p.mean()) / ref.mean():+.1f} %; mean paths {paths[:, rows].mean():.0f}; "
                  f"largest seed's error over converged: plain {100 * np.abs(plain[:, rows] / ref - 1).max():.0f} %, "
                  f"adaptive {100 * np.abs(adaptive[:, rows] / ref - 1).max():.0f} % (mean worst {100 * worst:.0f} %)",
                  flush=True)


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
