"""No fireflies in the light maps: texels far brighter than their neighbourhood that the converged
irradiance at their own sample point does not explain (issue 25).

The definitions and their thresholds are bench/fireflies.py's (shared with
bench/measure_fireflies.py, which measures living-room too: docs/BAKE.md "Fireflies"). A texel is an
outlier when its (denoised, stored) light-map value is more than 4 x the median of its
5 x 5 neighbourhood on the same chart (the texels of its object connected to it, path traced, not
dilated), and above 5 % of the page's median (black corners are not fireflies). An outlier can be
real: the edge of a shadow, the mouth of a 1 mm gap that light enters from one end (the skirting
board's back face in tests/seam_scenes.py's interior), a book's side at the front of a shelf. So each
outlier is traced again at its sample point with 4096 paths: it is a firefly when its light-map
value is more than twice that converged value (a few of its paths found a narrow gap or a caustic
with a huge weight). Where the bright texels of issue 25 came from (samples on chart borders'
edges and inside covering meshes) is tests/test_seams.py's.

Scenes: the interior and cornell-box at preview; metal-floor-room (polished metal floor, the
caustic case) at draft. living-room at preview takes about 50 s more on 2 cores (its 4096-path
re-traces included), over this file's budget: bench/measure_fireflies.py measures it.
"""
from __future__ import annotations

from pathlib import Path

import pytest

import seam_scenes as S
from glint.bake.gltf_loader import load_scene
from glint.bench.fireflies import count_fireflies
from glint.scenes import builtin_path


@pytest.mark.slow
@pytest.mark.parametrize("name", ["interior", "cornell-box", "metal-floor-room"])
def test_no_fireflies(tmp_path: Path, name):
    """Measured (this build): no outlier at all in the three (before bake/sample_points.py's sliver
    rule, the interior had 11, two of them fireflies: 0.057 and 0.052 against converged 0.028 and
    0.025, on the skirting board's back face in its 1 mm gap).

    Bug this catches (tried): the sliver rule off (bake/sample_points.py SLIVER = 0) fails the
    interior with those two fireflies. (Path regularisation off, scatter.py M_REGULARISE = 1e-4, does
    not make fireflies in metal-floor-room at draft: its lamp is an area light, found by next-event
    estimation with MIS.)"""
    if name == "interior":
        scene, quality = load_scene(S.write_interior(tmp_path / "interior.glb")), "preview"
    else:
        scene, quality = load_scene(builtin_path(name)), "draft" if name == "metal-floor-room" else "preview"
    result = count_fireflies(scene, quality)
    print(f"{name}: {len(result.outliers)} outliers, {len(result.fireflies)} fireflies", result.fireflies[:10])
    assert not result.fireflies
