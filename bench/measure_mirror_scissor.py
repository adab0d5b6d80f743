"""Mirror passes in a rectangle (viewer/reflectors.py `scissor_rect`, issue 27): each pass rasterised
only where its reflectors' look-ups are estimated to reach, against the whole buffer; how much faster,
how different.

    python3 -m glint.bench.measure_mirror_scissor [--scenes living-room planar-classes] [--size 640x360]
                                                  [--out DIR]

Per scene and camera, two renderers (Renderer(mirror_scissor=...)) drawing walkthrough frames
alternately in blocks (bench/measure_draw_count.py `alternate`): medians of the mirror passes' time and
of the frame's wall time; the rectangles' share of the buffer; then one frame each way compared pixel by
pixel (linear radiance, the relative difference |a - b| / max(|a|, |b|, 1e-6) of a channel). Draft
bakes are made in DIR when missing.
"""
from __future__ import annotations

import sys


def main(argv=None) -> int:
    from glint.bench.measure_visibility import paired_views, relative_difference, setup

    args, ctx, width, height = setup("measure_mirror_scissor", __doc__, ["living-room", "planar-classes"],
                                     "mirror-scissor", argv)
    print("| scene, camera | passes: share of the buffer rasterised | mirror passes ms: whole / rectangle "
          "| frame ms: whole / rectangle | largest relative difference | pixels over 1e-3 | over 1e-2 |")
    print("|---|---|---|---|---:|---:|---:|")
    for name, entry, renderers, frame in paired_views(ctx, args, width, height, "mirror_scissor"):
        mirror = {on: r.timer.median_ms.get("mirror_passes", float("nan")) for on, r in renderers.items()}
        rects = [d["scissor"] for d in renderers[True].stats["mirror"]["passes"]]
        shares = [1.0 if rect is None else rect[2] * rect[3] / (width * height) for rect in rects]
        rel = relative_difference(*(r.read_linear() for r in renderers.values()))
        print(f"| {name}, {entry.name} | {', '.join(f'{s:.2f}' for s in shares) or '-'} "
              f"| {mirror[False]:.2f} / {mirror[True]:.2f} | {frame[False]:.2f} / {frame[True]:.2f} | {rel.max():.2e} "
              f"| {int((rel > 1e-3).sum())} of {width * height} | {int((rel > 1e-2).sum())} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
