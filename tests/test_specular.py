"""Specular shading of curved objects (section 4.4) on llvmpipe: hand-made bake directories with
cube maps of known content, checked against numpy.

Expected values come from outside the viewer: the lobe's directional albedo by numpy quadrature
(glint.core.bsdf.lobe_albedo), the mirror direction and the OpenGL cube-map face rules written out
here from the GL specification (section 8.13, table 8.19), a ray-plane intersection in numpy,
and pixel coverage by a pinhole model written out from the camera's basis.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from test_renderer import KD, constant_page, make_bake, material, quad

from glint.core.manifest import Manifest
from glint.core import bsdf
from glint.core.bake_dir import Bake, write_json
from glint.core.image_io import write_image
from glint.viewer.camera import ViewCamera
from glint.viewer.cubemaps import read_cubemap
from glint.viewer.renderer import Renderer
from glint.viewer.tangent_frames import axis_tangents


# -- the OpenGL cube-map convention, from the specification -----------------------------------------
# Table 8.19: per face (major axis), sc and tc of a direction r, and ma = |r_major|;
# s = (sc / ma + 1) / 2, t = (tc / ma + 1) / 2; row 0 of a face image is t = 0.
def gl_face(r: np.ndarray) -> np.ndarray:
    """Face index (0..5 = +X, -X, +Y, -Y, +Z, -Z) of directions r (..., 3)."""
    a = np.abs(r)
    axis = np.argmax(a, axis=-1)  # ties are avoided by the callers
    negative = np.take_along_axis(r, axis[..., None], -1)[..., 0] < 0
    return 2 * axis + negative


def gl_texel_directions(size: int) -> np.ndarray:
    """(6, S, S, 3) unit directions of the texel centres of each face, rows t, columns s."""
    c = (np.arange(size) + 0.5) / size * 2 - 1
    tc, sc = np.meshgrid(c, c, indexing="ij")
    one = np.ones_like(sc)
    faces = [np.stack(f, -1) for f in (
        (one, -tc, -sc), (-one, -tc, sc),     # +X: sc = -rz, tc = -ry;  -X: sc = +rz, tc = -ry
        (sc, one, tc), (sc, -one, -tc),       # +Y: sc = +rx, tc = +rz;  -Y: sc = +rx, tc = -rz
        (sc, -tc, one), (-sc, -tc, -one))]    # +Z: sc = +rx, tc = -ry;  -Z: sc = -rx, tc = -ry
    d = np.stack(faces)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def cube_file(function, size: int) -> np.ndarray:
    """The bake's cube-map file layout (bake/cubemap.py): RGBA, the six faces stacked vertically in
    GL order, each with its row 0 at t = 0; RGB = function(direction), A = 1."""
    d = gl_texel_directions(size)
    rgba = np.ones((6, size, size, 4), np.float32)
    rgba[..., :3] = function(d)
    return rgba.reshape(6 * size, size, 4)


FACE_COLOURS = np.array([[1.0, 0.1, 0.1], [0.1, 1.0, 0.1], [0.1, 0.1, 1.0],
                         [1.0, 1.0, 0.1], [0.1, 1.0, 1.0], [1.0, 0.1, 1.0]])


def face_colours(d):
    return FACE_COLOURS[gl_face(d)]


def direction_colours(d):
    """A smooth, non-symmetric function of direction: every direction its own colour."""
    return 0.5 + 0.4 * d


def constant(value):
    return lambda d: np.full(d.shape, value)


# -- bake directories with cube maps ----------------------------------------------------------------
def specular_bake(path, meshes, materials, object_materials, cubes: dict, page=(0.0, 0.0, 0.0)):
    """make_bake's directory plus, for the objects in `cubes` ({index: (file pixels, centre,
    planes)}), role `curved` and a cube-map entry as bake/pipeline.py writes it."""
    make_bake(path, meshes, materials, object_materials, [constant_page(page)])
    manifest = json.loads((path / "manifest.json").read_text())
    (path / "cubemaps").mkdir()
    for i, (pixels, centre, planes) in cubes.items():
        write_image(path / f"cubemaps/{i}.exr", pixels, channels=("R", "G", "B", "A"))
        manifest["objects"][i]["role"] = "curved"
        manifest["objects"][i]["cubemap"] = {
            "file": f"cubemaps/{i}.exr", "size": int(pixels.shape[1]), "centre": list(map(float, centre)),
            "bounding_planes": [{"point": list(map(float, p)), "normal": list(map(float, n))} for p, n in planes]}
    write_json(path / "manifest.json", manifest)
    return Bake(path)


def lobe(kind="reflect", m=(0.1, 0.1), r0=0.04, alpha=0.0, ks=(1.0, 1.0, 1.0)):
    return {"kind": kind, "ks": list(ks), "mx": m[0], "my": m[1], "r0": r0, "alpha": alpha}


def pinhole_rays(eye, target, up, yfov, width, height):
    """(H, W, 3) unit view rays through the pixel centres, row 0 at the top: the pinhole model
    written out (forward f, right r = f x up, true up u = r x f)."""
    f = np.subtract(target, eye) / np.linalg.norm(np.subtract(target, eye))
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    t = math.tan(yfov / 2)
    x = ((np.arange(width) + 0.5) / width * 2 - 1) * t * width / height
    y = (1 - (np.arange(height) + 0.5) / height * 2) * t
    d = f + x[None, :, None] * r + y[:, None, None] * u
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def orbit(theta, phi=0.0, distance=3.0):
    """Eye at polar angle theta from +Z (the quads' normal), azimuth phi from +X."""
    return distance * np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)])


