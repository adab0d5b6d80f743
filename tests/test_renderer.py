"""The renderer core on llvmpipe (EGL): hand-made bake directories with known answers.

Expected values come from the definitions, computed here in numpy: kd/pi * E
(Eq. 4.1), a pinhole projection written out from the camera's basis, the ACES fit
and sRGB formulas, block means; the sky convention from bake/lights.py's own numpy
code; camera matrices against pyrr's. None is read back from the code under test.
"""
from __future__ import annotations

import json
import math

import moderngl
import numpy as np
import pyrr
import pytest

from glint.core.bake_dir import FORMAT_VERSION, Bake, save_meshes, write_json
from glint.core.image_io import write_image
from glint.core.manifest import Camera, CameraPath
from glint.viewer.camera import ViewCamera, camera_path_at, gl_bytes, in_frustum
from glint.viewer.passes.resolve import ResolvePass
from glint.viewer.passes.tonemap import TonemapPass
from glint.viewer.renderer import Renderer

KD = (0.5, 0.25, 0.8)
E = (2.0, 1.0, 0.5)


# -- hand-made bake directories -------------------------------------------------------------------
def quad(center, u, v, lm_rect=(0.0, 0.0, 1.0, 1.0), page=0, normal_scale=1.0):
    """A mesh dict (bake_dir layout) for the rectangle center +- u +- v, CCW seen from cross(u, v).

    Corner order: (-u,-v), (+u,-v), (+u,+v), (-u,+v); light-map and texture uv run with
    +u and -v (texture v = 0 at the +v edge, as glTF puts (0, 0) at the image's top-left)."""
    c, u, v = (np.asarray(a, np.float64) for a in (center, u, v))
    positions = np.array([c - u - v, c + u - v, c + u + v, c - u + v], np.float32)
    n = np.cross(u, v)
    n = n / np.linalg.norm(n) * normal_scale
    u0, v0, u1, v1 = lm_rect
    lm_uv = np.array([[u0, v1], [u1, v1], [u1, v0], [u0, v0]], np.float32)
    uvs = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    return {"positions": positions, "normals": np.tile(n, (4, 1)).astype(np.float32), "uvs": uvs,
            "lm_uv": lm_uv, "lm_page": np.full(4, page, np.int32),
            "indices": np.array([[0, 1, 2], [0, 2, 3]], np.uint32), "vmapping": np.arange(4)}


def material(name="m", kd=KD, emission=(0, 0, 0), double_sided=False, texture=None, lobes=()):
    return {"name": name, "kd": list(kd), "emission": list(emission), "double_sided": double_sided,
            "lobes": list(lobes), "kd_texture": texture}


def make_bake(path, meshes, materials, object_materials, pages, *, sky=None, sky_map=None,
              textures=None, cameras=()):
    """Write a bake directory the way bake/pipeline.py lays it out, without baking anything."""
    (path / "lightmaps").mkdir(parents=True)
    (path / "textures").mkdir()
    names = []
    for k, page in enumerate(pages):
        names.append(f"lightmaps/page_{k}.exr")
        write_image(path / names[-1], np.asarray(page, np.float32), channels=("R", "G", "B", "A"))
    for i, image in (textures or {}).items():
        write_image(path / f"textures/material_{i}.exr", np.asarray(image, np.float32))
    if sky_map is not None:
        write_image(path / "sky.exr", np.asarray(sky_map, np.float32), half=False)
    save_meshes(path / "meshes.npz", meshes)
    objects = [{"name": f"object{i}", "material": m, "role": "diffuse",
                "bounds": [mesh["positions"].min(0).tolist(), mesh["positions"].max(0).tolist()],
                "triangles": len(mesh["indices"])} for i, (mesh, m) in enumerate(zip(meshes, object_materials))]
    h, w = np.asarray(pages[0]).shape[:2]
    write_json(path / "manifest.json", {
        "format": "glint-bake", "version": FORMAT_VERSION, "scene": {"name": "test", "source": None, "hash": ""},
        "settings": {}, "stages": {}, "objects": objects, "materials": materials,
        "lights": {"point": [], "spot": [], "directional": []}, "sky": sky, "cameras": list(cameras),
        "camera_paths": [], "atlas": {"width": w, "height": h, "pages": len(pages)}, "lightmaps": names,
        "statistics": {}})
    return Bake(path)


