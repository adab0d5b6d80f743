"""Irradiance by path tracing (bake/irradiance.py, bake/lights.py, bake/raytrace.py) against
analytic results and Mitsuba 3."""
from __future__ import annotations

import numpy as np
import pytest

from glint.bake.irradiance import compute_irradiance
from glint.bake.lights import equirect_direction, equirect_uv
from glint.bake.raytrace import RayTracer
from glint.core.bsdf import lobe_albedo
from glint.core.scene import DirectionalLight, Lobe, Material, Object, PointLight, Scene, Sky, SpotLight

UP = np.array([0.0, 1.0, 0.0])


# -- scene building ------------------------------------------------------------------------------
def quad(name, center, u, v, material, flip=False):
    """Rectangle centre +- u +- v; its front face looks along u x v (along -(u x v) if flip)."""
    c, u, v = (np.asarray(a, float) for a in (center, u, v))
    P = np.array([c - u - v, c + u - v, c + u + v, c - u + v])
    idx = np.array([[0, 1, 2], [0, 2, 3]])
    n = np.cross(u, v)
    if flip:
        idx, n = idx[:, ::-1], -n
    return Object(name, P, np.tile(n / np.linalg.norm(n), (4, 1)).astype(np.float32), idx, material)


def disk(name, center, radius, normal, material, segments=512):
    """Regular polygon (triangle fan) approximating a disk, front face along `normal`."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    t = np.cross(n, a)
    t /= np.linalg.norm(t)
    b = np.cross(n, t)  # (t, b, n) right-handed: counter-clockwise around n
    phi = 2 * np.pi * np.arange(segments) / segments
    ring = np.asarray(center) + radius * (np.cos(phi)[:, None] * t + np.sin(phi)[:, None] * b)
    P = np.vstack([center, ring])
    idx = np.array([[0, 1 + i, 1 + (i + 1) % segments] for i in range(segments)])
    return Object(name, P, np.tile(n, (len(P), 1)).astype(np.float32), idx, material)


def box(name, lo, hi, material, inward=True):
    """Axis-aligned box of 12 triangles, faces looking inwards (or outwards)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c, h = (lo + hi) / 2, (hi - lo) / 2
    objs = []
    for axis in range(3):
        for s in (-1, 1):
            e = np.zeros(3)
            e[axis] = s * h[axis]
            u = np.zeros(3)
            u[(axis + 1) % 3] = h[(axis + 1) % 3]
            v = np.zeros(3)
            v[(axis + 2) % 3] = h[(axis + 2) % 3]
            # u x v points along +axis; the face at +axis looks outwards along +axis
            outward = s > 0
            objs.append(quad(f"{name}{axis}{s}", c + e, u, v, material, flip=(outward == inward)))
    P = np.vstack([o.positions for o in objs])
    N = np.vstack([o.normals for o in objs])
    idx = np.vstack([o.indices + 4 * i for i, o in enumerate(objs)])
    return Object(name, P, N, idx, material)


def black(name="black", **kw):
    return Material(name, kd=np.zeros(3, np.float32), **kw)


def ground(material=0, size=50.0):
    return quad("ground", (0, 0, 0), (size, 0, 0), (0, 0, -size), material)


def scene(objects, materials, **kw):
    return Scene("test", None, objects=objects, materials=materials, **kw)


def irradiance(sc, points, normals, samples=64, seed=0, **kw):
    points = np.atleast_2d(np.asarray(points, float))
    normals = np.broadcast_to(np.asarray(normals, float), points.shape)
    return compute_irradiance(sc, RayTracer(sc), points, normals, samples, seed=seed, **kw)


def on_ground(count=32, spread=0.2, rng=0):
    g = np.random.default_rng(rng)
    p = np.zeros((count, 3))
    p[:, [0, 2]] = g.uniform(-spread, spread, (count, 2))
    return p