def view(eye, target=(0, 0, 0), up=(0, 0, 1), yfov=math.radians(10)):
    return ViewCamera.look_at(eye, target, up, yfov, znear=0.01, zfar=100), (eye, target, up, yfov)


FLOOR = quad((0, 0, 0), (20, 0, 0), (0, 20, 0))  # z = 0, normal +z, texture u along +x


def converge(renderer, camera, size, frames):
    for _ in range(frames):
        renderer.render(camera, *size, mode="converge")
    return renderer.read_linear()


# -- white furnace --------------------------------------------------------------------------------
FURNACE = [  # lobe, view polar angle, azimuth
    (lobe(m=(0.1, 0.1), r0=0.04), 0.3, 0.0),                            # glossy insulator
    (lobe(m=(0.3, 0.3), r0=0.5, alpha=0.5), 1.2, 0.0),                  # rough, Kurt's alpha, 69 deg
    (lobe(m=(0.05, 0.5), r0=0.9, alpha=0.2), 1.0, 0.0),                 # brushed metal, 1:10
    (lobe(m=(0.05, 0.5), r0=0.9, alpha=0.2), 1.0, math.pi / 2),         # ... seen along the other axis
    (lobe(m=(0.01, 1.0), r0=0.9), 0.6, 0.7),                            # anisotropy 1:100
    (lobe(m=(1.0, 1.0), r0=0.2), 1.4, 0.0),                             # roughest, grazing (80 deg)
    (lobe(m=(0.002, 0.002), r0=1.0, alpha=0.5), 0.5, 0.0),              # near mirror
    (lobe("transmit", m=(0.2, 0.2), r0=0.04), 0.7, 0.0),                # frosted glass
]


def furnace_bake(path, spec, uvs=True):
    mesh = dict(FLOOR)
    if not uvs:
        del mesh["uvs"]  # no texture coordinates: the tangent is world X projected (axis_tangents)
    return specular_bake(path, [mesh], [material(kd=(0, 0, 0), double_sided=True, lobes=[spec])], [0],
                         {0: (cube_file(constant(1.0), 8), (0, 0, 0), [])})


def furnace_albedo(spec, geometry, size):
    """Per pixel: the lobe's directional albedo for that pixel's view direction. The quad lies in
    z = 0 with its tangent along +x (texture u), so local = world coordinates."""
    wo = -pinhole_rays(*geometry, *size)
    return bsdf.lobe_albedo(wo, spec["mx"], spec["my"], spec["r0"], spec["alpha"], spec["kind"], n=4096)