def _write_raw_exr(path, pixels):
    import OpenImageIO as oiio

    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), oiio.ImageSpec(w, h, c, oiio.FLOAT))
    assert out.write_image(np.ascontiguousarray(pixels, np.float32))
    out.close()


def constant_page(rgb, size=(8, 8)):
    page = np.ones((*size, 4), np.float32)
    page[..., :3] = rgb
    return page


def front_camera(distance=2.0, yfov=math.radians(60)):
    return ViewCamera.look_at((0, 0, distance), (0, 0, 0), (0, 1, 0), yfov, znear=0.01, zfar=100)


def render(ctx, bake, camera, size=(64, 48), supersample=1, exposure=0.0):
    r = Renderer(ctx, bake, supersample=supersample, exposure=exposure)
    r.render(camera, *size)
    out = r.read_linear(), r.read_srgb(), r.stats
    r.release()
    return out


# -- Eq. 4.1 through the whole chain --------------------------------------------------------------
def test_constant_light_map_gives_kd_over_pi_times_e(ctx, tmp_path):
    # A 20 m quad fills the view of a camera 2 m in front of it.
    bake = make_bake(tmp_path / "b", [quad((0, 0, 0), (10, 0, 0), (0, 10, 0))], [material()], [0],
                     [constant_page(E)])
    linear, srgb, stats = render(ctx, bake, front_camera(), size=(40, 30), supersample=2)
    expected = np.array(KD) / np.pi * np.array(E)
    assert linear.shape == (30, 40, 3) and linear.dtype == np.float32
    np.testing.assert_allclose(linear, np.broadcast_to(expected, linear.shape), rtol=1e-3, atol=0)
    assert stats["objects_drawn"] == 1 and stats["triangles"] == 2


def test_light_map_texel_convention_and_orientation(ctx, tmp_path):
    """E ramps linearly over texel indices (R along columns, G along rows): GL_LINEAR is exact
    on a linear ramp, so every pixel must show E at its uv under texel centres ((x+.5)/W, (y+.5)/H)
    with row 0 at v = 0."""
    W, H = 16, 8
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    page = np.stack([1 + 0.25 * x, 1 + 0.5 * y, np.full_like(x, 0.5), np.ones_like(x)], axis=-1)
    # The light-map rectangle stays one texel inside the page, away from the clamped border.
    u0, v0, u1, v1 = 1.5 / W, 1.5 / H, 14.5 / W, 6.5 / H
    half = 1.0
    bake = make_bake(tmp_path / "b", [quad((0, 0, 0), (half, 0, 0), (0, half, 0), (u0, v0, u1, v1))],
                     [material(kd=(1, 1, 1))], [0], [page])
    yfov = math.radians(40)
    distance = half / math.tan(yfov / 2) * 1.25  # the quad covers the central 80% of the view
    size = (50, 50)
    linear, _, _ = render(ctx, bake, front_camera(distance, yfov), size=size)
    # Pixel centre -> point on the plane z = 0 -> light-map uv (quad corner (-u,+v) is uv (u0, v0)).
    cols, rows = np.meshgrid(np.arange(size[0]) + 0.5, np.arange(size[1]) + 0.5)
    extent = distance * math.tan(yfov / 2)
    wx = (cols / size[0] * 2 - 1) * extent
    wy = (1 - rows / size[1] * 2) * extent
    inside = (np.abs(wx) < half * 0.95) & (np.abs(wy) < half * 0.95)
    lu = u0 + (wx + half) / (2 * half) * (u1 - u0)
    lv = v0 + (half - wy) / (2 * half) * (v1 - v0)
    expected = np.stack([1 + 0.25 * (lu * W - 0.5), 1 + 0.5 * (lv * H - 0.5), np.full_like(lu, 0.5)], -1) / np.pi
    assert inside.sum() > 1000
    np.testing.assert_allclose(linear[inside], expected[inside], rtol=2e-3)


def bilinear_repeat(image, u, v):
    """GL_LINEAR with GL_REPEAT at uv (texel (y, x) centred at ((x + .5) / W, (y + .5) / H))."""
    h, w = image.shape[:2]
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    at = lambda yy, xx: image[yy % h, xx % w]  # noqa: E731
    return ((1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x0 + 1))
            + fy * ((1 - fx) * at(y0 + 1, x0) + fx * at(y0 + 1, x0 + 1)))


