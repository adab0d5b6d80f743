"""glTF emissiveTexture (glTF 2.0 section 3.9.3: emission = emissiveFactor x emissiveTexture (sRGB)
x KHR_materials_emissive_strength) in the loader, the viewer and the bake's emitters.

The references are numpy expressions of the spec (sRGB decoding, texel look-up, a form-factor
quadrature), not glint's code.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from conftest import capture_front

from glint.bake.gltf_loader import load_scene
from glint.bake.irradiance import compute_irradiance
from glint.bake.raytrace import RayTracer
from glint.core.scene import Material, Object, Scene
from glint.scenes.gltf_writer import GltfWriter, quad

NEAREST = {"magFilter": 9728, "minFilter": 9728}  # glTF 5.26: texels stay sharp, one value each
FACTOR, STRENGTH = np.array([1.0, 0.5, 0.25]), 4.0


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1, the transfer function glTF 3.9.3 names for emissiveTexture."""
    c = np.asarray(c, float) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def emissive_image() -> np.ndarray:
    """(4, 4, 3) uint8: per texel and channel one of 0, 128, 255 (random, fixed)."""
    rng = np.random.default_rng(3)
    return np.array([0, 128, 255], np.uint8)[rng.integers(0, 3, (4, 4, 3))]


# -- loader and viewer ------------------------------------------------------------------------
HALF, EYE, FOV, SIZE = 0.4, (0.0, 1.0, 1.5), 60.0, 96


def write_lamp(path: Path) -> Path:
    """A black quad 0.8 m wide at z = 0 facing +z, centred at (0, 1, 0), emitting FACTOR x
    STRENGTH x the texture; uv (0, 0) at its top-left corner, v downwards. Nothing else lights it."""
    w = GltfWriter()
    mat = w.add_material("Lamp", base_color=(0, 0, 0), emissive=FACTOR, emissive_strength=STRENGTH,
                         emissive_texture=emissive_image(), sampler=NEAREST)
    p, i = quad((0.0, 1.0, 0.0), (HALF, 0, 0), (0, HALF, 0))
    uv = np.stack([(p[:, 0] + HALF) / (2 * HALF), (1.0 + HALF - p[:, 1]) / (2 * HALF)], axis=1)
    w.add_node("Lamp", mesh=w.add_mesh("Lamp", p, i, mat, normals=np.tile([0, 0, 1], (4, 1)), uvs=uv))
    path = Path(path)
    w.write(path)
    return path


def test_loader_reads_the_emissive_texture_as_linear(tmp_path):
    """Material.emission_texture is the image sRGB-decoded; emission stays factor x strength; no
    warning calls the texture ignored.

    Deliberate bugs this catches (tried): the texture kept (roughly) sRGB-encoded; emissiveTexture
    still listed as ignored."""
    scene = load_scene(write_lamp(tmp_path / "lamp.glb"))
    mat = scene.materials[0]
    np.testing.assert_allclose(mat.emission, FACTOR * STRENGTH, rtol=1e-6)
    np.testing.assert_allclose(mat.emission_texture, srgb_to_linear(emissive_image()), atol=1e-6)
    assert not any("emissiveTexture" in m for m in scene.warnings)


def test_capture_shows_the_emissive_texture(tmp_path):
    """The capture of the textured lamp (kd = 0, so radiance = emission) at every pixel whose centre
    sees the quad well inside one texel is FACTOR x STRENGTH x the texel, sRGB-decoded (rtol 1 %:
    the texture is stored as half floats); outside the quad the image is black.

    Deliberate bugs this catches (tried): the shading pass adding the constant emission for textured
    materials too (the white texels double, the black ones glow); the raster pass not multiplying
    by the texture (every texel at the factor)."""

    img = capture_front(write_lamp(tmp_path / "lamp.glb"), SIZE, EYE, FOV)
    texels = srgb_to_linear(emissive_image()) * FACTOR * STRENGTH
    t = math.tan(math.radians(FOV) / 2) * EYE[2]  # half the view's width at z = 0
    centre = (np.arange(SIZE) + 0.5) / SIZE * 2 - 1
    x, y = centre[None, :] * t, EYE[1] - centre[:, None] * t  # pixel centres on the plane z = 0
    u = (x + HALF) / (2 * HALF) * np.ones_like(y)
    v = (EYE[1] + HALF - y) / (2 * HALF) * np.ones_like(x)
    fu, fv = u * 4 - np.floor(u * 4), v * 4 - np.floor(v * 4)
    inside = (u > 0) & (u < 1) & (v > 0) & (v < 1)
    clear = inside & (np.minimum(fu, 1 - fu) > 0.1) & (np.minimum(fv, 1 - fv) > 0.1)
    assert clear.sum() > SIZE * SIZE // 8
    expected = texels[np.floor(v[clear] * 4).astype(int), np.floor(u[clear] * 4).astype(int)]
    np.testing.assert_allclose(img[clear], expected, rtol=0.01, atol=1e-3)
    outside = ~inside & (np.minimum.reduce([np.abs(u), np.abs(u - 1), np.abs(v), np.abs(v - 1)]) > 0.05)
    assert np.abs(img[outside]).max() < 1e-6


# -- bake ---------------------------------------------------------------------------------------
A, H = 0.5, 1.0  # the emitter: a square of side 2 A at height H facing down