@pytest.mark.parametrize("spec, theta, phi", FURNACE)
def test_white_furnace_converges_to_the_lobe_albedo(ctx, tmp_path, spec, theta, phi):
    """Constant incident radiance 1: the still camera's mean is the directional albedo."""
    size = (8, 8)
    camera, geometry = view(orbit(theta, phi))
    expected = furnace_albedo(spec, geometry, size)
    with Renderer(ctx, furnace_bake(tmp_path / "b", spec), samples_per_frame=16) as r:
        linear = converge(r, camera, size, 64)  # 1024 quasi-random samples per pixel
        assert r.stats["specular"]["progressive"]["samples_per_pixel"] == 1024
    assert expected.min() > 0.01
    np.testing.assert_allclose(linear[..., 0], expected, rtol=0.01)
    np.testing.assert_array_equal(linear[..., 0], linear[..., 2])  # ks = 1 1 1 and a grey cube map


def test_tangent_frame_without_texture_coordinates(ctx, tmp_path):
    """No uvs: the tangent is world X projected onto the surface -- for this floor the same frame
    as its texture's +u, so an anisotropic lobe must converge to the same albedo."""
    spec, size = lobe(m=(0.05, 0.5), r0=0.9), (8, 8)
    camera, geometry = view(orbit(1.0, 0.0))
    with Renderer(ctx, furnace_bake(tmp_path / "b", spec, uvs=False), samples_per_frame=16) as r:
        linear = converge(r, camera, size, 64)
    np.testing.assert_allclose(linear[..., 0], furnace_albedo(spec, geometry, size), rtol=0.01)


def test_axis_tangents_are_world_x_projected():
    n = np.array([[0, 0, 1], [0, 1, 0], [1, 0, 0], [0.6, 0.8, 0], [0, 0, 0]], float)
    t = axis_tangents(n)
    expected = np.array([[1, 0, 0, 1], [1, 0, 0, 1], [0, 0, 1, 1], [0.64, -0.48, 0, 1], [0, 0, 0, 0]])
    expected[3, :3] /= np.linalg.norm(expected[3, :3])
    np.testing.assert_allclose(t, expected, atol=1e-6)


@pytest.mark.parametrize("spec, theta", [(lobe(m=(0.1, 0.1), r0=0.04), 0.3), (lobe(m=(0.2, 0.2), r0=0.9), 0.6),
                                         (lobe("transmit", m=(0.15, 0.15), r0=0.04), 0.5)])
def test_walkthrough_estimate_is_close_to_the_albedo(ctx, tmp_path, spec, theta):
    """The regular pattern with Eq. 4.25 weights: within a few per cent in a white furnace."""
    size = (8, 8)
    camera, geometry = view(orbit(theta))
    with Renderer(ctx, furnace_bake(tmp_path / "b", spec)) as r:
        r.render(camera, *size)
        linear = r.read_linear()
        stats = r.stats["specular"]
    assert stats["mode"] == "walkthrough" and stats["pixels_with_lobes"] == 64
    assert stats["cube_map_lookups"] <= 64 * stats["samples_per_lobe"][0]["samples"]
    np.testing.assert_allclose(linear[..., 0], furnace_albedo(spec, geometry, size), rtol=0.05)


def test_walkthrough_samples_are_mip_filtered(ctx, tmp_path):
    """Eq. 4.14-4.17 through the whole chain: a rough lobe's samples cover hundreds of texels, so
    over a texel checkerboard (0 and 1) each filtered look-up is its 2 x 2 box mean, 1/2, and the
    image is half the white furnace's -- unfiltered look-ups would hit 0 or 1 texels instead."""
    spec, size = lobe(m=(0.3, 0.3), r0=0.5), (8, 8)
    camera, _ = view(orbit(0.4))
    t, u = np.meshgrid(np.arange(64), np.arange(64), indexing="ij")
    checker = np.ones((6, 64, 64, 4), np.float32)
    checker[..., :3] = ((t + u) % 2)[None, :, :, None]
    bakes = {"checker": checker.reshape(6 * 64, 64, 4), "white": cube_file(constant(1.0), 64)}
    images = {}
    for name, pixels in bakes.items():
        bake = specular_bake(tmp_path / name, [FLOOR], [material(kd=(0, 0, 0), lobes=[spec])], [0],
                             {0: (pixels, (0, 0, 0), [])})
        with Renderer(ctx, bake) as r:
            r.render(camera, *size)
            images[name] = r.read_linear()
    np.testing.assert_allclose(images["checker"], 0.5 * images["white"], rtol=1e-3)


