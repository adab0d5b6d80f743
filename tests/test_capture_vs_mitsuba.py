"""`glint capture cornell-box` against Mitsuba 3 rendering mitsuba.cornell_box() (the viewer's end-to-end accuracy).

The reference (tests/data/cornell_box_128.exr) is Mitsuba 3 with the same camera, 128x128,
box pixel filter, unlimited path depth, 16384 samples per pixel, made by
tests/data/make_mitsuba_references.py. Our capture uses 4x4 supersampling so each pixel
is the mean over its area too. Metric: relative mean absolute error sum|a-b| / sum|b|
over all pixels and channels of the linear radiance; at most 5 % at the `preview` bake.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from glint.core.image_io import read_image

REFERENCE = Path(__file__).parent / "data" / "cornell_box_128.exr"


def relative_mae(image: np.ndarray, reference: np.ndarray) -> float:
    return float(np.abs(image - reference).sum() / np.abs(reference).sum())


@pytest.mark.slow
def test_cornell_box_capture_matches_mitsuba(tmp_path):
    out = tmp_path / "cb.exr"
    result = subprocess.run(
        [sys.executable, "-m", "glint", "capture", "cornell-box", "--camera", "sensor", "--size", "128x128",
         "--supersample", "4", "-o", str(out), "--bake-dir", str(tmp_path / "cb.bake"), "-q", "preview"],
        capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    image, reference = read_image(out), read_image(REFERENCE)
    assert image.shape == reference.shape == (128, 128, 3)
    error = relative_mae(image, reference)
    print(f"relative MAE against Mitsuba 3: {error:.4f}")
    assert error <= 0.05
    # The error is not hiding a misplaced image: shifting by one pixel makes it clearly worse.
    assert relative_mae(np.roll(image, 1, axis=1), reference) > error + 0.01
