"""bench/mirror_projection.py: the two-step mirror-buffer sample projection and the MIP level.

The mirror buffers here are ray-cast analytically from the mirror camera through
every texel centre against a few rectangles: a mirror floor (y = 0), a back wall
and the front face of a box standing on the floor.
"""
import math

import numpy as np
import pytest

from glint.bench.mirror_projection import (
    ellipse_mip_level,
    fetch,
    lobe_extremes,
    lobe_mip_level,
    max_mip_level,
    project,
    project_sample,
    texel_centres,
    texel_index,
    unproject_rays,
)
from glint.viewer.camera import ViewCamera
from glint.viewer.mirror_camera import MirrorCamera

SIZE = (135, 240)  # (H, W) of the mirror buffer
ASPECT = SIZE[1] / SIZE[0]
FLOOR_N = np.array([0.0, 1.0, 0.0])

# (centre, normal, half extents along (x, y, z)): axis-aligned rectangles
BACK_WALL = ((0.0, 3.0, -4.0), (0.0, 0.0, 1.0), (10.0, 3.0, 0.0))
BOX_FACE = ((0.0, 0.4, -2.0), (0.0, 0.0, 1.0), (0.6, 0.4, 0.0))
SIDE_WALL = ((-3.0, 3.0, 0.0), (1.0, 0.0, 0.0), (0.0, 3.0, 10.0))
SCENE = [BACK_WALL, BOX_FACE, SIDE_WALL]


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def cast(origins, dirs, rects):
    """Nearest hit (t > 0) of rays against rectangles -> (t, position, normal); misses: t inf, zeros."""
    best_t = np.full(origins.shape[:-1], np.inf)
    pos = np.zeros(origins.shape)
    nrm = np.zeros(origins.shape)
    for c, n, ext in rects:
        c, n, ext = map(np.asarray, (c, n, ext))
        denom = dirs @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((c - origins) @ n) / denom
            x = origins + t[..., None] * dirs
        inside = np.all(np.abs(x - c) <= ext + 1e-12, axis=-1) & (np.abs(denom) > 1e-12) & (t > 1e-9)
        better = inside & (t < best_t)
        best_t = np.where(better, t, best_t)
        pos = np.where(better[..., None], x, pos)
        nrm = np.where(better[..., None], n, nrm)
    return best_t, pos, nrm


def mirror_buffer(vp_m, rects):
    """(positions, normals) images of the mirror pass: what the mirror camera sees above the floor."""
    origins, dirs = unproject_rays(vp_m, texel_centres(SIZE))
    # Clipped at the mirror plane: start the rays where they cross y = 0 (from below).
    t0 = np.maximum(0.0, -origins[..., 1] / dirs[..., 1])
    t, pos, nrm = cast(origins + t0[..., None] * dirs, dirs, rects)
    return pos, nrm


@pytest.fixture(scope="module")
def setup():
    cam = ViewCamera.look_at((0.0, 1.5, 3.0), (0.0, 0.6, -2.0), yfov=math.radians(55), znear=0.05, zfar=100)
    m = MirrorCamera(cam, (0, 0, 0), FLOOR_N)
    vp_m = m.view_projection(ASPECT).astype(np.float64)
    pos, nrm = mirror_buffer(vp_m, SCENE)
    return cam, vp_m, pos, nrm


def mirror_dir(cam, p):
    d = _unit(p - cam.eye)
    return d - 2 * (d @ FLOOR_N) * FLOOR_N


def rotate(v, axis, angle):
    """Rodrigues rotation of v about unit axis."""
    axis = _unit(axis)
    return (v * math.cos(angle) + np.cross(axis, v) * math.sin(angle)
            + axis * (axis @ v) * (1 - math.cos(angle)))


def true_uv(vp_m, p, w, rects=SCENE):
    t, x, n = cast(p[None], w[None], rects)
    assert np.isfinite(t[0])
    uv, ok = project(vp_m, x[0])
    assert ok
    return uv, x[0], n[0]


def test_conventions():
    assert texel_index(np.array([0.0, 0.0]), SIZE) == (0, 0)
    centres = texel_centres(SIZE)
    assert np.allclose(centres[0, 0], (0.5 / SIZE[1], 0.5 / SIZE[0]))
    assert np.allclose(centres[7, 11], (11.5 / SIZE[1], 7.5 / SIZE[0]))
    row, col = texel_index(centres, SIZE)
    assert np.array_equal(row, np.arange(SIZE[0])[:, None] + 0 * col)
    assert np.array_equal(col, np.arange(SIZE[1])[None, :] + 0 * row)
    assert texel_index(np.array([-0.3, 1.7]), SIZE) == (SIZE[0] - 1, 0)  # clamp to edge
    img = np.arange(SIZE[0] * SIZE[1] * 3, dtype=float).reshape(SIZE + (3,))
    assert np.array_equal(fetch(img, centres), img)
    # uv (0, 0) is NDC (-1, -1): the bottom-left of the image, row 0.
    vp = np.eye(4)
    uv, ok = project(vp, np.array([-1.0, -1.0, 0.0]))
    assert ok and np.allclose(uv, 0)
    uv, ok = project(vp, np.array([0.0, 0.0, 0.0]), 1.0)
    assert np.allclose(uv, 0.5)