def test_base_colour_texture_orientation(ctx, tmp_path):
    """Texture row 0 is the top of the image, at uv v = 0 (glTF); the quad's +v edge is up."""
    tex = np.array([[[1, 0, 0], [0, 1, 0]], [[0, 0, 1], [1, 1, 1]]], np.float32)  # 2x2: top row red, green
    bake = make_bake(tmp_path / "b", [quad((0, 0, 0), (1, 0, 0), (0, 1, 0))],
                     [material(kd=(1, 1, 1), texture="textures/material_0.exr")], [0], [constant_page(E)],
                     textures={0: tex})
    size = 60  # the quad covers the middle two thirds: pixels 10 to 50
    linear, _, _ = render(ctx, bake, front_camera(1.5 / math.tan(math.radians(20)), math.radians(40)),
                          size=(size, size))
    centres = np.arange(size) + 0.5
    u = (centres - 10) / 40
    inside = (u > 0.02) & (u < 0.98)
    uu, vv = np.meshgrid(u[inside], u[inside])
    expected = bilinear_repeat(tex, uu, vv) * np.array(E) / np.pi
    np.testing.assert_allclose(linear[np.ix_(inside, inside)], expected, atol=4e-3)
    assert linear[20, 20, 0] > 0.9 * 2 / np.pi and linear[20, 20, 1] < 0.1  # top left red, not flipped


# -- geometry of the camera -----------------------------------------------------------------------
def pinhole(points, eye, target, up, yfov, width, height):
    """Pixel (column, row from the top) of world points: the pinhole model written out."""
    f = np.subtract(target, eye) / np.linalg.norm(np.subtract(target, eye))
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    d = np.asarray(points, np.float64) - eye
    x, y, z = d @ r, d @ u, d @ f
    t = math.tan(yfov / 2)
    return np.stack([(x / z / (t * width / height) + 1) / 2 * width, (1 - y / z / t) / 2 * height], axis=1)


def test_projection_puts_points_where_the_pinhole_model_does(ctx, tmp_path):
    eye, target, up = np.array([1.5, 0.8, 3.0]), np.array([-0.2, 0.1, 0.0]), (0.0, 1.0, 0.0)
    yfov, width, height = math.radians(45), 160, 90
    points = np.array([[0.3, 0.5, 0.2], [-0.9, -0.3, -0.4], [0.0, 0.0, 0.0]])
    to_eye = (eye - points) / np.linalg.norm(eye - points, axis=1, keepdims=True)
    meshes, mats = [], []
    for k, (p, n) in enumerate(zip(points, to_eye)):
        a = np.cross(n, (0, 1, 0))
        a /= np.linalg.norm(a)
        b = np.cross(n, a)  # (a, b, n) right-handed: the quad faces the eye
        meshes.append(quad(p, a * 0.03, b * 0.03))
        mats.append(material(f"m{k}", kd=(0, 0, 0), emission=np.eye(3)[k] * 10))
    bake = make_bake(tmp_path / "b", meshes, mats, [0, 1, 2], [constant_page((0, 0, 0))])
    camera = ViewCamera.look_at(eye, target, up, yfov, znear=0.01, zfar=100)
    linear, _, _ = render(ctx, bake, camera, size=(width, height), supersample=4)
    predicted = pinhole(points, eye, target, up, yfov, width, height)
    rows, cols = np.mgrid[0:height, 0:width] + 0.5
    for k in range(3):
        w = linear[..., k]
        assert w.sum() > 0, f"point {k} not visible"
        centroid = np.array([(w * cols).sum() / w.sum(), (w * rows).sum() / w.sum()])
        np.testing.assert_allclose(centroid, predicted[k], atol=0.15, err_msg=f"point {k}")