# -- a mirror-like lobe shows the cube map ---------------------------------------------------------
MIRROR = lobe(m=(1e-3, 1e-3), r0=1.0, alpha=0.5)  # alpha = 0.5: as m -> 0 the albedo tends to F = 1


def mirror_scene(tmp_path, function, size=32, planes=(), centre=(0, 0, 0)):
    return specular_bake(tmp_path / "b", [FLOOR], [material(kd=(0, 0, 0), lobes=[MIRROR])], [0],
                         {0: (cube_file(function, size), centre, list(planes))})


def mirror_directions(geometry, size):
    """Per pixel: whether it sees the floor z = 0 (clearly), and the mirror direction there."""
    eye = np.asarray(geometry[0], float)
    ray = pinhole_rays(*geometry, *size)
    with np.errstate(divide="ignore"):
        point = eye + ray * (-eye[2] / ray[..., 2])[..., None]
    floor = (ray[..., 2] < -0.02) & np.all(np.abs(point[..., :2]) < 19, axis=-1)
    reflected = ray * np.array([1, 1, -1])  # 2 (n.v) n - v with n = +z, v = -ray
    return floor, reflected


@pytest.mark.parametrize("mode", ["walkthrough", "converge"])
def test_mirror_lobe_reflects_each_face_in_its_colour(ctx, tmp_path, mode):
    size = (48, 32)
    camera, geometry = view((0.3, -2.0, 1.2), (0.1, 0.5, 0.0), yfov=math.radians(100))
    floor, r = mirror_directions(geometry, size)
    a = np.sort(np.abs(r), axis=-1)
    clear = floor & (a[..., 1] < 0.9 * a[..., 2])  # away from the cube's edges, where faces blend
    with Renderer(ctx, mirror_scene(tmp_path, face_colours, 16)) as renderer:
        renderer.render(camera, *size)
        if mode == "converge":
            converge(renderer, camera, size, 4)
        linear = renderer.read_linear()
    faces = gl_face(r)
    assert clear.sum() > 300 and len(np.unique(faces[clear])) >= 3
    np.testing.assert_allclose(linear[clear], FACE_COLOURS[faces[clear]], rtol=0.01)


def test_mirror_lobe_keeps_the_orientation_within_faces(ctx, tmp_path):
    """Every direction its own colour: a flipped or rotated face would show wrong colours."""
    size = (48, 32)
    camera, geometry = view((0.3, -2.0, 1.2), (0.1, 0.5, 0.0), yfov=math.radians(100))
    floor, r = mirror_directions(geometry, size)
    with Renderer(ctx, mirror_scene(tmp_path, direction_colours, 64)) as renderer:
        renderer.render(camera, *size)
        linear = renderer.read_linear()
    assert floor.sum() > 600
    np.testing.assert_allclose(linear[floor], direction_colours(r[floor]), atol=0.01)


def test_cube_map_file_layout_round_trip(tmp_path):
    pixels = cube_file(direction_colours, 4)
    write_image(tmp_path / "c.exr", pixels, channels=("R", "G", "B", "A"))
    faces = read_cubemap(tmp_path / "c.exr")
    assert faces.shape == (6, 4, 4, 4)
    np.testing.assert_allclose(faces[2, 0, 0, :3], direction_colours(gl_texel_directions(4)[2, 0, 0]), atol=1e-3)