# -- (a) sky -------------------------------------------------------------------------------------
@pytest.mark.parametrize("kd", [0.0, 0.7])
def test_constant_sky_over_ground_is_pi_L(kd):
    L = np.array([1.0, 2.0, 0.5])
    sc = scene([ground()], [Material("g", kd=np.full(3, kd, np.float32))], sky=Sky(radiance=L))
    r = irradiance(sc, on_ground(), UP, samples=16)
    # every upward ray escapes: E = pi L exactly, for any kd (the plane is below the horizon)
    np.testing.assert_allclose(r.irradiance, np.tile(np.pi * L, (32, 1)), rtol=1e-5)
    assert np.all(r.backface == 0)


def test_equirect_mapping_round_trip_and_convention():
    rng = np.random.default_rng(1)
    d = rng.normal(size=(1000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    u, v = equirect_uv(d)
    np.testing.assert_allclose(equirect_direction(u, v), d, atol=1e-12)
    # the documented convention: row 0 up, u = 0.5 at +X, 0.75 at +Z, 0.25 at -Z
    axes = np.array([[0, 1, 0], [1, 0, 0], [0, 0, 1], [0, 0, -1], [0, -1, 0]], float)
    u, v = equirect_uv(axes)
    np.testing.assert_allclose(v, [0, 0.5, 0.5, 0.5, 1])
    np.testing.assert_allclose(u[1:4], [0.5, 0.75, 0.25])


def test_sky_map_half_space():
    """A map bright only for x > 0 (u in (0.25, 0.75)): a receiver in empty space facing +X gets
    pi L, facing -X nothing, facing +Z or +Y half of pi L; tests mapping, sampling and MIS."""
    H, W = 32, 64
    m = np.zeros((H, W, 3), np.float32)
    m[:, W // 4:3 * W // 4] = (1.0, 0.5, 2.0)
    sc = scene([], [], sky=Sky(radiance=np.ones(3), map=m))
    normals = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 0, 1], [0, 1, 0]])
    points = np.zeros((4, 3))
    r = compute_irradiance(sc, RayTracer(sc), np.repeat(points, 8, 0), np.repeat(normals, 8, 0), 64)
    E = r.irradiance.reshape(4, 8, 3).mean(axis=1)
    L = np.array([1.0, 0.5, 2.0])
    expected = np.pi * L * np.array([1, 0, 0.5, 0.5])[:, None]
    # bilinear filtering blurs the edges at u = 0.25 and 0.75 by half a pixel: a small, symmetric effect
    np.testing.assert_allclose(E, expected, atol=0.02 * np.pi * L.max())


# -- (b) punctual lights -------------------------------------------------------------------------
def test_point_light_inverse_square_cosine():
    I = np.array([10.0, 20.0, 5.0])
    h = 2.0
    sc = scene([ground()], [black()], point_lights=[PointLight(np.array([0.0, h, 0.0]), I)])
    p = np.array([[0, 0, 0], [1.0, 0, 0], [0, 0, -3.0]])
    r = irradiance(sc, p, UP, samples=4)
    dist = np.linalg.norm(p - [0, h, 0], axis=1)
    expected = I[None] * (h / dist ** 3)[:, None]  # I / d^2 x cos, cos = h / d
    np.testing.assert_allclose(r.irradiance, expected, rtol=1e-5)


def test_spot_light_cone():
    I = np.array([4.0, 4.0, 4.0])
    h = 1.0
    inner, outer = np.radians(20), np.radians(40)
    sc = scene([ground()], [black()], spot_lights=[
        SpotLight(np.array([0.0, h, 0.0]), np.array([0.0, -1.0, 0.0]), I, inner, outer)])
    angles = np.radians([0, 10, 30, 39, 45])
    p = np.stack([h * np.tan(angles), np.zeros(5), np.zeros(5)], axis=1)
    r = irradiance(sc, p, UP, samples=4)
    cd = np.cos(angles)
    scale = 1 / (np.cos(inner) - np.cos(outer))
    att = np.clip((cd - np.cos(outer)) * scale, 0, 1) ** 2  # KHR_lights_punctual
    expected = I[None] * (att * cd / (h / cd) ** 2)[:, None]
    np.testing.assert_allclose(r.irradiance, expected, rtol=1e-5, atol=1e-7)
    assert r.irradiance[-1].max() == 0 and 0 < att[3] < 0.1