@pytest.mark.parametrize("aspect", [16 / 9, 0.5])
def test_framing_camera_sees_the_whole_box(aspect):
    lo, hi = np.array([-3.0, 0.0, -1.0]), np.array([2.0, 2.5, 4.0])
    cam = ViewCamera.framing(lo, hi, aspect, math.radians(50))
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    px = pinhole(corners, cam.eye, cam.eye + cam.forward, cam.up, cam.yfov, 1000 * aspect, 1000)
    assert np.all(px >= 0) and np.all(px[:, 0] <= 1000 * aspect) and np.all(px[:, 1] <= 1000)
    depth = (corners - cam.eye) @ cam.forward
    assert np.all(depth > cam.znear) and np.all(depth < cam.zfar)


def test_camera_matrices_match_pyrr():
    eye, target, up = np.array([1.0, 2.0, 3.0]), np.array([-1.0, 0.5, 0.0]), np.array([0.0, 1.0, 0.0])
    cam = ViewCamera.look_at(eye, target, up, math.radians(55), znear=0.1, zfar=50)
    # pyrr uses row vectors: its matrices are the transposes of ours.
    np.testing.assert_allclose(cam.view_matrix(), pyrr.matrix44.create_look_at(eye, target, up).T, atol=1e-6)
    np.testing.assert_allclose(cam.projection_matrix(1.6),
                               pyrr.matrix44.create_perspective_projection(55, 1.6, 0.1, 50).T, rtol=1e-6)
    m = np.arange(16, dtype=np.float32).reshape(4, 4)
    assert np.frombuffer(gl_bytes(m), np.float32)[1] == m[1, 0]  # column-major for GLSL


def test_degenerate_up_and_camera_from_manifest():
    down = ViewCamera.look_at((0, 5, 0), (0, 0, 0), (0, 1, 0), 1.0)  # forward parallel to up
    basis = np.stack([down.forward, down.up, down.right])
    assert np.all(np.isfinite(basis))
    np.testing.assert_allclose(basis @ basis.T, np.eye(3), atol=1e-9)
    entry = {"name": "c", "eye": [0, 0, 3.9], "forward": [0, 0, -1], "up": [0, 1, 0], "yfov": 0.686,
             "aspect": 1.0, "znear": 0.001, "zfar": 100.0}
    cam = ViewCamera.from_manifest(Camera(**entry))
    assert cam.name == "c" and cam.yfov == 0.686 and cam.znear == 0.001
    np.testing.assert_allclose(cam.view_matrix() @ [0, 0, 0, 1], [0, 0, -3.9, 1], atol=1e-6)
    with pytest.raises(ValueError):
        ViewCamera.look_at((1, 1, 1), (1, 1, 1))


def test_camera_path_catmull_rom():
    keys = [{"time": 0.0, "eye": [0, 0, 0], "target": [0, 0, -1]},
            {"time": 1.0, "eye": [1, 0, 0], "target": [1, 0, -1], "yfov": 1.0},
            {"time": 3.0, "eye": [2, 1, 0], "target": [2, 1, -1]},
            {"time": 4.0, "eye": [0, 0, 0], "target": [0, 0, -1]}]
    path = CameraPath.from_json({"name": "p", "keys": keys})
    for k in keys:  # passes through every key
        np.testing.assert_allclose(camera_path_at(path, k["time"]).eye, k["eye"], atol=1e-12)
    np.testing.assert_allclose(camera_path_at(path, -5).eye, keys[0]["eye"])  # clamped
    np.testing.assert_allclose(camera_path_at(path, 99).eye, keys[-1]["eye"])
    # Between keys 1 and 2 (uneven times), the cubic Hermite form with m_i = (p_{i+1} - p_{i-1}) /
    # (t_{i+1} - t_{i-1}), evaluated by hand at s = 0.5: (p1 + p2) / 2 + h (m1 - m2) / 8.
    p = np.array([k["eye"] for k in keys], float)
    m1, m2 = (p[2] - p[0]) / 3.0, (p[3] - p[1]) / 3.0
    np.testing.assert_allclose(camera_path_at(path, 2.0).eye, (p[1] + p[2]) / 2 + 2.0 * (m1 - m2) / 8, atol=1e-12)
    # Closed path: the velocity is the same leaving the first key and arriving at the last.
    e = lambda t: camera_path_at(path, t).eye  # noqa: E731
    v_start, v_end = (e(1e-6) - e(0)) / 1e-6, (e(4) - e(4 - 1e-6)) / 1e-6
    np.testing.assert_allclose(v_start, v_end, atol=1e-4)
    # yfov linear between keys: key 0 and 2 use the default.
    from glint.viewer.camera import DEFAULT_YFOV

    assert camera_path_at(path, 0.5).yfov == pytest.approx((DEFAULT_YFOV + 1.0) / 2)


