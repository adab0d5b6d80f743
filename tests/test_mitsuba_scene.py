"""bench/mitsuba_scene.py (a glint Scene as a Mitsuba 3 scene) and `glint bench --mitsuba`.

All Mitsuba renders here use scalar_rgb (CI has no LLVM that drjit can use). References are
independent of the converter: Mitsuba's own mitsuba.cornell_box(), a uniform sky's analytic
radiance (a lone diffuse surface under a constant sky of radiance 1 shows L = kd), and
core/bsdf.py's numpy directional albedo for a glossy plane under that sky (furnace-like).
"""
from __future__ import annotations

import json
import math

import mitsuba as mi  # noqa: E402  (the test extra installs it)
import numpy as np
import pytest

from glint.core.scene import Camera, Lobe, Material, Object, Scene, Sky


@pytest.fixture(scope="module")
def scalar():
    mi.set_variant("scalar_rgb")
    from glint.bench import mitsuba_scene

    return mitsuba_scene


def block_means(image, k):
    h, w = image.shape[:2]
    return image[: h // k * k, : w // k * k].reshape(h // k, k, w // k, k, -1).mean(axis=(1, 3))


def rel_mae(a, b):
    return float(np.abs(a - b).sum() / np.abs(b).sum())


def test_cornell_box_converts_to_mitsubas_own(scalar):
    """scenes/cornell-box.glb through the bake's loader and the converter renders what Mitsuba's
    mitsuba.cornell_box() renders, within the noise of Mitsuba itself at the same sample count."""
    from glint.services import open_scene

    size, spp = 16, 32
    scene, _ = open_scene("cornell-box")
    camera = scene.cameras[0]
    converted, warnings = scalar.convert(scene, [scalar.sensor_dict(camera, size, size, spp)])
    assert not warnings
    ours = scalar.render(mi.load_dict(converted), spp=spp, seed=1)

    def native(spp, seed):
        d = mi.cornell_box()
        d["integrator"] = {"type": "path", "max_depth": -1}
        d["sensor"]["film"].update(width=size, height=size, rfilter={"type": "box"})
        return np.array(mi.render(mi.load_dict(d), spp=spp, seed=seed))[..., :3]

    truth = native(2048, 7)
    noise = rel_mae(block_means(native(spp, 2), 4), block_means(truth, 4))
    error = rel_mae(block_means(ours, 4), block_means(truth, 4))
    print(f"block rel MAE: converter {error:.4f}, Mitsuba's own at {spp} spp {noise:.4f}")
    assert error < 2 * noise + 0.005
    assert np.allclose(ours.mean(axis=(0, 1)), truth.mean(axis=(0, 1)), rtol=0.03)
    assert rel_mae(block_means(np.roll(ours, 4, axis=1), 4), block_means(truth, 4)) > error + 0.05


def plane(material: int = 0, half: float = 1.0) -> Object:
    """A square at z = 0 facing +z (counter-clockwise), texture u along +x and v along -y (glTF:
    v = 0 is the top row of the image, here the +y edge)."""
    p = np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]], float)
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    return Object("plane", p, np.tile(np.float32([0, 0, 1]), (4, 1)), np.array([[0, 1, 2], [0, 2, 3]]), material, uv)


def camera(eye, target, yfov_deg) -> Camera:
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    f = (target - eye) / np.linalg.norm(target - eye)
    up = np.array([0.0, 1.0, 0.0]) if abs(f[1]) < 0.9 else np.array([0.0, 0.0, 1.0])
    up = up - f * (up @ f)
    return Camera("test", eye, f, up / np.linalg.norm(up), math.radians(yfov_deg))