# -- (c) directional light -----------------------------------------------------------------------
def test_directional_light_cosine_and_shadow():
    Ed = np.array([3.0, 2.0, 1.0])
    direction = np.array([1.0, -2.0, 0.5])
    direction /= np.linalg.norm(direction)
    blocker = quad("roof", (10, 1, 10), (1, 0, 0), (0, 0, -1), 0, flip=True)  # shadows only near (10, 0, 10)
    sc = scene([ground(), blocker], [black()], directional_lights=[DirectionalLight(direction, Ed)])
    r = irradiance(sc, [[0, 0, 0], [5, 0, 2], [10 - 0.5, 0, 10.25]], UP, samples=4)
    cos = -direction[1]
    np.testing.assert_allclose(r.irradiance[:2], np.tile(Ed * cos, (2, 1)), rtol=1e-5)
    np.testing.assert_allclose(r.irradiance[2], 0.0)  # under the roof's shadow (offset by 0.5 along x)


# -- (d) area light ------------------------------------------------------------------------------
@pytest.mark.parametrize("double_sided,facing", [(False, -1), (True, -1), (True, 1), (False, 1)])
def test_emissive_disk_form_factor(double_sided, facing):
    Le = np.array([5.0, 3.0, 1.0])
    rad, h = 0.3, 1.0
    mats = [black(), Material("light", kd=np.zeros(3, np.float32), emission=Le, double_sided=double_sided)]
    sc = scene([ground(), disk("lamp", (0, h, 0), rad, (0, facing, 0), 1)], mats)
    r = irradiance(sc, on_ground(16, 0.01), UP, samples=128)
    expected = np.pi * Le * rad ** 2 / (rad ** 2 + h ** 2)
    if not double_sided and facing > 0:
        expected = 0 * Le  # one-sided emitter facing away
    E = r.irradiance.mean(axis=0)
    np.testing.assert_allclose(E, expected, rtol=0.01, atol=1e-9)


def test_disk_off_axis_against_quadrature():
    """A tilted receiver beside a disk light, with a bright diffuse floor: check the direct part
    (kd = 0) against numerical integration of the solid angle."""
    Le = np.array([2.0, 2.0, 2.0])
    rad, h = 0.5, 1.0
    mats = [black(), Material("light", kd=np.zeros(3, np.float32), emission=Le)]
    sc = scene([ground(), disk("lamp", (0, h, 0), rad, (0, -1, 0), 1)], mats)
    n = np.array([0.3, 1.0, 0.0])
    n /= np.linalg.norm(n)
    x = np.array([0.8, 0.0, 0.0])
    r = irradiance(sc, np.tile(x, (32, 1)), n, samples=128)
    # E = integral over the disk of L cos_x cos_l / d^2 dA (midpoint rule, polar grid)
    rr, pp = np.meshgrid((np.arange(400) + 0.5) / 400 * rad, (np.arange(800) + 0.5) / 800 * 2 * np.pi)
    y = np.stack([rr * np.cos(pp), np.full_like(rr, h), rr * np.sin(pp)], -1).reshape(-1, 3)
    dA = (rad / 400) * (2 * np.pi / 800) * rr.ravel()
    v = y - x
    d2 = (v * v).sum(1)
    cx = np.clip(v @ n, 0, None) / np.sqrt(d2)
    cl = v[:, 1] / np.sqrt(d2)
    expected = Le * np.sum(cx * cl / d2 * dA)
    np.testing.assert_allclose(r.irradiance.mean(axis=0), expected, rtol=0.01)


