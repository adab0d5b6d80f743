"""Mirror buffers at a lower resolution (Renderer(mirror_resolution=...), viewer/passes/mirror.py
MIRROR_RESOLUTIONS) against the full one: how much faster the mirror passes, how different the image.

    python3 -m glint.bench.measure_mirror_resolution [--resolution 0.5] [--scenes living-room planar-classes]
                                                     [--size 640x360] [--out DIR]

Per scene and camera, two renderers drawing walkthrough frames alternately in blocks
(bench/measure_draw_count.py `alternate`): medians of the mirror passes' and MIP chains' time and of
the frame's wall time; then one frame each way compared pixel by pixel (linear radiance, the relative
difference |a - b| / max(|a|, |b|, 1e-6), the largest of a pixel's channels), and the mean absolute
difference over the mean radiance. Draft bakes are made in DIR when missing.
"""
from __future__ import annotations

import sys


def main(argv=None) -> int:
    import numpy as np

    from glint.bench.measure_visibility import paired_views, relative_difference, setup
    from glint.viewer.passes.mirror import MIRROR_RESOLUTIONS

    def options(p):
        p.add_argument("--resolution", type=float, default=0.5, choices=MIRROR_RESOLUTIONS[1:],
                       help="the mirror buffers' size against the render's (default 0.5)")

    args, ctx, width, height = setup("measure_mirror_resolution", __doc__, ["living-room", "planar-classes"],
                                     "mirror-resolution", argv, options)
    resolution = args.resolution
    print(f"| scene, camera | mirror passes + MIPs ms: 1 / {resolution} | frame ms: 1 / {resolution} "
          "| largest relative difference | pixels over 1e-3 | over 1e-2 | over 1e-1 | mean difference |")
    print("|---|---|---|---:|---:|---:|---:|---:|")
    for name, entry, renderers, frame in paired_views(ctx, args, width, height, "mirror_resolution",
                                                     (1.0, resolution)):
        mirror = {f: sum(r.timer.median_ms.get(k, 0.0) for k in ("mirror_passes", "mirror_mips"))
                  for f, r in renderers.items()}
        a, b = (r.read_linear()[..., :3].astype(np.float64) for r in renderers.values())
        rel = relative_difference(a, b)
        mean = np.abs(a - b).mean() / max(float(np.abs(a).mean()), 1e-12)
        n = width * height
        print(f"| {name}, {entry.name} | {mirror[1.0]:.2f} / {mirror[resolution]:.2f} "
              f"| {frame[1.0]:.2f} / {frame[resolution]:.2f} | {rel.max():.2e} | "
              + " | ".join(f"{100 * (rel > t).sum() / n:.2f} %" for t in (1e-3, 1e-2, 1e-1))
              + f" | {100 * mean:.3f} % |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