def test_cube_map_lookups_filter_across_face_edges(tmp_path):
    """GL_TEXTURE_CUBE_MAP_SEAMLESS: exactly on the edge between +X and +Y the bilinear filter
    takes half its texels from each face; without it, one face's colour alone would show."""
    from types import SimpleNamespace

    from glint.bench import glsl_eval
    from glint.viewer.cubemaps import CubeMaps

    (tmp_path / "cubemaps").mkdir()
    write_image(tmp_path / "cubemaps/0.exr", cube_file(face_colours, 4), channels=("R", "G", "B", "A"))
    manifest = {"objects": [{"name": "o", "bounds": [[0, 0, 0], [1, 1, 1]],
                             "cubemap": {"file": "cubemaps/0.exr", "size": 4, "centre": [0, 0, 0]}}]}
    cubes = CubeMaps(glsl_eval.context(), SimpleNamespace(path=tmp_path, model=Manifest.from_json(manifest)))
    try:
        cubes.bind_buffers()
        assert cubes.bind(None, 8) == 1
        d = np.array([[1.0, 1.0, z] for z in (-0.5, 0.0, 0.3)]) / np.sqrt([[2.25], [2.0], [2.09]])
        out = glsl_eval.evaluate("cubemaps.glsl", "L = cube_radiance(cube_objects[0], d, 0.0);", {"d": d},
                                 {"L": 3}, defines=cubes.defines(8))
    finally:
        cubes.release()
    np.testing.assert_allclose(out["L"], np.tile((FACE_COLOURS[0] + FACE_COLOURS[2]) / 2, (3, 1)), atol=2e-3)


def test_more_cube_maps_than_an_array_has_layers_get_more_classes(tmp_path, monkeypatch):
    """An array holds GL_MAX_ARRAY_TEXTURE_LAYERS / 6 cube maps (341 on llvmpipe; an external
    interior has 548 of one size): with the limit lowered to 2 maps per array, 5 maps of one size
    make 3 classes and every object still finds its own map. Catches the upload of one array past
    the limit (GL_INVALID_VALUE, which went unnoticed before uploads were checked) and a wrong
    class or layer in the per-object table (the colours would swap)."""
    from types import SimpleNamespace

    from glint.bench import glsl_eval
    from glint.viewer.cubemaps import CubeMaps

    ctx = glsl_eval.context()
    monkeypatch.setitem(ctx.info, "GL_MAX_ARRAY_TEXTURE_LAYERS", 12)
    (tmp_path / "cubemaps").mkdir()
    colours = np.array([[0.1, 0.2, 0.3], [1.0, 0.5, 0.0], [0.0, 0.7, 0.2], [0.9, 0.9, 0.1], [0.4, 0.0, 0.6]])
    objects = []
    for i, c in enumerate(colours):
        write_image(tmp_path / f"cubemaps/{i}.exr", cube_file(lambda d, c=c: np.broadcast_to(c, d.shape), 4),
                    channels=("R", "G", "B", "A"))
        objects.append({"name": f"o{i}", "bounds": [[0, 0, 0], [1, 1, 1]],
                        "cubemap": {"file": f"cubemaps/{i}.exr", "size": 4, "centre": [0, 0, 0]}})
    cubes = CubeMaps(ctx, SimpleNamespace(path=tmp_path, model=Manifest.from_json({"objects": objects})))
    try:
        assert [len(c.probes) for c in cubes.classes] == [2, 2, 1]
        cubes.bind_buffers()
        assert cubes.bind(None, 8) == 5
        d = np.tile([[0.3, 0.5, 0.81]], (5, 1))
        k = np.arange(5, dtype=np.float64)[:, None]
        out = glsl_eval.evaluate("cubemaps.glsl", "L = cube_radiance(cube_objects[int(k.x)], d, 0.0);",
                                 {"d": d, "k": np.repeat(k, 3, axis=1)}, {"L": 3}, defines=cubes.defines(8))
    finally:
        cubes.release()
    np.testing.assert_allclose(out["L"], colours, atol=2e-3)


# -- bounding planes (section 4.4.1) ---------------------------------------------------------------
def plane_lookup(p, d, centre, planes):
    """The look-up direction of the ray p + t d: towards the nearest plane hit from the centre,
    or d itself without a hit."""
    best = np.full(len(p), np.inf)
    for q, n in planes:
        along = d @ np.asarray(n, float)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((np.asarray(q, float) - p) @ np.asarray(n, float)) / along
        ok = (np.abs(along) > 1e-8) & (t > 0)
        best = np.where(ok & (t < best), t, best)
    hit = p + np.where(np.isfinite(best), best, 0.0)[:, None] * d
    look = hit - np.asarray(centre, float)
    look /= np.linalg.norm(look, axis=1, keepdims=True)
    return np.where(np.isfinite(best)[:, None], look, d)