def test_base_colour_texture_orientation():
    """A point just above a textured, directionally lit floor looking down sees E = kd x texel x E0.

    The texture's four quadrants differ; glTF's convention puts uv (0, 0) at the image's top-left,
    row 0 of the array. Here u grows with +x and v with +z."""
    E0 = np.array([2.0, 2.0, 2.0])
    tex = np.zeros((64, 64, 3), np.float32)
    values = {(0, 0): 0.1, (0, 1): 0.3, (1, 0): 0.5, (1, 1): 0.9}  # (row half, column half)
    for (i, j), v in values.items():
        tex[32 * i:32 * (i + 1), 32 * j:32 * (j + 1)] = v
    floor = quad("floor", (0, 0, 0), (2, 0, 0), (0, 0, -2), 0)
    floor.uvs = np.stack([(floor.positions[:, 0] + 2) / 4, (floor.positions[:, 2] + 2) / 4], 1).astype(np.float32)
    sc = scene([floor], [Material("tex", kd=np.full(3, 0.8, np.float32), kd_texture=tex)],
               directional_lights=[DirectionalLight(np.array([0.0, -1.0, 0.0]), E0)])
    pts = np.array([[-1, 0.01, -1], [1, 0.01, -1], [-1, 0.01, 1], [1, 0.01, 1]], float)
    r = irradiance(sc, np.repeat(pts, 4, 0), [0, -1, 0], samples=256)
    E = r.irradiance.reshape(4, 4, 3).mean(axis=1)
    expected = [0.8 * values[k] * E0 for k in [(0, 0), (0, 1), (1, 0), (1, 1)]]
    np.testing.assert_allclose(E, expected, rtol=0.005)


# -- (e) furnace ---------------------------------------------------------------------------------
@pytest.mark.parametrize("albedo", [0.0, 0.5])
def test_furnace(albedo):
    """Inside a closed box whose walls emit L and reflect with albedo a: E = pi L / (1 - a), any normal."""
    Le = np.array([1.0, 0.5, 0.25])
    sc = scene([box("room", (-1, -1, -1), (1, 1, 1), 0)],
               [Material("wall", kd=np.full(3, albedo, np.float32), emission=Le)])
    rng = np.random.default_rng(3)
    normals = rng.normal(size=(64, 3))
    points = rng.uniform(-0.8, 0.8, (64, 3))
    r = irradiance(sc, points, normals / np.linalg.norm(normals, axis=1, keepdims=True), samples=64)
    expected = np.pi * Le / (1 - albedo)
    # 64 x 64 paths: the standard error of the mean is ~0.3% (albedo 0) and ~0.5% (albedo 0.5)
    np.testing.assert_allclose(r.irradiance.mean(axis=0), expected, rtol=0.015)
    np.testing.assert_allclose(r.irradiance, np.tile(expected, (64, 1)), rtol=0.25 if albedo else 0.1)
    assert np.all(r.backface == 0)


# Albedo 0.5 split between the diffuse part and a lobe (kd, ks, m, r0, alpha). A metal lobe with r0 = 1
# and alpha = 0.5 reflects F cos^(1 - 2 alpha) = 1 of what reaches it as m -> 0 (core/bsdf.py), so
# kd + ks = 0.5 in every direction (checked below); the dielectric lobe (r0 0.04, alpha 0) reflects
# 0.035-0.064 depending on the direction, so its kd is 0.5 minus its cosine-weighted mean.
GLOSSY_FURNACES = {
    "metal and diffuse": (0.25, 0.25, 0.05, 1.0, 0.5),
    "near-mirror metal": (0.0, 0.5, 1e-4, 1.0, 0.5),
    "dielectric and diffuse": (None, 1.0, 0.05, 0.04, 0.0),
}