def test_centre_sample_reads_the_pixel_of_p(setup):
    cam, vp_m, pos, nrm = setup
    vp = cam.view_projection(ASPECT).astype(np.float64)
    rng = np.random.default_rng(5)
    p = np.c_[rng.uniform(-1.5, 1.5, 50), np.zeros(50), rng.uniform(-2.5, 1.0, 50)]
    uv_main, ok = project(vp, p)
    assert ok.all()
    for i in range(len(p)):
        w_r = mirror_dir(cam, p[i])
        res = project_sample(p[i], w_r, vp_m, pos, nrm)
        assert np.allclose(res.uv_centre, uv_main[i], atol=1e-6)  # pixel-aligned with the main view
        t, x, _ = cast(p[i][None], w_r[None], SCENE)
        if np.isfinite(t[0]):
            # The mirror ray's hit is seen by the mirror camera at P's pixel ...
            assert np.allclose(project(vp_m, x[0])[0], uv_main[i], atol=1e-6)
            # ... and the buffer there holds it (up to the texel's footprint).
            assert np.linalg.norm(fetch(pos, uv_main[i]) - x[0]) < 0.1
            # The centre direction maps back onto its own position.
            assert np.allclose(res.uv, uv_main[i], atol=1e-6)


def test_step_one_is_exact_on_the_plane_of_the_mirror_hit(setup):
    cam, vp_m, pos, nrm = setup
    p = np.array([0.3, 0.0, 0.5])
    w_r = mirror_dir(cam, p)
    _, x_r, n_r = true_uv(vp_m, p, w_r)
    assert np.allclose(n_r, BACK_WALL[1])  # the mirror ray hits the back wall
    checked = 0
    for axis in ((1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, -2, 1)):
        for angle in (-0.08, -0.03, 0.01, 0.05):
            w = rotate(w_r, np.asarray(axis, float), angle)
            uv_ref, _, n_hit = true_uv(vp_m, p, w)
            if not np.allclose(n_hit, BACK_WALL[1]):
                continue
            res = project_sample(p, w, vp_m, pos, nrm, second_step=False)
            assert res.valid and res.hit_first
            assert np.allclose(res.uv_first, uv_ref, atol=1e-9)
            assert np.allclose(res.uv, uv_ref, atol=1e-9)
            # The second step looks up the same plane: it changes nothing.
            res2 = project_sample(p, w, vp_m, pos, nrm)
            assert np.allclose(res2.uv, uv_ref, atol=1e-9)
            checked += 1
    assert checked >= 15


def test_second_step_fixes_a_tangent_plane_change(setup):
    cam, vp_m, pos, nrm = setup
    p = np.array([0.0, 0.0, -0.5])
    w_r = mirror_dir(cam, p)
    _, x_r, n_r = true_uv(vp_m, p, w_r)
    assert np.allclose(n_r, BOX_FACE[1]) and abs(x_r[2] + 2) < 1e-9  # centre: on the box face
    improved = 0
    for angle in (0.10, 0.14, 0.2):  # tilted upwards: passes over the box, hits the back wall
        w = rotate(w_r, np.array([1.0, 0.0, 0.0]), angle)
        assert w[1] > w_r[1]
        uv_ref, x_true, n_true = true_uv(vp_m, p, w)
        assert abs(x_true[2] + 4) < 1e-9  # truly on the back wall
        res = project_sample(p, w, vp_m, pos, nrm)
        assert res.valid and res.hit_first and res.hit_second
        err1 = np.linalg.norm((res.uv_first - uv_ref) * SIZE[::-1])
        err2 = np.linalg.norm((res.uv - uv_ref) * SIZE[::-1])
        assert err1 > 2.0  # step 1 (box plane) is off by pixels
        assert err2 < err1 and err2 < 1e-6  # step 2 lands on the true intersection
        assert np.allclose(res.point, x_true, atol=1e-9)
        improved += 1
    assert improved == 3


def test_samples_that_meet_background_go_to_infinity(setup):
    cam, vp_m, _, _ = setup
    # Only the box: everything around it is background (normal 0).
    pos, nrm = mirror_buffer(vp_m, [BOX_FACE])
    p = np.array([0.0, 0.0, -0.5])
    w_r = mirror_dir(cam, p)
    w = rotate(w_r, np.array([1.0, 0.0, 0.0]), 0.3)  # well above the box: sky
    res = project_sample(p, w, vp_m, pos, nrm)
    uv_inf, ok = project(vp_m, w, 0.0)
    assert ok and res.valid and res.at_infinity.all()
    assert np.allclose(res.uv, uv_inf, atol=1e-12)
    # A far-away wall converges to the same look-up.
    far_wall = ((0.0, 500.0, -1000.0), (0.0, 0.0, 1.0), (5000.0, 500.0, 0.0))
    uv_far, _, _ = true_uv(vp_m, p, w, [far_wall])
    assert np.linalg.norm((uv_far - uv_inf) * SIZE[::-1]) < 1.0