def test_texture_rows_and_sky(scalar):
    """A base-colour texture whose top half is red and bottom half green on a plane under a
    constant sky of radiance 1: the image shows kd x texture (L = kd for a lone diffuse
    surface), red at the top, as glTF's uv convention puts it."""
    texture = np.zeros((8, 1, 3), np.float32)
    texture[:4, :, 0] = 1.0
    texture[4:, :, 1] = 1.0
    material = Material("tex", kd=np.float32([0.8, 0.8, 0.8]), kd_texture=texture)
    cam = camera((0, 0, 3), (0, 0, 0), 2 * math.degrees(math.atan(1 / 3)))
    scene = Scene("t", None, objects=[plane()], materials=[material], sky=Sky(np.float32([1, 1, 1])), cameras=[cam])
    d, _ = scalar.convert(scene, [scalar.sensor_dict(cam, 8, 8, 16)])
    image = scalar.render(mi.load_dict(d), spp=16)
    # Image rows 1-2 see texture rows 0-3 only, rows 5-6 rows 4-7 (the edges blend across the
    # repeat wrap, as the viewer's sampler does).
    assert np.allclose(image[1:3].mean(axis=(0, 1)), [0.8, 0, 0], atol=0.04), image[1:3].mean(axis=(0, 1))
    assert np.allclose(image[5:7].mean(axis=(0, 1)), [0, 0.8, 0], atol=0.04), image[5:7].mean(axis=(0, 1))


def test_glossy_plane_under_a_constant_sky_is_its_albedo(scalar):
    """A plane with kd, an anisotropic reflection lobe (mx 0.05 along the texture's u = world x,
    my 0.6) and a transmission lobe under a sky of radiance 1 on both sides: each pixel shows the
    directional albedo kd + ks a_r(wo) + kt a_t(wo), computed by glint.core.bsdf.lobe_albedo (numpy).
    Seen along world y at ~70 degrees, the reflection lobe's albedo is 0.44; along x it would be
    0.27, so a wrong tangent frame fails."""
    from glint.core import bsdf as ref

    kd = np.float32([0.1, 0.1, 0.1])
    lobes = [Lobe("reflect", (1.0, 1.0, 1.0), 0.05, 0.6, 1.0, 0.0), Lobe("transmit", (0.3, 0.3, 0.3), 0.3, 0.3, 0.04, 0.0)]
    scene = Scene("g", None, objects=[plane(half=50.0)], materials=[Material("glossy", kd=kd, lobes=lobes)],
                  sky=Sky(np.float32([1, 1, 1])))
    eye = np.array([0.0, -5 * math.sin(math.radians(70)), 5 * math.cos(math.radians(70))])
    cam = camera(eye, (0, 0, 0), 8.0)
    w = h = 10
    spp = 64
    d, _ = scalar.convert(scene, [scalar.sensor_dict(cam, w, h, spp)])
    image = scalar.render(mi.load_dict(d), spp=spp)
    # Pixel-centre rays of the same pinhole (viewer/camera.py conventions) hit z = 0 at x; wo = eye - x.
    t = math.tan(cam.yfov / 2)
    right = np.cross(cam.forward, cam.up)
    ys, xs = np.meshgrid((1 - 2 * (np.arange(h) + 0.5) / h) * t, (2 * (np.arange(w) + 0.5) / w - 1) * t * w / h,
                         indexing="ij")
    rays = cam.forward + xs[..., None] * right + ys[..., None] * cam.up
    hit = eye + rays * (-eye[2] / rays[..., 2])[..., None]
    wo = eye - hit
    wo = (wo / np.linalg.norm(wo, axis=-1, keepdims=True)).reshape(-1, 3)  # world = the lobe frame here
    expected = (kd[0] + sum(lobe.ks[0] * ref.lobe_albedo(wo, lobe.mx, lobe.my, lobe.r0, lobe.alpha, lobe.kind)
                            for lobe in lobes)).reshape(h, w)
    wrong_frame = kd[0] + ref.lobe_albedo(wo[:, [1, 0, 2]], 0.05, 0.6, 1.0, 0.0, "reflect").mean() + 0.3 * 0.314
    got = image.mean(axis=2)
    print(f"mean radiance {got.mean():.4f}, albedo {expected.mean():.4f} (wrong tangent: {wrong_frame:.4f})")
    assert abs(got.mean() - expected.mean()) < 0.02 * expected.mean()
    assert abs(wrong_frame - expected.mean()) > 0.1 * expected.mean()
    assert np.allclose(block_means(got[..., None], 5)[..., 0], block_means(expected[..., None], 5)[..., 0], rtol=0.05)