@pytest.mark.parametrize("case", list(GLOSSY_FURNACES))
def test_furnace_with_lobes(case):
    """Inside a closed box whose walls emit Le and reflect with albedo 0.5, split between the diffuse
    part and a reflection lobe, E = pi L with L = Le / (1 - 0.5) = 2 Le everywhere (the Neumann
    series): every one of 32 points within 2 % (4096 paths each: standard error ~0.4 %).

    Deliberate bugs this catches (tried): the bake's paths ignoring the lobes (as before this test)
    give a mean of 0.667 / 0.500 / 0.930 of the expectation (the three cases in order); the one-sample
    MIS mixture pdf without the component probabilities (p = cos / pi + sum_j p_j) gives 0.693 and
    0.855 (metal and diffuse, dielectric and diffuse); the scattering weight f cos / p without its
    cosine (f / p) gives 9.4 / 7.6 / 14.1."""
    kd, ks, m, r0, alpha = GLOSSY_FURNACES[case]
    th = (np.arange(256) + 0.5) * (np.pi / 2) / 256
    wo = np.stack([np.sin(th), 0 * th, np.cos(th)], -1)
    a = lobe_albedo(wo, m, m, r0, alpha, "reflect", n=4096)
    mean = float(np.sum(a * 2 * np.cos(th) * np.sin(th)) * (np.pi / 2) / 256)  # int a(mu) 2 mu dmu
    if kd is None:
        kd = 0.5 - ks * mean
    else:  # the metal lobe reflects all up to 70 degrees (beyond, the lobe starts to cross the horizon)
        assert np.all(np.abs(a[th < np.radians(70)] - 1.0) < 0.012) and mean > 0.99
    Le = np.array([1.0, 0.5, 0.25])
    wall = Material("wall", kd=np.full(3, kd, np.float32), emission=Le,
                    lobes=[Lobe("reflect", (ks, ks, ks), m, m, r0, alpha)])
    sc = scene([box("room", (-1, -1, -1), (1, 1, 1), 0)], [wall])
    rng = np.random.default_rng(5)
    normals = rng.normal(size=(32, 3))
    points = rng.uniform(-0.8, 0.8, (32, 3))
    r = irradiance(sc, points, normals / np.linalg.norm(normals, axis=1, keepdims=True), samples=4096)
    ratio = r.irradiance / (np.pi * 2 * Le)
    print(case, "kd", kd, "mean", ratio.mean(), "min", ratio.min(), "max", ratio.max())
    np.testing.assert_allclose(ratio, 1.0, atol=0.02)


# -- (f) glass -----------------------------------------------------------------------------------
def glass(kd=0.0, ks=0.9, r0=0.04):
    return Material("glass", kd=np.full(3, kd, np.float32),
                    lobes=[Lobe("transmit", (ks, ks, ks), 0.01, 0.01, r0, 0.0)])


def test_glass_pane_filters_point_light():
    I = np.array([8.0, 8.0, 8.0])
    sc = scene([ground(), quad("pane", (0, 1, 0), (2, 0, 0), (0, 0, -2), 1)], [black(), glass()],
               point_lights=[PointLight(np.array([0.0, 2.0, 0.0]), I)])
    r = irradiance(sc, [[0, 0, 0]], UP, samples=4)
    T = 0.9 * (1 - 0.04)  # normal incidence: ks (1 - r0)
    np.testing.assert_allclose(r.irradiance[0], I / 4 * T, rtol=1e-5)


@pytest.mark.parametrize("glass_kd", [0.0, 0.3])
def test_glass_roof_under_constant_sky(glass_kd):
    """Under an infinite horizontal pane, E = 2 pi L int T(mu) mu dmu = 2 pi L ks (1 - r0) 10/21
    (T = ks (1 - r0) (1 - (1 - mu)^5)); a diffuse part on the pane changes nothing with a black floor
    (it only chooses scatter vs. pass-through at random)."""
    L = np.array([1.0, 1.0, 1.0])
    ks, r0 = 0.9, 0.04
    sc = scene([ground(), quad("pane", (0, 1, 0), (50, 0, 0), (0, 0, -50), 1)],
               [black(), glass(glass_kd, ks, r0)], sky=Sky(radiance=L))
    r = irradiance(sc, on_ground(64, 1.0), UP, samples=256)
    expected = 2 * np.pi * L * ks * (1 - r0) * 10 / 21  # standard error ~0.35% with glass_kd = 0.3
    np.testing.assert_allclose(r.irradiance.mean(axis=0), expected, rtol=0.012)