def test_no_nan_at_grazing_and_degenerate_directions(setup):
    cam, vp_m, pos, nrm = setup
    rng = np.random.default_rng(6)
    k = 4000
    p = np.c_[rng.uniform(-3, 3, k), np.zeros(k), rng.uniform(-4, 3, k)]
    w = _unit(rng.normal(size=(k, 3)))
    w[: k // 4, 1] = 0.0  # exactly along the floor
    w[k // 4: k // 2, 1] = 1e-7  # grazing
    w[k // 2: k // 2 + 10] = (0.0, 0.0, 1.0)  # parallel to the walls' normals' planes
    w[k // 2 + 10: k // 2 + 20] = (1.0, 0.0, 0.0)
    w = _unit(w)
    res = project_sample(p, w, vp_m, pos, nrm)
    for a in (res.uv, res.uv_first, res.point, res.point_first):
        assert np.isfinite(a).all()
    assert res.uv.shape == (k, 2) and res.valid.shape == (k,)
    ext = lobe_extremes(w, _unit(np.cross(w, (0.3, 1, 0.2))), _unit(np.cross(w, np.cross(w, (0.3, 1, 0.2)))),
                        0.05, 0.02)
    lvl = lobe_mip_level(p, ext, 7, vp_m, pos, nrm)
    assert np.isfinite(lvl).all() and (lvl >= 0).all() and (lvl <= max_mip_level(SIZE)).all()


def test_ellipse_mip_level_formula():
    h, w = SIZE
    c = np.array([0.5, 0.5])
    r = 16.0  # pixels

    def extremes(a, b):
        return np.array([c + a, c - a, c + b, c - b]) / np.array([w, h])

    circle = extremes(np.array([r, 0]), np.array([0, r]))
    for n in (1, 3, 7, 19):
        expected = 0.5 * math.log2(math.pi * r * r / n)
        assert ellipse_mip_level(circle, n, SIZE) == pytest.approx(expected)
        assert ellipse_mip_level(circle, n, SIZE, conjugate=False) == pytest.approx(expected)
    # Conjugate semi-diameters of an ellipse (a sheared circle): the area is |a x b|, not |a||b|.
    sheared = extremes(np.array([r, 0]), np.array([r, r]))
    assert ellipse_mip_level(sheared, 1, SIZE) == pytest.approx(0.5 * math.log2(math.pi * r * r))
    assert ellipse_mip_level(sheared, 1, SIZE, conjugate=False) > ellipse_mip_level(sheared, 1, SIZE)
    # Clamped: sub-pixel footprints -> 0, huge ones -> the last level.
    assert ellipse_mip_level(extremes(np.array([0.1, 0]), np.array([0, 0.1])), 1, SIZE) == 0.0
    huge = extremes(np.array([1e6, 0]), np.array([0, 1e6]))
    assert ellipse_mip_level(huge, 1, SIZE) == max_mip_level(SIZE)
    # Batched.
    both = np.stack([circle, sheared])
    assert ellipse_mip_level(both, 1, SIZE).shape == (2,)


def test_lobe_mip_level_grows_with_lobe_width_and_reflected_distance(setup):
    cam, vp_m, pos, nrm = setup
    p = np.array([0.0, 0.0, -0.5])  # mirror hit on the box face
    w_r = mirror_dir(cam, p)
    a = _unit(np.cross(w_r, FLOOR_N))
    b = np.cross(a, w_r)
    narrow = lobe_mip_level(p, lobe_extremes(w_r, a, b, 0.03, 0.03), 1, vp_m, pos, nrm)
    wide = lobe_mip_level(p, lobe_extremes(w_r, a, b, 0.06, 0.06), 1, vp_m, pos, nrm)
    assert narrow > 0.5  # not clamped
    assert wide == pytest.approx(narrow + 1.0, abs=0.05)  # twice the angle: four times the area
    seven = lobe_mip_level(p, lobe_extremes(w_r, a, b, 0.06, 0.06), 7, vp_m, pos, nrm)
    assert seven == pytest.approx(wide - 0.5 * math.log2(7))  # area shared by 7 samples
    # Without the box the same lobe reaches the back wall, farther from the floor: blurrier.
    pos2, nrm2 = mirror_buffer(vp_m, [BACK_WALL, SIDE_WALL])
    farther = lobe_mip_level(p, lobe_extremes(w_r, a, b, 0.03, 0.03), 1, vp_m, pos2, nrm2)
    assert farther > narrow + 0.5
    # Against the projection of the exact hit points.
    ext = lobe_extremes(w_r, a, b, 0.03, 0.03)
    uv = np.array([true_uv(vp_m, p, e, [BOX_FACE])[0] for e in ext])
    assert narrow == pytest.approx(ellipse_mip_level(uv, 1, SIZE), abs=1e-9)
