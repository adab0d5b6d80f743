"""Grow light-map charts into the empty texels around them.

A bilinear look-up near a chart border reads texels just outside the chart;
those must hold the chart's own values, not black. `dilate` fills each empty
texel from the average of its valid 8-neighbours, one ring of texels per pass;
`dilate_to_fill` does a few such passes and then fills every remaining empty
texel of the page (pull-push: averages over coarser and coarser 2x2 blocks), so
even mip-mapped or far-off look-ups never see black.

With `labels` (the object of each texel, -1 where no surface), an invalid texel of a surface takes
only neighbours of its own object while it has any, so a texel whose sample was covered by another
object is filled from its own surface, not from the object that covered it across a chart's border
(issue 25); empty texels (label -1) take any neighbour, as without labels.
"""
from __future__ import annotations

import numpy as np

# The 8 neighbours as (dy, dx).
_NEIGHBOURS = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx]


def dilate(image: np.ndarray, valid: np.ndarray, iterations: int, labels: np.ndarray | None = None) -> np.ndarray:
    """(H, W, C) image, (H, W) bool valid -> image with `iterations` rings of invalid texels filled.

    Valid texels are returned unchanged; invalid texels no pass reaches keep
    their input values. The input is not modified. `labels`: (H, W) int, the module docstring.
    """
    image, valid = _check(image, valid)
    if labels is None:
        return _dilate(image, valid, iterations)[0]
    out, done = _dilate(image, valid, iterations, np.asarray(labels))
    # what no neighbour of its own object reached: from any neighbour
    return _dilate(out, done, iterations)[0]


def dilate_to_fill(image: np.ndarray, valid: np.ndarray, iterations: int = 2) -> np.ndarray:
    """Like `dilate`, then every texel still empty gets the pull-push average of the nearby filled ones.

    With no valid texel at all the image comes back with zeros where it was invalid.
    """
    out, done = _dilate(*_check(image, valid), iterations)
    if done.all():
        return out
    fill = _pull_push(np.where(done[..., None], out, np.float32(0)), done.astype(np.float32))
    return np.where(done[..., None], out, fill)


def _dilate(image: np.ndarray, valid: np.ndarray, iterations: int, labels: np.ndarray | None = None):
    out = image.astype(np.float32, copy=True)
    done = valid.copy()
    H, W = done.shape
    for _ in range(int(iterations)):
        if done.all() or not done.any():
            break
        # Only the ring of empty texels next to filled ones changes: gather their
        # neighbours sparsely instead of filtering the whole page (mostly empty).
        count = _box3(done.astype(np.uint8)[..., None])[..., 0]
        ys, xs = np.nonzero(~done & (count > 0))
        own = None if labels is None else labels[ys, xs]
        total = np.zeros((len(ys), out.shape[2]), np.float64)
        n = np.zeros(len(ys))
        for dy, dx in _NEIGHBOURS:
            y, x = ys + dy, xs + dx
            ok = (y >= 0) & (y < H) & (x >= 0) & (x < W)
            y, x = np.clip(y, 0, H - 1), np.clip(x, 0, W - 1)
            ok &= done[y, x]
            if own is not None:
                ok &= (labels[y, x] == own) | (own < 0)
            total += np.where(ok[:, None], out[y, x], 0.0)
            n += ok
        got = n > 0
        if not got.any():
            break
        ys, xs = ys[got], xs[got]
        out[ys, xs] = total[got] / n[got, None]
        done[ys, xs] = True
    return out, done


def _check(image, valid):
    image = np.asarray(image)
    valid = np.asarray(valid, bool)
    if image.ndim != 3 or valid.shape != image.shape[:2]:
        raise ValueError(f"dilate: image must be (H, W, C) and valid (H, W); got {image.shape} and {valid.shape}")
    return image, valid


def _box3(a: np.ndarray) -> np.ndarray:
    """3x3 box sum of (H, W, C), zero outside; separable."""
    p = np.pad(a, ((1, 1), (1, 1), (0, 0)))
    rows = p[:-2] + p[1:-1] + p[2:]
    return rows[:, :-2] + rows[:, 1:-1] + rows[:, 2:]


def _pull_push(values: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Fill weight-0 texels: average 2x2 blocks down to one texel (pull), then copy coarse into empty (push)."""
    levels = [(values * weight[..., None], weight)]
    while max(levels[-1][1].shape) > 1:
        s, w = levels[-1]
        H, W = w.shape
        s = np.pad(s, ((0, H % 2), (0, W % 2), (0, 0)))
        w = np.pad(w, ((0, H % 2), (0, W % 2)))
        s = s[0::2, 0::2] + s[1::2, 0::2] + s[0::2, 1::2] + s[1::2, 1::2]
        w = w[0::2, 0::2] + w[1::2, 0::2] + w[0::2, 1::2] + w[1::2, 1::2]
        levels.append((s, w))
    colour = np.zeros(levels[-1][0].shape, values.dtype)
    for s, w in reversed(levels):
        H, W = w.shape
        h, w2 = colour.shape[:2]
        # Nearest-neighbour upsampling of the coarser level by a broadcast view.
        coarse = np.broadcast_to(colour[:, None, :, None], (h, 2, w2, 2, colour.shape[2]))
        colour = coarse.reshape(2 * h, 2 * w2, -1)[:H, :W].copy() if (H, W) != (h, w2) else colour
        has = w > 0
        colour[has] = s[has] / w[has][:, None]
    return colour