def test_glass_pane_filters_area_light():
    """A disk light seen through a pane at normal incidence: NEE (filtered) and the direction sample
    (passing through) together attenuate by T(cos) integrated over the disk."""
    Le = np.array([4.0, 4.0, 4.0])
    rad, h = 0.4, 2.0
    ks, r0 = 0.8, 0.1
    mats = [black(), Material("light", kd=np.zeros(3, np.float32), emission=Le), glass(0.0, ks, r0)]
    sc = scene([ground(), disk("lamp", (0, h, 0), rad, (0, -1, 0), 1),
                quad("pane", (0, 1, 0), (3, 0, 0), (0, 0, -3), 2)], mats)
    r = irradiance(sc, on_ground(16, 0.01), UP, samples=128)
    # on the axis, mu = cos theta, disk covers mu > mu0: E = 2 pi L int_mu0^1 T(mu) mu dmu
    mu = np.linspace(h / np.hypot(h, rad), 1.0, 20001)
    f = ks * (1 - r0) * (1 - (1 - mu) ** 5) * mu
    expected = 2 * np.pi * Le * np.sum((f[1:] + f[:-1]) / 2 * np.diff(mu))
    np.testing.assert_allclose(r.irradiance.mean(axis=0), expected, rtol=0.01)


# -- (g) back faces ------------------------------------------------------------------------------
def test_backface_fraction_inside_inverted_box():
    L = np.ones(3)
    sc_out = scene([box("b", (-1, -1, -1), (1, 1, 1), 0, inward=False)], [Material("w")], sky=Sky(radiance=L))
    sc_in = scene([box("b", (-1, -1, -1), (1, 1, 1), 0, inward=True)], [Material("w")], sky=Sky(radiance=L))
    p = np.zeros((8, 3))
    r_out = irradiance(sc_out, p, UP, samples=32)
    r_in = irradiance(sc_in, p, UP, samples=32)
    np.testing.assert_array_equal(r_out.backface, 1.0)
    np.testing.assert_array_equal(r_out.irradiance, 0.0)  # single-sided back faces end paths
    np.testing.assert_array_equal(r_in.backface, 0.0)
    # half a box open at the bottom: rays that leave through the open bottom miss, the rest hit back faces
    half = scene([quad("top", (0, 1, 0), (1, 0, 0), (0, 0, -1), 0)], [Material("w")])  # front face up
    r = irradiance(half, [[0, 0, 0]], UP, samples=4096)
    # fraction of cosine-weighted directions through a 2x2 square at distance 1: quadrature
    g = (np.arange(400) + 0.5) / 400 * 2 - 1
    X, Z = np.meshgrid(g, g)
    frac = np.sum(1 / np.pi / (X ** 2 + Z ** 2 + 1) ** 2) * (2 / 400) ** 2  # cos^2/(pi d^2) dA
    assert abs(r.backface[0] - frac) < 0.01


# -- robustness and determinism ------------------------------------------------------------------
def cornell_like():
    """A closed room with a ceiling light, two colours of wall and a box: for determinism and speed."""
    white = Material("white", kd=np.array([0.7, 0.7, 0.7], np.float32))
    red = Material("red", kd=np.array([0.6, 0.1, 0.1], np.float32))
    light = Material("light", kd=np.zeros(3, np.float32), emission=np.array([15.0, 12.0, 8.0]))
    room = box("room", (-1, -1, -1), (1, 1, 1), 0)
    objs = [room, box("block", (-0.5, -1, -0.4), (0.1, 0.2, 0.2), 0, inward=False),
            quad("red", (-0.99, 0, 0), (0, 0, -0.9), (0, 0.9, 0), 1),
            quad("lamp", (0, 0.99, 0), (0.25, 0, 0), (0, 0, 0.2), 2)]
    return scene(objs, [white, red, light])


def test_chunking_does_not_change_result_and_no_nan():
    sc = cornell_like()
    tr = RayTracer(sc)
    rng = np.random.default_rng(5)
    pts = np.column_stack([rng.uniform(-0.9, 0.9, 40), np.full(40, -1.0), rng.uniform(-0.9, 0.9, 40)])
    nrm = np.tile(UP, (40, 1))
    nrm[3] = 0  # a zero-length normal: E = 0, no NaN
    pts[4] = np.nan
    whole = compute_irradiance(sc, tr, pts, nrm, 16, seed=7)
    parts = [compute_irradiance(sc, tr, pts[i:i + 13], nrm[i:i + 13], 16, seed=7, first_index=i)
             for i in range(0, 40, 13)]
    np.testing.assert_array_equal(whole.irradiance, np.concatenate([p.irradiance for p in parts]))
    np.testing.assert_array_equal(whole.backface, np.concatenate([p.backface for p in parts]))
    assert np.isfinite(whole.irradiance).all() and whole.irradiance[[3, 4]].max() == 0
    other = compute_irradiance(sc, tr, pts, nrm, 16, seed=8)
    assert not np.array_equal(other.irradiance, whole.irradiance)
    assert whole.rays > 40 * 16


