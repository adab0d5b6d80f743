"""The split-sum comparison method (viewer/split_sum.py, `glint bench --methods split-sum`) on
llvmpipe: hand-made bake directories with cube maps or a sky of known content.

Expected values come from outside the method: the lobe's directional albedo and the prefilter's
convolution by a deterministic quadrature over the half vector written out here (Gauss-Legendre
in tan(theta_h) scaled to the lobe's width, uniform in phi_h; the integrand is the numpy BSDF of
core/bsdf.py, not its importance sampling, which the method's LUT uses), the OpenGL cube-map
face rules of tests/test_specular.py, and analytic radiance functions.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from test_mirror_pass import BLACK, glossy, planar_bake
from test_renderer import material, quad
from test_specular import (
    EXTREMES,
    FLOOR,
    constant,
    cube_file,
    gl_texel_directions,
    lobe,
    orbit,
    pinhole_rays,
    specular_bake,
    view,
)

from glint.core import bsdf
from glint.viewer.camera import ViewCamera
from glint.viewer.passes.gbuffer import read_gbuffer
from glint.viewer.renderer import Renderer


# -- independent quadrature over the half vector ----------------------------------------------------
def half_vector_nodes(mx, my, n_t=64, n_phi=256, t_max=6.0):
    """(h (K, 3), d_omega_h (K,)): nodes and solid-angle weights over the upper hemisphere of half
    vectors, dense where the Beckmann lobe D(h) lives: tan(theta_h) = t m(phi), t Gauss-Legendre on
    [0, t_max] (D ~ exp(-t^2): exp(-36) beyond), m(phi)^-2 = cos^2 phi / mx^2 + sin^2 phi / my^2; and
    tan(phi) = my / mx tan(psi), psi uniform, which crowds phi where an anisotropic lobe is narrow."""
    x, w = np.polynomial.legendre.leggauss(n_t)
    t, wt = (x + 1) * t_max / 2, w * t_max / 2
    psi = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    phi = np.arctan2(my * np.sin(psi), mx * np.cos(psi))
    d_phi = mx * my / (mx ** 2 * np.cos(psi) ** 2 + my ** 2 * np.sin(psi) ** 2) * (2 * np.pi / n_phi)
    m = 1 / np.sqrt(np.cos(phi) ** 2 / mx ** 2 + np.sin(phi) ** 2 / my ** 2)
    T, P = np.meshgrid(t, phi, indexing="ij")
    M = np.broadcast_to(m, T.shape)
    theta = np.arctan(T * M)
    d_theta = M / (1 + (T * M) ** 2) * wt[:, None]  # d theta / dt
    h = np.stack([np.sin(theta) * np.cos(P), np.sin(theta) * np.sin(P), np.cos(theta)], -1).reshape(-1, 3)
    return h, (np.sin(theta) * d_theta * d_phi[None, :]).reshape(-1)


def albedo_quadrature(wo, spec):
    """int f(wi, wo) |cos theta_i| d omega_i = int f |wi.z| 4 (wo.h) d omega_h (wi = 2 (wo.h) h - wo,
    mirrored for transmission), for each wo (N, 3)."""
    h, dw = half_vector_nodes(max(spec["mx"], 1e-4), max(spec["my"], 1e-4))
    out = []
    for v in np.atleast_2d(wo):
        oh = h @ v
        wi = 2 * oh[:, None] * h - v
        if spec["kind"] == "transmit":
            wi = wi * np.array([1, 1, -1])
        f = bsdf.lobe_value(wi, v, spec["mx"], spec["my"], spec["r0"], spec["alpha"], spec["kind"])
        out.append(np.sum(f * np.abs(wi[:, 2]) * 4 * np.maximum(oh, 0) * dw))
    return np.array(out)


def test_the_quadrature_is_right():
    """The quadrature itself, on what is known in closed form: the projected area of the Beckmann
    half vectors, int D(h) cos(theta_h) d omega_h = 1, for mirror-like, rough and 1:100 lobes."""
    for mx, my in ((1e-3, 1e-3), (1.0, 1.0), (0.01, 1.0)):
        h, dw = half_vector_nodes(mx, my)
        assert np.sum(bsdf.beckmann_D(h, mx, my) * h[:, 2] * dw) == pytest.approx(1.0, abs=1e-6)


# -- white furnace ----------------------------------------------------------------------------------
FURNACE = [  # lobe, view polar angle, azimuth
    (lobe(m=(0.1, 0.1), r0=0.04), 0.3, 0.0),                            # glossy insulator
    (lobe(m=(0.3, 0.3), r0=0.5, alpha=0.5), 1.2, 0.0),                  # rough, Kurt's alpha, 69 deg
    (lobe(m=(0.05, 0.5), r0=0.9, alpha=0.2), 1.0, 0.0),                 # brushed metal, 1:10
    (lobe(m=(0.05, 0.5), r0=0.9, alpha=0.2), 1.0, math.pi / 2),         # ... seen along the other axis
    (lobe(m=(0.01, 1.0), r0=0.9), 0.6, 0.7),                            # anisotropy 1:100, between the axes
    (lobe(m=(1.0, 1.0), r0=0.2, alpha=1.0), 1.4, 0.0),                  # roughest, alpha 1, grazing (80 deg)
    (lobe(m=(0.002, 0.002), r0=1.0, alpha=0.5), 0.5, 0.0),              # near mirror
    (lobe("transmit", m=(0.2, 0.2), r0=0.04), 0.7, 0.0),                # frosted glass
]


@pytest.mark.parametrize("spec, theta, phi", FURNACE)
def test_white_furnace_gives_the_lobe_albedo(ctx, tmp_path, spec, theta, phi):
    """Constant incident radiance 1: the prefiltered map is 1 at every level, so each pixel shows
    the lobe's directional albedo for its view, within 1 % (the LUT's bilinear interpolation)."""
    size = (4, 4)
    camera, geometry = view(orbit(theta, phi))
    bake = specular_bake(tmp_path / "b", [FLOOR], [material(kd=(0, 0, 0), double_sided=True, lobes=[spec])], [0],
                         {0: (cube_file(constant(1.0), 16), (0, 0, 0), [])})
    with Renderer(ctx, bake, walkthrough="split-sum") as r:
        r.render(camera, *size)
        linear = r.read_linear()
        stats = r.stats
    wo = -pinhole_rays(*geometry, *size).reshape(-1, 3)  # the floor's frame is the world's (tangent +x)
    expected = albedo_quadrature(wo, spec).reshape(size[::-1])
    assert expected.min() > 0.01
    np.testing.assert_allclose(linear[..., 0], expected, rtol=0.01)
    assert stats["specular"]["walkthrough"] == "split-sum"
    assert stats["specular"]["lookups_per_pixel_with_lobes"] == 1.0  # one look-up per lobe, whatever n
    assert stats["split_sum"]["prefilter_ms"] > 0


def test_planar_reflector_under_a_uniform_sky_gives_the_albedo(ctx, tmp_path):
    """A glossy planar floor under a constant sky: its mirror buffer is 1 at every MIP level, so the
    one mirror-buffer look-up per pixel times the albedo is the albedo."""
    m, r0 = 0.15, 0.04
    bake = planar_bake(tmp_path / "b", [quad((0, 0, 0), (30, 0, 0), (0, 0, -30))],
                       [material("floor", kd=BLACK, lobes=[glossy(m, r0=r0, alpha=0.0)])], [0],
                       {0: ((0, 0, 0), (0, 1, 0))}, sky={"radiance": [1.0, 1.0, 1.0], "map": None})
    camera = ViewCamera.look_at((0, 1.0, 1.0), (0, 0, -1.5), (0, 1, 0), math.radians(40), znear=0.01, zfar=100)
    size = (12, 8)
    with Renderer(ctx, bake, walkthrough="split-sum") as r:
        r.render(camera, *size)
        linear = r.read_linear()[..., 0]
        spec = r.stats["specular"]
    assert spec["pixels_with_lobes"] == 12 * 8 and spec["mirror_buffer_lookups"] == 12 * 8
    assert spec["cube_map_lookups"] == 0
    forward, right, up = camera.ray_basis(size[0] / size[1])
    x = ((np.arange(size[0]) + 0.5) / size[0] * 2 - 1)[None, :, None]
    y = (1 - (np.arange(size[1]) + 0.5) / size[1] * 2)[:, None, None]
    d = forward + x * right + y * up
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    # local frame of the floor: any tangent will do for an isotropic lobe; wo = (sin theta, 0, cos theta)
    cos_o = -d[..., 1]
    wo = np.stack([np.sqrt(1 - cos_o ** 2), 0 * cos_o, cos_o], -1).reshape(-1, 3)
    expected = albedo_quadrature(wo, glossy(m, r0=r0, alpha=0.0)).reshape(size[::-1])
    np.testing.assert_allclose(linear, expected, rtol=0.01)


# -- the prefilter ----------------------------------------------------------------------------------
SUN = np.array([1.0, 0.5, 0.3]) / np.linalg.norm([1.0, 0.5, 0.3])


def sunny(d):
    """A smooth, non-symmetric sky: 0.1 plus a soft sun of ~0.4 rad around SUN, and a red tint."""
    s = np.exp(6.0 * (d @ SUN - 1.0))[..., None]
    return 0.1 + s * np.array([1.0, 0.8, 0.6]) + 0.05 * (d[..., :1] > 0)


def prefiltered_quadrature(r, m):
    """The split-sum prefilter of `sunny` along directions r (N, 3) for roughness m, in numpy: with
    n = v = r, the kernel f cos(theta_l) of Eq. 3.4 with F = 1 (r0 = 1) and alpha = 0, normalised:
    sum L(l) f cos / sum f cos over the half-vector quadrature (l = 2 (v.h) h - v)."""
    h, dw = half_vector_nodes(m, m, n_t=48, n_phi=96)
    v = np.array([0.0, 0.0, 1.0])
    l_local = 2 * h[:, 2:3] * h - v
    w = bsdf.reflect_lobe(l_local, v, m, m, 1.0, 0.0) * np.maximum(l_local[:, 2], 0) * 4 * h[:, 2] * dw
    out = []
    for rr in r:
        a = np.array([0.0, 0.0, 1.0]) if abs(rr[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        t = np.cross(a, rr)
        t /= np.linalg.norm(t)
        l_world = l_local @ np.stack([t, np.cross(rr, t), rr])  # columns t, b, r
        out.append(np.sum(sunny(l_world) * w[:, None], axis=0) / np.sum(w))
    return np.array(out)


def test_prefiltered_levels_are_the_lobe_convolution(ctx, tmp_path):
    """A 32-texel cube map of `sunny`: 4 levels (faces 32, 16, 8, 4) of roughness m_k = (k / 3)^2
    (level(m) = sqrt(m) (levels - 1), the glTF viewer's mapping). Every texel of levels 1 .. 3
    against the numpy convolution of the analytic sky: within 2 % + 0.001 (measured: 1.6 % at most,
    0.3 .. 0.5 % on average; the cube map's own texels, and the source's box-filtered MIP levels that
    filtered importance sampling reads; with 16 samples per texel instead of 64 .. 256 it is 5 .. 19 %)."""
    bake = specular_bake(tmp_path / "b", [FLOOR], [material(kd=(0, 0, 0), lobes=[lobe(m=(0.1, 0.1))])], [0],
                         {0: (cube_file(sunny, 32), (0, 0, 0), [])})
    with Renderer(ctx, bake, walkthrough="split-sum") as r:
        split = r.split_sum
        assert split.levels == [4]
        got = {k: split.read_level(0, k)[0] for k in range(4)}
    # level 0: the map itself (half floats; its lobe of m = 1e-4 reads a hair beside the texel centre)
    np.testing.assert_allclose(got[0][..., :3], sunny(gl_texel_directions(32)), rtol=2e-3, atol=5e-4)
    for k, face in ((1, 16), (2, 8), (3, 4)):
        m = (k / 3) ** 2
        d = gl_texel_directions(face).reshape(-1, 3)
        want = prefiltered_quadrature(d, m)
        have = got[k][..., :3].reshape(-1, 3)
        assert got[k].shape == (6, face, face, 4)
        np.testing.assert_allclose(have, want, rtol=0.02, atol=1e-3, err_msg=f"level {k}, m = {m:.3f}")
        # and it is a convolution: not the unfiltered sky (the sun's peak is lower, its flanks wider)
        assert np.abs(have - sunny(d)).max() > 0.05


# -- numerics ---------------------------------------------------------------------------------------
def test_extreme_parameters_give_finite_frames(ctx, tmp_path):
    """Roughness 1e-4..1, anisotropy 1:100, alpha 0..1, r0 0..1, both kinds, views down to exactly
    grazing, a 1e4 sun in the cube map: no NaN or Inf; with a uniform cube map of 1 the alpha = 0
    lobes (energy conserving) reflect at most 1."""
    k_all = range(len(EXTREMES))
    strips = [quad((-4.5 + k, 0, 0), (0.5, 0, 0), (0, 50, 0)) for k in k_all]
    mats = [material(f"m{k}", kd=(0, 0, 0), double_sided=True, lobes=[spec]) for k, spec in enumerate(EXTREMES)]

    def sun(d):
        return np.where((d[..., 2:3] > 0.9) | (d[..., 1:2] > 0.95), 1e4, 1.0) * np.ones(3)

    size = (48, 32)
    low = ((0, -3, 1e-3), (0, 10, 1e-3), (0, 0, 1), math.radians(60))
    views = [low, ((0, -3, 0.0), (0, 10, 0.0), (0, 0, 1), math.radians(60)),
             ((0, -1, 4), (0, 3, 0), (0, 0, 1), math.radians(80))]
    for name, function in (("sun", sun), ("uniform", constant(1.0))):
        bake = specular_bake(tmp_path / name, strips, mats, list(k_all),
                             {k: (cube_file(function, 8), (-4.5 + k, 0, 0), [((0, 0, -1), (0, 0, 1))]) for k in k_all})
        with Renderer(ctx, bake, walkthrough="split-sum") as r:
            shaded = 0
            for eye, target, up, yfov in views:
                r.render(ViewCamera.look_at(eye, target, up, yfov, znear=1e-4, zfar=100), *size)
                linear = r.read_linear()
                assert np.all(np.isfinite(linear)) and linear.min() >= 0
                shaded += r.stats["specular"]["pixels_with_lobes"]
            assert shaded > 1000
            r.render(ViewCamera.look_at(*low, znear=1e-4, zfar=100), *size)
            linear = r.read_linear()
            lut = r.scene.material_buffers.albedo.texture.read()
            g = read_gbuffer(r.gbuffer.targets)  # which strip (= material) each pixel shows, GL rows bottom first
            strip, drawn = g["material"][::-1], g["drawn"][::-1]
        assert np.all(np.isfinite(np.frombuffer(lut, np.float32)))
    conserving = drawn & np.isin(strip, [k for k, spec in enumerate(EXTREMES) if spec["alpha"] == 0.0])
    assert conserving.sum() > 100
    assert linear[..., 0][conserving].max() <= 1.01
