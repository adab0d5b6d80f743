"""The files the measurement tools write: JSON, CSV, Markdown, PNG images and plots.

Every one is written through core/atomic.py (`atomic_path`): a report is either the previous
one or wholly the new one, never half-written, and a failure to write is a GlintError naming
the file. Numbers go into JSON with non-finite values as null (strict JSON has no Infinity)
and into CSV as text with `inf` kept and NaN empty.
"""
from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import numpy as np

from glint.core.atomic import atomic_path, atomic_write_text
from glint.core.errors import GlintError
from glint.core.image_io import write_image


def num(x) -> str:
    """A CSV cell: "" for None and NaN, "inf" for an infinity, 6 significant digits for a float."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return ""
    if isinstance(x, float) and math.isinf(x):
        return "inf"
    return f"{x:.6g}" if isinstance(x, float) else str(x)


def json_safe(x):
    """`x` with every non-finite float as None and the others rounded (6 decimals, or 6 significant
    digits below 1e-3), through dicts, lists and tuples."""
    if isinstance(x, float):
        return None if not math.isfinite(x) else round(x, 6) if abs(x) >= 1e-3 else float(f"{x:.6g}")
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    return x


def slug(name: str) -> str:
    """A camera's name as part of a file name."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", name).strip("-") or "camera"


def write_json(path: Path, data) -> None:
    """`data` through `json_safe`, one space of indent, a final newline."""
    atomic_write_text(path, json.dumps(json_safe(data), indent=1) + "\n")


def write_csv(path: Path, columns, rows: list[dict]) -> None:
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)


def write_png(path: Path, srgb: np.ndarray) -> None:
    """An (H, W, 3) uint8 image; the folder is made when missing."""
    path.parent.mkdir(parents=True, exist_ok=True)
    write_image(path, srgb)


def pyplot():
    """matplotlib.pyplot on the Agg back end (files only, no display)."""
    try:  # here, not at the top: it takes longer to import than the rest of glint; and optional
        import matplotlib
    except ImportError:
        raise GlintError("the measurement tools' plots need matplotlib, which is not installed: "
                         "pip install 'glint[bench]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path: Path, dpi: int = 110) -> None:
    """Save a matplotlib figure (its format from the suffix of `path`) and close it."""
    plt = pyplot()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=dpi)
    finally:
        plt.close(fig)