# -- Mitsuba 3 ----------------------------------------------------------------------------------
def _mitsuba_irradiance(scene_dict, points, normals, spp):
    """E at surface points in a Mitsuba scene: pi x the radiance of a tiny white Lambertian disk
    lying 0.5 mm above the point, seen by a radiancemeter (as bench/mitsuba_reference.py does)."""
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    T = mi.ScalarTransform4f
    d = dict(scene_dict)
    d["integrator"] = {"type": "path", "max_depth": -1}
    d["patch_bsdf"] = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}}
    for i, (p, n) in enumerate(zip(points, normals)):
        c = p + 5e-4 * n
        a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
        up = np.cross(n, a)
        d[f"patch_{i}"] = {"type": "disk", "bsdf": {"type": "ref", "id": "patch_bsdf"},
                           "to_world": T().look_at(origin=c.tolist(), target=(c + n).tolist(),
                                                   up=(up / np.linalg.norm(up)).tolist()) @ T().scale([2e-3, 2e-3, 1])}
        d[f"sensor_{i:04d}"] = {"type": "radiancemeter", "origin": (c + 1e-2 * n).tolist(), "direction": (-n).tolist(),
                                "film": {"type": "hdrfilm", "width": 1, "height": 1, "rfilter": {"type": "box"},
                                         "pixel_format": "rgb"},
                                "sampler": {"type": "independent", "sample_count": spp}}
    scene = mi.load_dict(d)
    return np.array([np.pi * np.array(mi.render(scene, sensor=i, spp=spp, seed=i)).reshape(-1, 3)[0]
                     for i in range(len(points))])


def test_sky_map_against_mitsuba_envmap():
    """A floor and a box under a sky map with a sun-like blob: Mitsuba's envmap with
    to_world = rotate(Y, 90 deg) is the documented equivalent of our mapping (the wrong
    rotation moves the sun and fails by 40-80%)."""
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    H, W = 64, 128
    vv, uu = np.meshgrid((np.arange(H) + 0.5) / H, (np.arange(W) + 0.5) / W, indexing="ij")
    dirs = equirect_direction(uu.ravel(), vv.ravel()).reshape(H, W, 3)
    sun = np.array([0.6, 0.6, 0.5]) / np.linalg.norm([0.6, 0.6, 0.5])
    m = (0.3 + 0.7 * np.clip(dirs[..., 1:2], 0, 1)) * np.array([0.4, 0.6, 1.0])
    m = (m + np.exp(((dirs @ sun) - 1) * 200)[..., None] * np.array([50.0, 40.0, 30.0])).astype(np.float32)
    kd = 0.5
    sc = scene([quad("floor", (0, 0, 0), (2, 0, 0), (0, 0, -2), 0),
                box("cube", (-0.3, 0.0, -0.3), (0.3, 0.6, 0.3), 0, inward=False)],
               [Material("w", kd=np.full(3, kd, np.float32))], sky=Sky(radiance=np.ones(3), map=m))
    pts = np.array([[0.6, 0, 0.1], [-0.5, 0, 0.4], [0.0, 0, -0.7], [0.3, 0.3, 0.0], [-0.3, 0.3, 0.1], [0.0, 0.6, 0.0]])
    nrm = np.array([[0, 1, 0], [0, 1, 0], [0, 1, 0], [1, 0, 0], [-1, 0, 0], [0, 1, 0]], float)
    ours = irradiance(sc, np.repeat(pts, 8, 0), np.repeat(nrm, 8, 0), samples=1024).irradiance
    ours = ours.reshape(len(pts), 8, 3).mean(axis=1)
    T = mi.ScalarTransform4f
    white = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [kd] * 3}}
    ref = _mitsuba_irradiance({
        "type": "scene",
        "sky": {"type": "envmap", "bitmap": mi.Bitmap(m), "to_world": T().rotate([0, 1, 0], 90)},
        "floor": {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale([2, 2, 1]), "bsdf": white},
        "cube": {"type": "cube", "to_world": T().translate([0, 0.3, 0]).scale([0.3, 0.3, 0.3]), "bsdf": white},
    }, pts, nrm, spp=16384)
    rel = np.abs(ours - ref).mean(axis=1) / ref.mean(axis=1)
    assert rel.max() < 0.03 and rel.mean() < 0.012, rel


