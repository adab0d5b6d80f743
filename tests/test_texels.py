"""Texel rasterisation (bake/texels.py), bilinear look-ups and dilation (bake/dilate.py)."""
import numpy as np
import pytest
import trimesh

from glint.bake.dilate import dilate, dilate_to_fill
from glint.bake.texels import rasterize_texels
from glint.bake.unwrap import unwrap
from glint.core.image_io import sample_bilinear
from glint.core.scene import Object

DENSITY = 16.0


def _object(vertices, faces, name, normals=None):
    vertices = np.asarray(vertices, np.float64)
    if normals is None:
        normals = trimesh.Trimesh(vertices, faces, process=False).vertex_normals
    return Object(name=name, positions=vertices, normals=np.asarray(normals, np.float32),
                  indices=np.asarray(faces, np.int64), material=0)


def _quad(w, h, name="quad", origin=(0.0, 0.0, 0.0)):
    """w x h metres in the XZ plane facing +Y."""
    v = np.array([[0, 0, 0], [0, 0, h], [w, 0, h], [w, 0, 0]], np.float64) + origin
    return _object(v, [[0, 1, 2], [0, 2, 3]], name, normals=np.tile([0.0, 1.0, 0.0], (4, 1)))


@pytest.fixture(scope="module")
def scene():
    sphere = trimesh.creation.icosphere(2, 0.5)
    box = trimesh.creation.box((1.0, 0.6, 0.4))
    box.unmerge_vertices()  # hard edges: each face its own vertices and normal
    sliver = _object([[0, 0, 0], [2.0, 0, 0], [1.0, 0.01, 0]], [[0, 1, 2]], "sliver",
                     normals=np.tile([0.0, 0.0, 1.0], (3, 1)))
    return [_object(sphere.vertices + (2.0, 0, 0), sphere.faces, "sphere"),
            _object(box.vertices, box.faces, "box", normals=None),
            _quad(1.0, 2.0, origin=(0.0, -1.0, 0.0)), sliver]


@pytest.fixture(scope="module")
def baked(scene):
    atlas = unwrap(scene, DENSITY, 2)
    return atlas, rasterize_texels(scene, atlas)


def _per_texel_triangles(scene, page):
    """World corners (n, 3, 3) of the triangle each covered texel names."""
    covered = page.object >= 0
    corners = np.empty((covered.sum(), 3, 3))
    objs, tris = page.object[covered], page.triangle[covered]
    for k, obj in enumerate(scene):
        mine = objs == k
        corners[mine] = obj.positions[obj.indices[tris[mine]]]
    return covered, corners


def test_page_layout(baked):
    atlas, pages = baked
    assert len(pages) == atlas.pages == 1
    page = pages[0]
    H, W = atlas.height, atlas.width
    assert page.position.shape == page.normal.shape == (H, W, 3)
    assert page.object.shape == page.triangle.shape == (H, W)
    assert page.position.dtype == page.normal.dtype == np.float32
    assert page.object.dtype == page.triangle.dtype == np.int32
    empty = page.object < 0
    assert ((page.triangle < 0) == empty).all()
    assert np.isfinite(page.position).all()
    assert not page.position[empty].any() and not page.normal[empty].any()


def test_texel_positions_lie_on_their_triangles(scene, baked):
    page = baked[1][0]
    covered, t = _per_texel_triangles(scene, page)
    p = page.position[covered].astype(np.float64)
    # barycentrics of p in its triangle's plane, and the distance to that plane
    e1, e2, d = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0], p - t[:, 0]
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.abs((d * n).sum(axis=1)).max() < 1e-5
    g = np.stack([(e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)], axis=1)
    r1, r2 = (d * e1).sum(1), (d * e2).sum(1)
    det = g[:, 0] * g[:, 2] - g[:, 1] ** 2
    s, u = (g[:, 2] * r1 - g[:, 1] * r2) / det, (g[:, 0] * r2 - g[:, 1] * r1) / det
    # a 2 m x 1 cm sliver makes the tolerance in barycentric units larger there
    assert min(s.min(), u.min(), (1 - s - u).min()) > -1e-3


def test_normals_are_unit_and_follow_the_surface(scene, baked):
    page = baked[1][0]
    covered, t = _per_texel_triangles(scene, page)
    normal = page.normal[covered]
    np.testing.assert_allclose(np.linalg.norm(normal, axis=1), 1.0, atol=1e-5)
    face = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    face /= np.linalg.norm(face, axis=1, keepdims=True)
    # smooth sphere normals lean from the face normal by a few degrees only
    assert (np.sum(normal * face, axis=1) > 0.9).all()
    quad = page.object == 2
    np.testing.assert_allclose(page.normal[quad], np.tile([0, 1, 0], (quad.sum(), 1)), atol=1e-6)


def test_quad_texels_match_its_area_and_the_uv_convention(scene, baked):
    atlas, (page,) = baked
    quad = page.object == 2
    # 1 m x 2 m at 16 texels/m: 16 x 32 texels plus at most a conservative ring
    assert 16 * 32 <= quad.sum() <= 18 * 34
    # interior texels (all 8 neighbours on the quad too) sample the point at their
    # centre uv ((x+0.5)/W, (y+0.5)/H): map that uv to 3D independently
    padded = np.pad(quad, 1)
    H, W = quad.shape
    interior = np.ones_like(quad)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            interior &= padded[1 + dy:1 + dy + H, 1 + dx:1 + dx + W]
    ys, xs = np.nonzero(interior)
    assert len(ys) >= 14 * 30
    uv = np.stack([(xs + 0.5) / W, (ys + 0.5) / H], axis=1)
    c = atlas.objects[2]
    expected = np.full((len(ys), 3), np.nan)
    for tri in range(len(c.indices)):
        a, b, d = c.uv[c.indices[tri]].astype(np.float64)
        m = np.array([[b[0] - a[0], d[0] - a[0]], [b[1] - a[1], d[1] - a[1]]])
        s, t = np.linalg.solve(m, (uv - a).T)
        inside = (s >= -1e-9) & (t >= -1e-9) & (s + t <= 1 + 1e-9)
        P = scene[2].positions[c.vmapping[c.indices[tri]]]
        expected[inside] = P[0] + s[inside, None] * (P[1] - P[0]) + t[inside, None] * (P[2] - P[0])
    assert not np.isnan(expected).any()
    np.testing.assert_allclose(page.position[ys, xs], expected, atol=1e-5)
    # neighbouring texel centres are 1/16 m apart on the quad
    step = np.linalg.norm(page.position[ys[0], xs[0] + 1] - page.position[ys[0], xs[0]])
    assert step == pytest.approx(1 / DENSITY, rel=0.02)


