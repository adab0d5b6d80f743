"""`glint capture cornell-box` against Mitsuba 3 rendering mitsuba.cornell_box() (the viewer's end-to-end accuracy).

The reference (tests/data/cornell_box_128.exr) is Mitsuba 3 with the same camera, 128x128,
box pixel filter, unlimited path depth, 16384 samples per pixel, made by
tests/data/make_mitsuba_references.py. Our capture uses 4x4 supersampling so each pixel
is the mean over its area too.

Metrics, on the linear radiance:
- per surface (floor, ceiling, back, red and green walls, the two boxes): the pixels that
  show only that surface, found by casting 4x4 rays per pixel through the scene's own
  geometry in numpy (`object_ids`) and eroding by one pixel (pixels that mix two surfaces
  or sit on an edge are left out). On each, the signed bias sum(a - b) / sum(b) within
  +-2.5 % and the relative MAE sum|a - b| / sum(b) at most 3 % (5.5 % on the small box);
- the lamp (the emissive object) is masked out of those: its 0.7 % of the pixels carry half
  the image's sum, so in a whole-image figure they hide everything else. Its interior
  pixels are compared on their own (they check that the masks line up with both images);
- the whole image's relative MAE, at most 5 %, and a one-pixel shift of the image makes
  it clearly worse.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from glint.core.image_io import read_image

REFERENCE = Path(__file__).parent / "data" / "cornell_box_128.exr"
SUPERSAMPLE = 4
BIAS_BOUND = 0.025
MAE_BOUND = {"small-box": 0.055}  # else MAE_DEFAULT
MAE_DEFAULT = 0.03


def relative_mae(image: np.ndarray, reference: np.ndarray) -> float:
    return float(np.abs(image - reference).sum() / np.abs(reference).sum())


def object_ids(scene, camera, size: int, sub: int = SUPERSAMPLE) -> np.ndarray:
    """(size, size) index of the object that all sub x sub rays of a pixel meet first (rows top
    first, as the captured image), -1 where they do not all meet the same one or meet nothing.
    The rays are the pinhole's through the sub-pixel centres (vertical field of view, square
    image); Moller-Trumbore against every triangle of the scene, in numpy."""
    eye, f, up = (np.asarray(a, np.float64) for a in (camera.eye, camera.forward, camera.up))
    right = np.cross(f, up)
    t = np.tan(camera.yfov / 2)
    s = (np.arange(size * sub) + 0.5) / (size * sub) * 2 - 1
    x, y = np.meshgrid(s, -s)
    d = (f + x[..., None] * t * right + y[..., None] * t * up).reshape(-1, 3)
    nearest, ids = np.full(len(d), np.inf), np.full(len(d), -1)
    for k, obj in enumerate(scene.objects):
        for a, b, c in np.asarray(obj.positions, np.float64)[obj.indices]:
            e1, e2, o = b - a, c - a, eye - a
            p, q = np.cross(d, e2), np.cross(o, e1)
            det = p @ e1
            if abs(det).max() < 1e-12:
                continue
            with np.errstate(divide="ignore", invalid="ignore"):
                u, v, dist = (p @ o) / det, (d @ q) / det, (q @ e2) / det
            hit = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (dist > 0) & (dist < nearest)
            nearest[hit], ids[hit] = dist[hit], k
    ids = ids.reshape(size, sub, size, sub).transpose(0, 2, 1, 3).reshape(size, size, sub * sub)
    return np.where(np.all(ids == ids[..., :1], axis=-1), ids[..., 0], -1)


@pytest.mark.slow
def test_cornell_box_capture_matches_mitsuba(tmp_path):
    """Deliberate bugs this catches (tried, never committed), with the whole-image MAE (2.09 %,
    bound 5 %) that alone let both pass:
    - the light maps x1.05 at their upload (viewer/gpu_lightmaps.py): every surface's
      bias goes to +4.4 % (ceiling) .. +5.7 % (large box), from -0.55 .. +0.61 %, past the
      +-2.5 % bound, and its MAE to 4.5 .. 6.7 % (bounds 3 % / 5.5 %); whole image 3.72 %;
    - the light-map look-up shifted by half a texel (shaders/raster_surface.glsl, uv + 0.5 /
      textureSize along +-u, +-v, or both): the floor's MAE goes from 2.25 % to 4.1 .. 6.3 %
      (bound 3 %) in all six directions, with other surfaces failing too in each (back wall,
      boxes, the diagonal shifts on every wall); whole image 2.63 .. 3.21 %."""
    from scipy import ndimage

    from glint.bake.gltf_loader import load_scene
    from glint.scenes import builtin_path

    out = tmp_path / "cb.exr"
    result = subprocess.run(
        [sys.executable, "-m", "glint", "capture", "cornell-box", "--camera", "sensor", "--size", "128x128",
         "--supersample", str(SUPERSAMPLE), "-o", str(out), "--bake-dir", str(tmp_path / "cb.bake"),
         "-q", "preview"],
        check=False, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    image, reference = read_image(out), read_image(REFERENCE)
    assert image.shape == reference.shape == (128, 128, 3)
    image, reference = image.astype(np.float64), reference.astype(np.float64)
    error = relative_mae(image, reference)
    print(f"relative MAE against Mitsuba 3: {error:.4f}")
    assert error <= 0.05
    # The error is not hiding a misplaced image: shifting by one pixel makes it clearly worse.
    assert relative_mae(np.roll(image, 1, axis=1), reference) > error + 0.01

    scene = load_scene(builtin_path("cornell-box"))
    camera = next(c for c in scene.cameras if c.name == "sensor")
    ids = object_ids(scene, camera, 128)
    names = [o.name for o in scene.objects]
    lamps = [k for k, o in enumerate(scene.objects) if scene.material_of(o).is_emissive]
    assert [names[k] for k in lamps] == ["light"]

    # The lamp's interior pixels: the reference shows the emitted radiance there (Mitsuba's area
    # light, our emissive material: 18.387, 13.9873, 6.75357) plus the little its white diffuse
    # surface reflects (measured +1.2 %, +0.6 %, +0.5 %), and so do we (measured: equal within
    # 0.02 %). This checks that the ray-cast masks line up with both images: a mask off by a
    # pixel takes in the dark ceiling (the lamp without erosion: 1.4 % too dark in both).
    lamp = ndimage.binary_erosion(ids == lamps[0])
    emission = scene.materials[scene.objects[lamps[0]].material].emission
    assert lamp.sum() >= 30
    lamp_ref = reference[lamp].mean(axis=0)
    assert np.all(lamp_ref >= emission) and np.all(lamp_ref <= 1.02 * emission), lamp_ref
    np.testing.assert_allclose(image[lamp].mean(axis=0), lamp_ref, rtol=0.005)

    # Per surface, lamp excluded. Measured at this test's bake (seed 0), in %:
    #   surface     bias   MAE     (bakes with seeds 1..4: bias, MAE)
    #   floor      -0.16   2.25    -0.6..+0.2, 2.1..2.2
    #   ceiling    -0.55   1.78    -0.0..+0.4, 1.8..2.2
    #   back       +0.11   1.40    -0.2..+0.2, 1.2..1.3
    #   green-wall +0.07   1.15    -0.2..+0.4, 1.1..1.2
    #   red-wall   +0.12   1.63    -0.5..-0.0, 1.4..1.5
    #   small-box  -0.23   3.92    -1.2..-0.0, 4.0..4.5
    #   large-box  +0.61   1.82    -0.3..+0.5, 1.7..1.9
    # (the noise of the 128-sample preview bake, its texel-scale interpolation, and the
    # reference's own noise). The bias bound, 2.5 %, sits between the worst seed's 1.2 % and the
    # 4.4 % that a 5 % scale gives on the least-lit surface. The MAE bound, 3 %, is ~0.8 points
    # above the worst seed, and under the 4.1 % a half-texel shift gives the floor. The small
    # box gets 5.5 %: its faces are ~10 texels wide, so most of its pixels are near an edge or
    # a contact, where the light map's bilinear interpolation departs from the reference.
    failures = []
    for k, name in enumerate(names):
        if k in lamps:
            continue
        mask = ndimage.binary_erosion(ids == k)
        assert mask.sum() >= 500, (name, mask.sum())
        ours, theirs = image[mask], reference[mask]
        bias = (ours - theirs).sum() / theirs.sum()
        mae = relative_mae(ours, theirs)
        bound = MAE_BOUND.get(name, MAE_DEFAULT)
        print(f"{name:10s} {mask.sum():5d} px: bias {bias:+.4f}, relative MAE {mae:.4f} (bound {bound})")
        if abs(bias) > BIAS_BOUND:
            failures.append(f"{name}: bias {bias:+.4f} beyond +-{BIAS_BOUND}")
        if mae > bound:
            failures.append(f"{name}: relative MAE {mae:.4f} above {bound}")
    assert not failures, "; ".join(failures)