def _cornell_from_mitsuba(mi):
    """mitsuba.cornell_box() as a bake Scene (rectangles and cubes with their transforms)."""
    d = mi.cornell_box()
    mats, index = [], {}
    for k in ("white", "red", "green"):
        index[k] = len(mats)
        mats.append(Material(k, kd=np.array(d[k]["reflectance"]["value"], np.float32)))
    objs = []
    for name, v in d.items():
        if not isinstance(v, dict) or v.get("type") not in ("rectangle", "cube"):
            continue
        M = np.array(v["to_world"].matrix)
        if v["type"] == "rectangle":
            o = quad(name, (0, 0, 0), (1, 0, 0), (0, 1, 0), 0)  # [-1, 1]^2, front face +z
        else:
            o = box(name, (-1, -1, -1), (1, 1, 1), 0, inward=False)
        P = o.positions @ M[:3, :3].T + M[:3, 3]
        n = o.normals @ np.linalg.inv(M[:3, :3])  # normals by the inverse transpose
        material = index[v["bsdf"]["id"]]
        if "emitter" in v:
            material = len(mats)
            mats.append(Material("light", kd=mats[index["white"]].kd,
                                 emission=np.array(v["emitter"]["radiance"]["value"], np.float32)))
        objs.append(Object(name, P, (n / np.linalg.norm(n, axis=1, keepdims=True)).astype(np.float32),
                           o.indices, material))
    return scene(objs, mats)


def test_cornell_box_against_mitsuba():
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    sc = _cornell_from_mitsuba(mi)
    # points on the walls, ceiling and floor and on the two boxes' tops, away from edges
    pts = np.array([[-0.99999, 0.3, 0.2], [0.99999, -0.4, -0.5], [0.2, 0.5, -0.99999], [0.5, -0.99999, -0.6],
                    [-0.5, 0.99999, 0.5], [0.35, -0.4, 0.4], [-0.33, 0.21, -0.28], [-0.8, -0.99999, 0.8]])
    nrm = np.array([[1, 0, 0], [-1, 0, 0], [0, 0, 1], [0, 1, 0], [0, -1, 0], [0, 1, 0], [0, 1, 0], [0, 1, 0]], float)
    tr = RayTracer(sc)
    # the box tops: lift the points onto the actual surfaces (the cubes are rotated)
    for i in (5, 6):
        h = tr.intersect(pts[i:i + 1] + [0, 0.25, 0], np.array([[0, -1.0, 0]]))
        assert h.object[0] == [o.name for o in sc.objects].index(("small-box", "large-box")[i - 5])
        pts[i] = h.position[0]
        nrm[i] = h.ng[0]
    r = compute_irradiance(sc, tr, np.repeat(pts, 8, 0), np.repeat(nrm, 8, 0), 4096)
    assert r.backface.max() < 1e-3  # a grazing ray from the ceiling may hit the lamp's back
    ours = r.irradiance.reshape(len(pts), 8, 3).mean(axis=1)
    ref = _mitsuba_irradiance({k: v for k, v in mi.cornell_box().items() if k not in ("sensor", "integrator")},
                              pts, nrm, spp=32768)
    rel = np.abs(ours - ref).mean(axis=1) / ref.mean(axis=1)
    assert rel.mean() < 0.02 and rel.max() < 0.05, rel