def test_bounding_plane_lookup_matches_numpy():
    """shaders/cubemaps.glsl bounding_plane_direction over random rays, floor and ceiling planes."""
    from glint.bench import glsl_eval
    from glint.viewer.cubemaps import CUBE_OBJECT_DTYPE, PLANE_DTYPE
    from glint.viewer.gl_bindings import BOUNDING_PLANE_BINDING, CUBE_OBJECT_BINDING

    rng = np.random.default_rng(4)
    centre = np.array([0.3, 1.0, -0.2])
    planes = [((0, 0, 0), (0, 1, 0)), ((0, 2.5, 0), (0, -1, 0)), ((-2, 0, 0), (1, 0, 0))]
    n = 4000
    p = centre + rng.uniform(-0.4, 0.4, (n, 3))
    d = rng.normal(size=(n, 3))
    d[:200, 1] = 0.0  # parallel to floor and ceiling
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ctx = glsl_eval.context()
    objects = np.zeros(1, CUBE_OBJECT_DTYPE)
    objects[0]["centre"][:3] = centre
    objects[0]["info"] = (0, 0, 0, len(planes))
    rows = np.zeros(len(planes), PLANE_DTYPE)
    for k, (q, m) in enumerate(planes):
        rows[k]["point"][:3], rows[k]["normal"][:3] = q, m
    buffers = [ctx.buffer(objects.tobytes()), ctx.buffer(rows.tobytes())]
    buffers[0].bind_to_storage_buffer(CUBE_OBJECT_BINDING)
    buffers[1].bind_to_storage_buffer(BOUNDING_PLANE_BINDING)
    try:
        out = glsl_eval.evaluate("cubemaps.glsl", "look = bounding_plane_direction(cube_objects[0], p, d);",
                                 {"p": p, "d": d}, {"look": 3},
                                 defines={"CUBE_CLASSES": 1, "CUBE_FIRST_UNIT": 8, "CUBE_OBJECTS": 1})
    finally:
        for b in buffers:
            b.release()
    expected = plane_lookup(p, d, centre, planes)
    np.testing.assert_allclose(out["look"], expected, atol=2e-5)
    plain = np.all(expected == d, axis=1)
    assert 0 < plain.sum() < 200  # rays parallel to floor and ceiling that miss the wall keep their direction


def test_mirror_reflects_the_floor_through_its_bounding_plane(ctx, tmp_path):
    """A vertical mirror 1 m above a floor plane: rays going down look the cube map up towards
    their floor hit from the centre, not along their own direction."""
    size = (40, 40)
    centre = np.array([0.0, 0.0, 1.0])
    floor = ((0.0, 0.0, -1.0), (0.0, 0.0, 1.0))  # the plane z = -1, below the mirror's centre
    mirror = quad((0, 0, 1), (1, 0, 0), (0, 0, 1))  # in the plane y = 0, normal (1,0,0) x (0,0,1) = -y
    bake = specular_bake(tmp_path / "b", [mirror], [material(kd=(0, 0, 0), double_sided=True, lobes=[MIRROR])],
                         [0], {0: (cube_file(direction_colours, 64), centre, [floor])})
    eye = np.array([0.2, -3.0, 1.6])
    camera, geometry = view(eye, (0.0, 0.0, 0.8), (0, 0, 1), math.radians(30))
    with Renderer(ctx, bake) as r:
        r.render(camera, *size)
        linear = r.read_linear()
    ray = pinhole_rays(*geometry, *size)
    point = eye + ray * (-eye[1] / ray[..., 1])[..., None]  # on the plane y = 0
    on_mirror = (np.abs(point[..., 0]) < 0.95) & (np.abs(point[..., 2] - 1) < 0.95)
    reflected = ray * np.array([1, -1, 1])
    look = plane_lookup(point[on_mirror], reflected[on_mirror], centre, [floor])
    down = reflected[on_mirror][:, 2] < -0.05
    assert down.sum() > 100 and (~down).sum() > 100
    np.testing.assert_allclose(linear[on_mirror], direction_colours(look), atol=0.01)
    # without the plane, the downward rays would show other colours
    assert np.abs(direction_colours(reflected[on_mirror][down]) - direction_colours(look[down])).max() > 0.05