def test_thin_sliver_is_covered_conservatively(baked):
    page = baked[1][0]
    # 2 m long, less than one texel wide: centre sampling alone would miss most of it
    assert (page.object == 3).sum() >= 2 * DENSITY


def test_rasterisation_is_deterministic(scene, baked):
    atlas, (page,) = baked
    (again,) = rasterize_texels(scene, atlas)
    for field in ("position", "normal", "object", "triangle"):
        assert getattr(page, field).tobytes() == getattr(again, field).tobytes()


def test_batches_do_not_change_the_result(scene, baked, monkeypatch):
    import glint.bake.texels

    atlas, (page,) = baked
    monkeypatch.setattr(glint.bake.texels, "BATCH", 64)  # hundreds of batches instead of one
    (small,) = rasterize_texels(scene, atlas)
    for field in ("position", "normal", "object", "triangle"):
        assert getattr(page, field).tobytes() == getattr(small, field).tobytes()


def test_bilinear_matches_hand_computed_values():
    image = np.array([[[0.0], [1.0]], [[2.0], [3.0]]], np.float32)  # H = W = 2
    uv = np.array([[0.5, 0.5],  # between all four centres
                   [0.25, 0.25],  # centre of texel (0, 0)
                   [0.375, 0.25],  # a quarter of the way to texel (0, 1)
                   [0.0, 0.0],  # clamped to the edge
                   [1.0, 1.0],
                   [0.6, 0.9]])  # x = 0.7, y = 1.3 -> row clamped to 1
    expected = [1.5, 0.0, 0.25, 0.0, 3.0, 2.7]
    np.testing.assert_allclose(sample_bilinear(image, uv)[:, 0], expected, atol=1e-6)
    # three channels on a 3 x 4 image: (y, x) = (1.0, 1.5) of texel centres
    rgb = np.arange(36, dtype=np.float32).reshape(3, 4, 3)
    out = sample_bilinear(rgb, np.array([[2.0 / 4, 1.5 / 3]]))
    np.testing.assert_allclose(out[0], 0.5 * (rgb[1, 1] + rgb[1, 2]), atol=1e-5)
    assert sample_bilinear(rgb[..., 0], np.array([[0.125, 0.5]])).shape == (1,)


def test_dilation_fills_a_hole_with_the_neighbour_average():
    rng = np.random.default_rng(1)
    image = rng.random((5, 5, 3)).astype(np.float32)
    valid = np.ones((5, 5), bool)
    valid[2, 2] = False
    image[2, 2] = 100.0
    out = dilate(image, valid, 1)
    ring = np.ones((3, 3), bool)
    ring[1, 1] = False
    expected = image[1:4, 1:4][ring].astype(np.float64).mean(axis=0)
    np.testing.assert_allclose(out[2, 2], expected, rtol=1e-6)
    np.testing.assert_array_equal(out[valid], image[valid])
    assert image[2, 2, 0] == 100.0  # input untouched


def test_dilation_grows_one_ring_per_pass():
    image = np.zeros((7, 7, 1), np.float32)
    valid = np.zeros((7, 7), bool)
    valid[0, 0], image[0, 0] = True, 4.0
    valid[0, 2], image[0, 2] = True, 8.0
    one = dilate(image, valid, 1)
    assert one[0, 1, 0] == pytest.approx(6.0)  # between the two valid texels
    assert one[1, 0, 0] == pytest.approx(4.0) and one[1, 3, 0] == pytest.approx(8.0)
    assert one[2, 0, 0] == 0.0  # two rings away: untouched after one pass
    two = dilate(image, valid, 2)
    # (2, 0) sees (1, 0) = 4 and (1, 1) = 6 from the first ring
    assert two[2, 0, 0] == pytest.approx(5.0)
    assert two[3, 0, 0] == 0.0


def test_dilate_to_fill_leaves_no_empty_texel():
    image = np.zeros((40, 33, 3), np.float32)
    valid = np.zeros((40, 33), bool)
    valid[10:14, 5:9], image[10:14, 5:9] = True, (1.0, 2.0, 3.0)
    valid[30, 30], image[30, 30] = True, (5.0, 5.0, 5.0)
    out = dilate_to_fill(image, valid, 2)
    np.testing.assert_array_equal(out[valid], image[valid])
    assert out.dtype == np.float32 and np.isfinite(out).all()
    # every texel is a blend of the valid values, none left black
    assert (out[..., 0] >= 1.0 - 1e-6).all() and (out[..., 0] <= 5.0 + 1e-6).all()
    np.testing.assert_allclose(out[0, 0], (1.0, 2.0, 3.0), atol=1e-5)  # near the block, far from (30, 30)
    assert not dilate_to_fill(np.zeros((4, 4, 1), np.float32), np.zeros((4, 4), bool)).any()