def test_frustum_culling_is_conservative():
    cam = front_camera()
    vp = cam.view_projection(1.5)
    assert in_frustum(np.array([[-0.1, -0.1, -0.1], [0.1, 0.1, 0.1]]), vp)
    assert not in_frustum(np.array([[-1, -1, 5], [1, 1, 6]]), vp)  # behind the eye
    assert not in_frustum(np.array([[50, 0, -1], [51, 1, 0]]), vp)  # far to the right
    assert in_frustum(np.array([[-100, -100, -1], [100, 100, 1]]), vp)  # contains the view, no corner inside


def test_objects_outside_the_view_are_skipped_and_counted(ctx, tmp_path):
    meshes = [quad((0, 0, 0), (10, 0, 0), (0, 10, 0)), quad((0, 0, 5), (1, 0, 0), (0, 1, 0))]
    bake = make_bake(tmp_path / "b", meshes, [material()], [0, 0], [constant_page(E)])
    _, _, stats = render(ctx, bake, front_camera(), size=(16, 16))
    assert stats["objects_drawn"] == 1 and stats["triangles"] == 2
    assert stats["skipped"]["objects_outside_view"] == ["object1"]
    assert set(stats["gpu_ms"]) >= {"gbuffer", "shading", "tonemap", "total"}
    assert "resolve" in stats["skipped"]  # supersample 1
    json.dumps(stats)  # JSON-ready


# -- faces, emission, sky -------------------------------------------------------------------------
def test_back_faces_single_sided_black_two_sided_lit_emission_front_only(ctx, tmp_path):
    # Three quads facing away from the camera (-Z), side by side.
    away = lambda x: quad((x, 0, 0), (-0.4, 0, 0), (0, 0.4, 0))  # noqa: E731  cross(u, v) = -Z
    bake = make_bake(tmp_path / "b", [away(-1), away(0), away(1)],
                     [material("one"), material("two", double_sided=True),
                      material("lamp", kd=(0, 0, 0), emission=(5, 5, 5))], [0, 1, 2],
                     [constant_page(E)], sky={"radiance": [0.1, 0.2, 0.3], "map": None})
    distance, yfov, width, height = 3.0, math.radians(50), 90, 30
    linear, _, _ = render(ctx, bake, ViewCamera.look_at((0, 0, distance), (0, 0, 0), (0, 1, 0), yfov),
                          size=(width, height))
    half_width = distance * math.tan(yfov / 2) * width / height  # metres at z = 0

    def cx(x):  # pixel column of the world point (x, 0, 0)
        return int((x / half_width + 1) / 2 * width)

    np.testing.assert_array_equal(linear[15, cx(-1)], 0.0)                     # single-sided back: black
    np.testing.assert_allclose(linear[15, cx(0)], np.array(KD) / np.pi * E, rtol=1e-3)  # two-sided: lit
    np.testing.assert_array_equal(linear[15, cx(1)], 0.0)                      # emitter seen from behind
    np.testing.assert_allclose(linear[2, 2], [0.1, 0.2, 0.3], rtol=1e-6)       # sky behind everything


def test_sky_map_follows_the_bake_convention(ctx, tmp_path):
    from glint.bake.lights import SkyLight
    from glint.core.scene import Sky

    rng = np.random.default_rng(1)
    sky_map = rng.uniform(0.5, 2.0, (6, 12, 3)).astype(np.float32)
    scale = np.array([1.0, 0.5, 2.0])
    bake = make_bake(tmp_path / "b", [quad((0, 0, -50), (0.01, 0, 0), (0, 0.01, 0))], [material()], [0],
                     [constant_page(E)], sky={"radiance": scale.tolist(), "map": "sky.exr"}, sky_map=sky_map)
    reference = SkyLight(Sky(radiance=scale, map=sky_map))
    for target, up in [((1, 0.3, 0), (0, 1, 0)), ((-0.2, -0.5, 1), (0, 1, 0)), ((0, 1, 0.01), (0, 0, -1)),
                       ((-1, 0.01, -0.02), (0, 1, 0))]:  # the last one looks across the u seam at -X
        camera = ViewCamera.look_at((0, 0, 0), target, up, math.radians(70))
        linear, _, _ = render(ctx, bake, camera, size=(24, 16))
        cols, rows = np.meshgrid(np.arange(24) + 0.5, np.arange(16) + 0.5)
        t = math.tan(camera.yfov / 2)
        d = (camera.forward + ((cols / 24 * 2 - 1) * t * 1.5)[..., None] * camera.right
             + ((1 - rows / 16 * 2) * t)[..., None] * camera.up)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        expected = reference.radiance(d.reshape(-1, 3)).reshape(16, 24, 3)
        # GL may filter with 8-bit weights: |error| <= |texel difference| / 256 (here <= 1.5 x 2 / 256).
        np.testing.assert_allclose(linear, expected, rtol=0, atol=0.012, err_msg=f"looking at {target}")