# -- stability --------------------------------------------------------------------------------------
EXTREMES = [lobe(m=(1e-4, 1e-4), r0=1.0, alpha=1.0), lobe(m=(1e-4, 1e-2), r0=0.0, alpha=0.0),
            lobe(m=(0.01, 1.0), r0=0.5, alpha=0.5), lobe(m=(1.0, 0.01), r0=1.0, alpha=1.0),
            lobe(m=(1.0, 1.0), r0=0.04, alpha=0.0), lobe(m=(1.0, 1.0), r0=1.0, alpha=1.0),
            lobe("transmit", m=(1e-4, 1e-4), r0=0.0, alpha=1.0), lobe("transmit", m=(1.0, 0.01), r0=0.5),
            lobe(m=(0.05, 0.05), r0=0.0, alpha=0.0), lobe(m=(0.3, 0.003), r0=1.0, alpha=0.25)]


def test_extreme_parameters_give_finite_bounded_frames(ctx, tmp_path):
    """Roughness 1e-4..1, anisotropy 1:100, alpha 0..1, r0 0..1, both kinds, on strips of a floor
    seen from just above it (views down to exactly grazing), with a cube map holding a 1e4 sun:
    no NaN or Inf anywhere. With a uniform cube map of radiance 1, the alpha = 0 lobes (energy
    conserving, thesis 3.3) reflect at most 1, up to the estimates' error."""
    k_all = range(len(EXTREMES))
    strips = [quad((-4.5 + k, 0, 0), (0.5, 0, 0), (0, 50, 0)) for k in k_all]
    mats = [material(f"m{k}", kd=(0, 0, 0), double_sided=True, lobes=[spec]) for k, spec in enumerate(EXTREMES)]

    def sun(d):
        return np.where((d[..., 2:3] > 0.9) | (d[..., 1:2] > 0.95), 1e4, 1.0) * np.ones(3)

    floor_plane = [((0, 0, -1), (0, 0, 1))]
    bright = specular_bake(tmp_path / "b", strips, mats, list(k_all),
                           {k: (cube_file(sun, 16), (-4.5 + k, 0, 0), floor_plane) for k in k_all})
    size = (64, 48)
    low = ((0, -3, 1e-3), (0, 10, 1e-3), (0, 0, 1), math.radians(60))
    views = [low, ((0, -3, 0.0), (0, 10, 0.0), (0, 0, 1), math.radians(60)),  # eye in the floor's plane
             ((0, -1, 4), (0, 3, 0), (0, 0, 1), math.radians(80))]
    with Renderer(ctx, bright, samples_per_frame=4) as r:
        for eye, target, up, yfov in views:
            camera = ViewCamera.look_at(eye, target, up, yfov, znear=1e-4, zfar=100)
            r.render(camera, *size)
            walk = r.read_linear()
            still = converge(r, camera, size, 3)
            for linear in (walk, still):
                assert np.all(np.isfinite(linear)) and linear.min() >= 0
    uniform = specular_bake(tmp_path / "c", strips, mats, list(k_all),
                            {k: (cube_file(constant(1.0), 8), (-4.5 + k, 0, 0), []) for k in k_all})
    with Renderer(ctx, uniform, samples_per_frame=16) as r:
        camera = ViewCamera.look_at(*low, znear=1e-4, zfar=100)
        r.render(camera, *size)
        walk = r.read_linear()[..., 0]
        still = converge(r, camera, size, 16)[..., 0]
    ray = pinhole_rays(*low, *size)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = low[0][0] + ray[..., 0] * (-low[0][2] / ray[..., 2])
    strip = np.where(ray[..., 2] < 0, np.floor(x + 5.0), -1)
    conserving = np.isin(strip, [k for k, spec in enumerate(EXTREMES) if spec["alpha"] == 0.0])
    assert conserving.sum() > 200
    assert still[conserving].max() <= 1.02
    assert walk[conserving].max() <= 1.02