def test_sky_map_orientation(scalar):
    """An equirectangular sky seen directly: Mitsuba's envmap, as the converter orients it, shows
    the radiance bake/lights.py's SkyLight gives the same directions (its mapping's one home)."""
    from glint.bake.lights import SkyLight

    h, w = 16, 32
    v, u = np.meshgrid((np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w, indexing="ij")
    sky_map = np.stack([1 + np.cos(2 * np.pi * u), 1 + np.sin(2 * np.pi * u), 0.5 + v], axis=-1).astype(np.float32)
    sky = Sky(np.float32([1.0, 2.0, 1.0]), sky_map)
    views = [(1, 0, 0), (0, 0, 1), (-1, 0.3, 0), (0.3, 0.2, -1), (0.2, 0.5, 0.3)]
    cams = [camera((0, 0, 0), target, 6.0) for target in views]
    scene = Scene("sky", None, sky=sky)
    d, _ = scalar.convert(scene, [scalar.sensor_dict(c, 2, 2, 16) for c in cams])
    mi_scene = mi.load_dict(d)
    light = SkyLight(sky)
    for i, c in enumerate(cams):
        got = scalar.render(mi_scene, sensor=i, spp=16).mean(axis=(0, 1))
        want = light.radiance(c.forward[None])[0]
        assert np.allclose(got, want, rtol=0.03), (views[i], got, want)


def test_spot_light_has_the_bakes_cone(scalar):
    """The `glint_spot` emitter: a white diffuse plane under a spot light shows kd/pi x E cos, with
    E (the glTF cone, squared) from bake/lights.py's DeltaLights, the bake's own light code."""
    from glint.bake.lights import DeltaLights
    from glint.core.scene import SpotLight

    spot = SpotLight(np.array([0.2, 0.1, 2.0]), np.array([0.0, 0.0, -1.0]), np.float32([2.0, 1.5, 1.0]), 0.2, 0.35)
    cam = camera((0, 0, 3), (0, 0, 0), 2 * math.degrees(math.atan(1 / 3)))
    scene = Scene("s", None, objects=[plane()], materials=[Material("white", kd=np.float32([1, 1, 1]))],
                  spot_lights=[spot])
    n = 24
    d, _ = scalar.convert(scene, [scalar.sensor_dict(cam, n, n, 4)])
    image = scalar.render(mi.load_dict(d), spp=4)
    centres = (np.arange(n) + 0.5) / n * 2 - 1  # the plane spans the image exactly
    X, Y = np.meshgrid(centres, -centres)
    points = np.stack([X, Y, np.zeros_like(X)], axis=-1).reshape(-1, 3)
    (l, _, E), = DeltaLights(scene).evaluate(points)
    expected = (E * l[:, 2:3] / np.pi).reshape(n, n, 3)
    lit = expected[..., 0] > 0.05 * expected[..., 0].max()
    assert 0.1 < lit.mean() < 0.9  # the cone's edge is in the picture
    assert np.allclose(block_means(image, 4), block_means(expected, 4), rtol=0.05, atol=0.01 * expected.max())


@pytest.mark.slow
def test_bench_mitsuba_cornell_box(tmp_path, scalar):
    """`glint bench cornell-box --mitsuba` at a tiny size writes the files with finite numbers; the
    converged viewer image is closer to Mitsuba's reference than Mitsuba itself at 4 spp, and
    within rel MSE 0.05 of it (measured about 0.01 at these sizes)."""
    from glint.cli import main

    out = tmp_path / "bench"
    assert main(["bench", "cornell-box", "--mitsuba", "--size", "16x16", "--supersample", "2",
                 "--reference-samples", "16", "--frames", "2", "--warmup", "1", "--mitsuba-reference-spp", "64",
                 "--mitsuba-max-spp", "4", "--mitsuba-variant", "scalar_rgb", "-o", str(out),
                 "--bake-dir", str(tmp_path / "cb.bake"), "-q", "preview"]) == 0
    data = json.loads((out / "mitsuba.json").read_text())
    assert data["mitsuba"]["variant"] == "scalar_rgb"
    assert (out / "mitsuba.png").stat().st_size > 1000
    rows = (out / "mitsuba.csv").read_text().splitlines()
    assert rows[0].startswith("scene,camera,method,spp,seconds")
    by = {(r["method"], r.get("spp")): r for r in data["results"]}
    assert set(by) == {("glint-walkthrough", None), ("glint-converged", None), ("mitsuba", 1), ("mitsuba", 2),
                       ("mitsuba", 4)}
    for r in data["results"]:
        e = r["regions"]["image"]
        assert r["seconds"] > 0 and math.isfinite(e["rel_mse"]) and math.isfinite(e["psnr_db"])
    converged = by[("glint-converged", None)]["regions"]["image"]["rel_mse"]
    assert converged < by[("mitsuba", 4)]["regions"]["image"]["rel_mse"]
    assert converged < 0.05
    # Mitsuba's error falls as its samples grow (the curve is a curve).
    assert by[("mitsuba", 4)]["regions"]["image"]["rel_mse"] < by[("mitsuba", 1)]["regions"]["image"]["rel_mse"]
    # The Mitsuba images' display transform is the renderer's own.
    from glint.bench.mitsuba import display_srgb
    from glint.core.bake_dir import Bake
    from glint.viewer.camera import ViewCamera
    from glint.viewer.context import headless_context
    from glint.viewer.renderer import Renderer

    bake = Bake(tmp_path / "cb.bake")
    ctx = headless_context()
    try:
        renderer = Renderer(ctx, bake, exposure=1.0)
        renderer.render(ViewCamera.from_manifest(bake.model.cameras[0]), 16, 16)
        shown = renderer.read_srgb().astype(int)
        assert np.abs(display_srgb(renderer.read_linear(), 1.0, ctx).astype(int) - shown).max() <= 1
        renderer.release()
    finally:
        ctx.release()


def test_display_srgb_is_the_tone_map():
    """bench/mitsuba.py display_srgb (the shaders' tone map run on numpy radiance) equals
    shaders/colour.glsl's formulas written in numpy here, to one 8-bit step (the renderer's own
    display: test_bench_mitsuba_cornell_box)."""
    from glint.bench.mitsuba import display_srgb

    rng = np.random.default_rng(0)
    linear = (rng.lognormal(-1, 2, (6, 5, 3))).astype(np.float32)
    linear[0, 0] = [0, 1e-5, 1e5]
    got = display_srgb(linear, 1.0)
    # numpy, from shaders/colour.glsl's formulas (Narkowicz's ACES fit, IEC 61966-2-1 sRGB)
    x = np.clip(linear * 2.0, 0, 1e4)
    a = np.clip((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0, 1)
    s = np.where(a <= 0.0031308, 12.92 * a, 1.055 * a ** (1 / 2.4) - 0.055)
    assert np.abs(got.astype(int) - np.rint(s * 255)).max() <= 1


def test_missing_mitsuba_is_one_line(monkeypatch):
    import sys

    from glint.bench.mitsuba import choose_variant
    from glint.core.errors import GlintError

    monkeypatch.setitem(sys.modules, "mitsuba", None)
    with pytest.raises(GlintError, match=r"pip install 'glint\[bench\]'"):
        choose_variant("auto")