def test_no_nan_or_inf_from_degenerate_input(ctx, tmp_path):
    """Zero-length normals, emission 1e5, non-finite and beyond-half light-map values, a camera in
    the plane of a surface and on a surface: every pixel finite, tone mapping saturates cleanly."""
    page = constant_page((1.0, 2.0, 3.0))
    page[0, 0, :3] = (np.nan, np.inf, -np.inf)
    page[1, 1, :3] = 1e6  # beyond half float: the light maps must go to RGBA32F
    meshes = [quad((0, 0, 0), (1, 0, 0), (0, 1, 0), normal_scale=0.0),   # zero-length normals
              quad((0, 0, -1), (5, 0, 0), (0, 5, 0)),
              quad((0.5, 0.5, 0.5), (0.2, 0, 0), (0, 0.2, 0))]           # emitter
    mats = [material(), material("b", kd=(1, 1, 1)), material("hot", emission=(1e5, 1e5, 1e5))]
    bake = make_bake(tmp_path / "b", meshes, mats, [0, 1, 2], [constant_page(E)],
                     sky={"radiance": [1e5, 0, 1], "map": None})
    _write_raw_exr(tmp_path / "b" / "lightmaps" / "page_0.exr", page)  # image_io refuses NaN: bypass it
    bake = Bake(tmp_path / "b")
    views = [front_camera(),
             ViewCamera.look_at((0, 0, 0), (1, 0, 0), (0, 1, 0), 1.0),        # eye on the surface, along it
             ViewCamera.look_at((0, 0, 0), (0, 0, 1), (0, 1, 0), 1.0),        # eye on the surface, off it
             ViewCamera.look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 1.0),       # eye on the surface, into it
             ViewCamera.look_at((0, 0, 3), (0, 0, 0), (0, 0, 1), 1e-4, znear=1e-6, zfar=1e9)]
    r = Renderer(ctx, bake, supersample=2, exposure=30.0)
    for camera in views:
        r.render(camera, 33, 17)
        linear = r.read_linear()
        assert np.all(np.isfinite(linear)) and linear.min() >= 0, camera
        srgb = r.read_srgb()
        assert srgb.dtype == np.uint8 and srgb.shape == (17, 33, 3)
    assert r.stats["lightmap_format"] == "RGBA32F"
    r.exposure = float("nan")
    r.render(views[0], 8, 8)
    assert np.all(np.isfinite(r.read_linear()))
    r.release()


# -- the compute passes against numpy -------------------------------------------------------------
def _upload(ctx, image):
    h, w = image.shape[:2]
    rgba = np.concatenate([image, np.ones((h, w, 1), np.float32)], -1).astype(np.float32)
    tex = ctx.texture((w, h), 4, rgba.tobytes(), dtype="f4")
    tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return tex


def _read(tex, dtype, channels=4):
    w, h = tex.size
    return np.frombuffer(tex.read(alignment=1), dtype).reshape(h, w, channels)