# -- what is (not) done -----------------------------------------------------------------------------
def test_diffuse_only_scene_does_no_specular_work(ctx, tmp_path):
    bake = make_bake(tmp_path / "b", [quad((0, 0, 0), (10, 0, 0), (0, 10, 0))], [material()], [0],
                     [constant_page((1, 1, 1))])
    with Renderer(ctx, bake) as r:
        r.render(ViewCamera.look_at((0, 0, 2), (0, 0, 0)), 40, 20)
        stats = r.stats
        r.render(ViewCamera.look_at((0, 0, 2), (0, 0, 0)), 40, 20, mode="converge")
        still = r.stats
    for s in (stats, still):
        spec = s["specular"]
        assert spec["pixels_with_lobes"] == 0 and spec["tiles_with_lobes"] == 0
        assert spec["tiles_skipped"] == 5 * 3  # every 8 x 8 tile of 40 x 20
        assert spec["cube_map_lookups"] == 0 and spec["cube_maps_bound"] == 0 and spec["materials_with_lobes"] == 0
        assert "specular" in s["skipped"]


def test_specular_work_only_where_the_curved_object_shows(ctx, tmp_path):
    """Left half of the view: a specular quad with a cube map; right half: a diffuse one. Pixels
    and tiles with lobes are those whose centre sees the specular quad (pinhole model)."""
    spec = lobe(m=(0.2, 0.2))
    meshes = [quad((-1, 0, 0), (1, 0, 0), (0, 3, 0)), quad((1, 0, 0), (1, 0, 0), (0, 3, 0))]
    bake = specular_bake(tmp_path / "b", meshes, [material("shiny", lobes=[spec]), material("matt")], [0, 1],
                         {0: (cube_file(constant(0.5), 8), (-1, 0, 0), [])})
    size = (44, 30)  # tiles: 6 x 4, the last column and row partly outside
    eye, target, up, yfov = (-0.37, 0.2, 2.0), (-0.37, 0.2, 0.0), (0, 1, 0), math.radians(60)
    camera = ViewCamera.look_at(eye, target, up, yfov, znear=0.01, zfar=100)
    ray = pinhole_rays(eye, target, up, yfov, *size)
    x = eye[0] + ray[..., 0] * (-eye[2] / ray[..., 2])
    shiny = (x < 0.0) & (x > -2.0)  # left of x = -2 only sky shows
    assert np.all(np.abs(x) > 1e-3) and np.all(np.abs(x + 2) > 1e-3)  # no pixel centre on an edge
    with Renderer(ctx, bake) as r:
        r.render(camera, *size)
        s = r.stats["specular"]
    rows_gl = shiny[::-1]  # tiles count from the bottom row (GL)
    tiles = {(row // 8, col // 8) for row, col in zip(*np.nonzero(rows_gl))}
    assert s["pixels_with_lobes"] == shiny.sum()
    assert s["tiles_with_lobes"] == len(tiles) and s["tiles_skipped"] == 6 * 4 - len(tiles)
    n = s["samples_per_lobe"][0]["samples"]
    assert s["cube_map_lookups"] == n * shiny.sum()  # a 0.2 lobe seen head-on drops no sample
    assert s["cube_maps_bound"] == 1 and s["cube_map_classes"][0]["size"] == 8


def test_lobes_without_cube_map_are_reported_and_skipped(ctx, tmp_path):
    spec = lobe(m=(0.2, 0.2))
    bake = make_bake(tmp_path / "b", [quad((0, 0, 0), (10, 0, 0), (0, 10, 0))], [material(lobes=[spec])], [0],
                     [constant_page((1, 1, 1))])
    with Renderer(ctx, bake) as r:
        r.render(ViewCamera.look_at((0, 0, 2), (0, 0, 0)), 16, 16)
        linear, stats = r.read_linear(), r.stats
    np.testing.assert_allclose(linear, np.broadcast_to(np.array(KD) / np.pi, linear.shape), rtol=1e-3)  # kd/pi E
    assert stats["specular"]["pixels_with_lobes"] == 0
    assert "object0" in stats["skipped"]["lobes_without_cube_map"]