def textured_lamp_scene(texture: np.ndarray | None) -> Scene:
    """A black floor (kd = 0: no inter-reflection) under the square emitter, uv = ((x + A) / 2A,
    (z + A) / 2A); emission FACTOR x STRENGTH x `texture` (None: untextured), NEAREST sampler."""
    floor_p = np.array([[-50, 0, 50], [50, 0, 50], [50, 0, -50], [-50, 0, -50]], float)
    floor = Object("floor", floor_p, np.tile([0, 1, 0], (4, 1)).astype(np.float32),
                   np.array([[0, 1, 2], [0, 2, 3]]), 0)
    lamp_p = np.array([[-A, H, -A], [A, H, -A], [A, H, A], [-A, H, A]], float)  # CCW seen from below
    lamp = Object("lamp", lamp_p, np.tile([0, -1, 0], (4, 1)).astype(np.float32),
                  np.array([[0, 1, 2], [0, 2, 3]]), 1,
                  uvs=np.stack([(lamp_p[:, 0] + A) / (2 * A), (lamp_p[:, 2] + A) / (2 * A)], 1).astype(np.float32))
    mats = [Material("floor", kd=np.zeros(3, np.float32)),
            Material("lamp", kd=np.zeros(3, np.float32), emission=(FACTOR * STRENGTH).astype(np.float32),
                     emission_texture=texture, kd_nearest=True)]
    return Scene("emissive-texture", None, objects=[floor, lamp], materials=mats)


def lit_rectangle_irradiance(x: np.ndarray, x0: float, x1: float, z0: float, z1: float) -> np.ndarray:
    """E at floor point x (normal +y) from the rectangle [x0, x1] x [z0, z1] at height H emitting
    FACTOR x STRENGTH: midpoint rule of L cos_x cos_l / d^2 dA on a 400 x 400 grid."""
    n = 400
    gx = x0 + (np.arange(n) + 0.5) / n * (x1 - x0)
    gz = z0 + (np.arange(n) + 0.5) / n * (z1 - z0)
    X, Z = np.meshgrid(gx, gz)
    d2 = (X - x[0]) ** 2 + H ** 2 + (Z - x[2]) ** 2
    form = np.sum(H * H / d2 ** 2) * (x1 - x0) * (z1 - z0) / n ** 2  # cos_x = cos_l = H / d
    return FACTOR * STRENGTH * form


def test_bake_lights_the_floor_from_the_lit_texels_only():
    """A 2 x 2 emissive texture with only texel (row 0, column 0) white lights the floor as the
    quadrant x in [-A, 0], z in [-A, 0] alone does (a numpy quadrature of its form factor), at four
    floor points, within 3 %. The untextured lamp gives 1.5 to 4x that, a texture flipped in u or v
    the mirrored quadrant (far off at the off-centre points).

    Deliberate bugs this catches (tried): next-event estimation evaluating the factor only (not the
    texture at the sampled point); emission at path hits ignoring the texture."""
    texture = np.zeros((2, 2, 3), np.float32)
    texture[0, 0] = 1.0
    sc = textured_lamp_scene(texture)
    points = np.array([[-0.5, 0, -0.5], [0.0, 0, 0.0], [0.5, 0, 0.5], [-0.4, 0, 0.3]])
    reps = 16
    r = compute_irradiance(sc, RayTracer(sc), np.repeat(points + [0, 1e-3, 0], reps, 0),
                           np.tile([0.0, 1.0, 0.0], (len(points) * reps, 1)), 256, seed=1)
    E = r.irradiance.reshape(len(points), reps, 3).mean(axis=1)
    for k, x in enumerate(points):
        expected = lit_rectangle_irradiance(x, -A, 0.0, -A, 0.0)
        np.testing.assert_allclose(E[k], expected, rtol=0.03, err_msg=str(x))
        whole = lit_rectangle_irradiance(x, -A, A, -A, A)
        assert np.all(whole > 1.4 * expected)  # what an untextured lamp would give: far outside


def test_textured_emitter_pdf_is_positive_wherever_it_emits():
    """A triangle whose probe points all miss a lone lit texel still gets a sampling weight (the
    floor of bake/lights.py), so next-event estimation can reach it: pdf_A > 0 on both triangles.

    Deliberate bug this catches (tried): EMISSION_FLOOR = 0 (the triangle whose probes see only
    black has weight 0)."""
    from glint.bake.lights import AreaLights

    texture = np.zeros((64, 64, 3), np.float32)
    texture[40, 1] = 1.0  # one texel in the lower-left triangle, between the probes
    sc = textured_lamp_scene(texture)
    tracer = RayTracer(sc)
    area = AreaLights(sc, tracer)
    lamp = np.flatnonzero(tracer.tri_material == 1)  # triangles (0, 1, 2): u > v, (0, 2, 3): u < v
    assert area.tri_pdf_area[lamp[1]] > 0


def test_another_texcoord_set_is_warned_and_the_base_colours_used(tmp_path):
    """An emissiveTexture naming TEXCOORD_1 beside a base colour texture on TEXCOORD_0: one
    warning; the object keeps the base colour's set (an object has one uv set here).

    Deliberate bug this catches (tried): the set compared but never warned."""
    w = GltfWriter()
    img = emissive_image()
    mat = w.add_material("Lamp", base_color=(1, 1, 1), base_color_texture=img, emissive=FACTOR,
                         emissive_texture=img)
    w.materials[mat]["emissiveTexture"]["texCoord"] = 1
    p, i = quad((0.0, 1.0, 0.0), (HALF, 0, 0), (0, HALF, 0))
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], float)
    w.add_node("Lamp", mesh=w.add_mesh("Lamp", p, i, mat, normals=np.tile([0, 0, 1], (4, 1)),
                                       uvs=uv, uvs1=uv[:, ::-1]))
    w.write(tmp_path / "two.glb")
    scene = load_scene(tmp_path / "two.glb")
    assert scene.materials[0].emission_texture is not None
    np.testing.assert_allclose(scene.objects[0].uvs, uv)
    assert sum("emissiveTexture uses another texture coordinate set" in m for m in scene.warnings) == 1
