"""Light-map unwrap (bake/unwrap.py): charts do not overlap, padding is kept, density holds."""
import numpy as np
import pytest
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from glint.bake.texels import rasterize_texels
from glint.bake.unwrap import unwrap
from glint.core.errors import GlintError
from glint.core.scene import Object

DENSITY = 16.0
PADDING = 2


def _object(mesh, name, offset=(0.0, 0.0, 0.0)):
    return Object(name=name, positions=np.asarray(mesh.vertices, np.float64) + offset,
                  normals=np.asarray(mesh.vertex_normals, np.float32),
                  indices=np.asarray(mesh.faces, np.int64), material=0)


def _scene():
    return [
        _object(trimesh.creation.icosphere(2, 0.5), "sphere", (3.0, 0.0, 0.0)),
        _object(trimesh.creation.box((2.0, 1.0, 0.5)), "box"),
        _object(trimesh.creation.cylinder(0.3, 1.0, sections=24), "cylinder", (0.0, 2.0, 0.0)),
        _object(trimesh.creation.torus(0.6, 0.15, major_sections=32, minor_sections=12), "torus"),
        _object(trimesh.creation.box((0.01, 0.01, 0.01)), "knob", (5.0, 5.0, 5.0)),
    ]


@pytest.fixture(scope="module")
def scene():
    return _scene()


@pytest.fixture(scope="module")
def atlas(scene):
    return unwrap(scene, DENSITY, PADDING)


@pytest.fixture(scope="module")
def paged(scene):
    return unwrap(scene, DENSITY, PADDING, max_page_size=64)


def _chart_labels(atlas):
    """Chart id of every triangle of every object: xatlas splits vertices at chart
    seams, so a chart is a connected component of triangles sharing new vertices."""
    labels, offset = [], 0
    for c in atlas.objects:
        n, t = len(c.uv), c.indices
        graph = coo_matrix((np.ones(t.size), (np.repeat(t[:, 0], 3), t.ravel())), shape=(n, n))
        count, vertex_label = connected_components(graph, directed=False)
        labels.append(vertex_label[t[:, 0]] + offset)
        offset += count
    return labels


def _centre_claims(atlas, labels):
    """(page, texel, chart) for every texel centre inside a triangle; a plain per-triangle rasteriser."""
    W, H = atlas.width, atlas.height
    claims = []
    for c, lab in zip(atlas.objects, labels):
        uv = c.uv.astype(np.float64)[c.indices] * (W, H)
        for tri, (a, b, d) in enumerate(uv):
            lo, hi = np.floor(np.minimum(np.minimum(a, b), d)), np.ceil(np.maximum(np.maximum(a, b), d))
            xs, ys = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
            p = np.stack([xs.ravel() + 0.5, ys.ravel() + 0.5], axis=1)
            m = np.array([[b[0] - a[0], d[0] - a[0]], [b[1] - a[1], d[1] - a[1]]])
            if abs(np.linalg.det(m)) < 1e-12:
                continue
            s, t = np.linalg.solve(m, (p - a).T)
            inside = (s >= 0) & (t >= 0) & (s + t <= 1)
            px, py = p[inside, 0].astype(int), p[inside, 1].astype(int)
            ok = (px >= 0) & (px < W) & (py >= 0) & (py < H)
            page = c.page[c.indices[tri, 0]]
            for x, y in zip(px[ok], py[ok]):
                claims.append((page, y * W + x, lab[tri]))
    return np.unique(np.array(claims, np.int64), axis=0)


def _min_gap(label_map):
    """Fewest empty texels between texels of two different charts (Chebyshev), up to 8."""
    H, W = label_map.shape
    for d in range(1, 9):
        padded = np.pad(label_map, d, constant_values=-1)
        for dy in range(-d, d + 1):
            for dx in range(-d, d + 1):
                if max(abs(dy), abs(dx)) != d:
                    continue
                other = padded[d + dy:d + dy + H, d + dx:d + dx + W]
                if ((label_map >= 0) & (other >= 0) & (other != label_map)).any():
                    return d - 1
    return 8


def test_charts_reproduce_the_original_geometry(scene, atlas):
    for obj, c in zip(scene, atlas.objects):
        assert c.vmapping.dtype == np.int64 and c.indices.dtype == np.int64
        assert c.uv.dtype == np.float32 and c.page.dtype == np.int32
        assert c.indices.shape == obj.indices.shape
        np.testing.assert_array_equal(c.vmapping[c.indices], obj.indices)
        assert c.uv.min() >= 0.0 and c.uv.max() <= 1.0
        # all three corners of a triangle on one page
        assert (c.page[c.indices] == c.page[c.indices[:, :1]]).all()
    assert atlas.pages == 1 and atlas.texels_per_metre == DENSITY and atlas.padding == PADDING