def aces_srgb_reference(x, ev):
    """Narkowicz's fit (a=2.51, b=0.03, c=2.43, d=0.59, e=0.14), then the sRGB OETF, in float64."""
    x = np.clip(np.asarray(x, np.float64) * 2.0 ** ev, 0, None)
    with np.errstate(over="ignore", invalid="ignore"):
        y = np.clip((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0, 1)
    y = np.where(np.isfinite(y), y, 1.0)
    s = np.where(y <= 0.0031308, 12.92 * y, 1.055 * y ** (1 / 2.4) - 0.055)
    return s * 255


@pytest.mark.parametrize("ev", [0.0, 1.5, -3.0])
def test_tonemap_matches_aces_fit_and_srgb(ctx, ev):
    rng = np.random.default_rng(7)
    values = np.concatenate([[0, 1e-6, 0.0031308 / 0.8, 0.01, 0.18, 0.5, 1, 2, 10, 1e3, 1e5, 1e30],
                             np.exp(rng.uniform(-9, 5, 500))])
    image = np.resize(values, 3 * 64 * 9).reshape(9, 64, 3).astype(np.float32)
    tonemap = TonemapPass(ctx)
    out = _read(tonemap.run(_upload(ctx, image), ev), np.uint8)[..., :3]
    expected = aces_srgb_reference(image, ev)
    assert np.abs(out.astype(np.float64) - expected).max() <= 0.5 + 1e-3  # rounded to nearest
    assert out[0, 0, 0] == 0
    tonemap.release()


@pytest.mark.parametrize("factor, size", [(2, (10, 7)), (3, (5, 4)), (4, (3, 3))])
def test_resolve_is_the_block_mean(ctx, factor, size):
    w, h = size
    image = np.random.default_rng(factor).uniform(0, 100, (h * factor, w * factor, 3)).astype(np.float32)
    resolve = ResolvePass(ctx)
    out = _read(resolve.run(_upload(ctx, image), factor), np.float32)[..., :3]
    expected = image.reshape(h, factor, w, factor, 3).mean(axis=(1, 3), dtype=np.float64)
    np.testing.assert_allclose(out, expected, rtol=1e-6)
    resolve.release()


def test_supersampled_edge_is_the_covered_fraction(ctx, tmp_path):
    """A straight edge through the middle of a pixel column: with N x N supersampling that
    column shows the covered fraction of the light-mapped value (box filter)."""
    bake = make_bake(tmp_path / "b", [quad((-5, 0, 0), (5, 0, 0), (0, 5, 0))], [material()], [0],
                     [constant_page(E)])
    width = 9  # the edge x = 0 runs through the middle of column 4
    linear, _, _ = render(ctx, bake, front_camera(), size=(width, 5), supersample=4)
    full = np.array(KD) / np.pi * E
    np.testing.assert_allclose(linear[:, :4], np.broadcast_to(full, (5, 4, 3)), rtol=1e-3)
    np.testing.assert_allclose(linear[:, 4], np.broadcast_to(full / 2, (5, 3)), rtol=1e-3)
    np.testing.assert_array_equal(linear[:, 5:], 0.0)


# -- shader sources -------------------------------------------------------------------------------
def test_includes_resolve_once_and_errors_name_the_file(ctx, monkeypatch):
    from glint.viewer import shader_source

    files = {"main.comp": '#include "a.glsl"\n#include "b.glsl"\nlayout(local_size_x = 1) in;\n'
                          'void main() { f(); g(); }\n',
             "a.glsl": '#include "b.glsl"\nvoid f() { g(); }\n',
             "b.glsl": "void g() {}\n",
             "bad.comp": '#include "b.glsl"\nlayout(local_size_x = 1) in;\nvoid main() {\n  h();\n}\n',
             "cycle.glsl": '#include "cycle2.glsl"\n', "cycle2.glsl": '#include "cycle.glsl"\n'}
    monkeypatch.setattr(shader_source, "read", lambda name: files[name])
    text, used = shader_source.preprocess("main.comp", {"N": 3, "FLAG": True})
    assert text.startswith("#version 430 core\n#define HALF_MAX 65504.0\n")  # core/constants.py, injected first
    assert "\n#define N 3\n#define FLAG 1\n#line 1 0\n" in text
    assert used == ["main.comp", "a.glsl", "b.glsl"] and text.count("void g()") == 1
    shader_source.compute_program(ctx, "main.comp").release()
    with pytest.raises(shader_source.ShaderError, match=r"bad\.comp:4"):
        shader_source.compute_program(ctx, "bad.comp")
    with pytest.raises(shader_source.ShaderError, match="cycle"):
        shader_source.preprocess("cycle.glsl")