def test_charts_do_not_overlap_at_texel_centres(atlas):
    labels = _chart_labels(atlas)
    claims = _centre_claims(atlas, labels)
    page_texel = claims[:, 0] * atlas.width * atlas.height + claims[:, 1]
    assert len(claims) > 1000
    assert len(np.unique(page_texel)) == len(page_texel), "a texel centre lies in two charts"


@pytest.mark.parametrize("which", ["atlas", "paged"])
def test_padding_between_charts_is_kept(scene, which, request):
    atlas = request.getfixturevalue(which)
    labels = _chart_labels(atlas)
    assert sum(len(np.unique(lab)) for lab in labels) >= 20
    # conservative texels (what the bake samples) of different charts
    for page in rasterize_texels(scene, atlas):
        label_map = np.full(page.object.shape, -1)
        covered = page.object >= 0
        for k, lab in enumerate(labels):
            mine = page.object == k
            label_map[mine] = lab[page.triangle[mine]]
        assert covered.any()
        assert _min_gap(label_map) >= PADDING


def test_texel_density_per_object(scene, atlas):
    W, H = atlas.width, atlas.height
    for obj, c in zip(scene, atlas.objects):
        if obj.name == "knob":
            continue
        t = c.uv.astype(np.float64)[c.indices] * (W, H)
        texel_area = 0.5 * np.abs(_cross2(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])).sum()
        density = np.sqrt(texel_area / obj.area)
        assert abs(density / DENSITY - 1) < 0.25, (obj.name, density)


def test_tiny_object_still_gets_texels(scene, atlas):
    page = rasterize_texels(scene, atlas)[0]
    knob = [o.name for o in scene].index("knob")
    # 6 faces of 0.16 x 0.16 texels at the asked density: less than one texel in all
    assert (page.object == knob).sum() >= 6 * 4


def test_several_pages_when_the_page_is_small(scene, paged):
    assert paged.pages > 1
    assert paged.width == paged.height == 64
    pages = np.concatenate([c.page for c in paged.objects])
    assert pages.min() == 0 and pages.max() == paged.pages - 1
    labels = _chart_labels(paged)
    claims = _centre_claims(paged, labels)
    page_texel = claims[:, 0] * 64 * 64 + claims[:, 1]
    assert len(np.unique(page_texel)) == len(page_texel)


def test_single_page_is_cropped_to_its_charts(scene, atlas):
    # The page is the charts' extent plus padding, rounded to 4 (RGB half rows stay 4-byte aligned).
    assert atlas.width % 4 == 0 and atlas.height % 4 == 0
    total_area = sum(o.area for o in scene if o.name != "knob") * DENSITY ** 2
    assert total_area < atlas.width * atlas.height < 3 * total_area


def test_unwrap_is_deterministic(scene, atlas):
    again = unwrap(_scene(), DENSITY, PADDING)
    assert (again.width, again.height, again.pages) == (atlas.width, atlas.height, atlas.pages)
    for a, b in zip(atlas.objects, again.objects):
        for field in ("vmapping", "indices", "uv", "page"):
            assert getattr(a, field).tobytes() == getattr(b, field).tobytes()


def test_hopeless_density_is_refused_with_advice():
    wall = _object(trimesh.creation.box((100.0, 100.0, 0.1)), "wall")
    with pytest.raises(GlintError, match="texels_per_metre"):
        unwrap([wall], 1000.0, max_page_size=1024)


def _cross2(u, v):
    return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]


def test_uncharted_zero_area_triangle_gets_no_texels():
    # triangle 1 is a line (the loader normally drops these; the unwrap must not choke)
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0]], np.float64)
    obj = Object("degenerate", v, np.tile([0.0, 0.0, 1.0], (5, 1)).astype(np.float32),
                 np.array([[0, 1, 2], [1, 3, 4]]), 0)
    atlas = unwrap([obj], DENSITY)
    c = atlas.objects[0]
    np.testing.assert_array_equal(c.vmapping[c.indices], obj.indices)
    assert (c.page == 0).all()
    assert (c.uv[c.indices[1]] == 0).all()
    page = rasterize_texels([obj], atlas)[0]
    assert set(np.unique(page.triangle[page.object >= 0])) == {0}


def _crash_first_time(marker):
    import os
    import signal
    from pathlib import Path

    if not Path(marker).exists():
        Path(marker).write_text("crashed once")
        os.kill(os.getpid(), signal.SIGSEGV)  # what an xatlas crash looks like to the parent
    return "charts"


def test_a_crashing_unwrap_is_retried_and_errors_are_passed_on(tmp_path):
    from glint.bake.unwrap import _isolated

    assert _isolated(_crash_first_time, str(tmp_path / "marker")) == "charts"
    with pytest.raises(ZeroDivisionError):
        _isolated(lambda: 1 / 0)
