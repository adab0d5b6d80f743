"""Normal maps, tangent frames and the anisotropy direction (glTF normalTexture, TANGENT,
KHR_materials_anisotropy rotation and texture).

The image test renders a 2 x 2 x 2 m room whose floor is a glossy metal with a normal map of
tilted bands, lit by a bright panel on the back wall, with glint (a converged capture) and with
Mitsuba 3 (bench/mitsuba_scene.py: the `normalmap` BSDF around glint's), and compares the floor
block by block.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from glint.bake.gltf_loader import load_scene
from glint.bake.material_mapping import GltfPbr, map_pbr
from glint.core.image_io import read_image
from glint.scenes.gltf_writer import GltfWriter, quad, room_faces
from glint.viewer.tangent_frames import surface_tangents, tangents

TILT = math.radians(22.0)
SIZE = 48
EYE = (0.0, 1.7, 0.95)
FOV = 70.0


def band_normal_map(flip_green: bool = False) -> np.ndarray:
    """(32, 32, 3) uint8 tangent-space normals in four bands along v, tilted by TILT towards +y, +x,
    -y, -x of the map (glTF: +x along +u, +y up the image, towards -v)."""
    s, c = math.sin(TILT), math.cos(TILT)
    tilts = [(0, s, c), (s, 0, c), (0, -s, c), (-s, 0, c)]
    image = np.zeros((32, 32, 3))
    for k, n in enumerate(tilts):
        image[8 * k:8 * k + 8] = n
    if flip_green:
        image[..., 1] *= -1
    return np.round((image * 0.5 + 0.5) * 255).astype(np.uint8)


def write_scene(path: Path, *, normal_map: np.ndarray | None, tangent=None, floor_extensions=None,
                floor_extras=None, anisotropy_texture: np.ndarray | None = None) -> Path:
    """The room: grey diffuse walls, a 1.4 x 0.7 m panel on the back wall (radiance 6), a metal
    floor (roughness 0.3) whose uvs repeat twice across it (u along +x, v along +z). An
    `anisotropy_texture` (uint8 RGB) joins the floor's KHR_materials_anisotropy extension."""
    w = GltfWriter()
    wall = w.add_material("Wall", base_color=(0.6, 0.6, 0.6), roughness=1.0)
    floor = w.add_material("Floor", base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=0.3,
                           extensions=floor_extensions, extras=floor_extras)
    if normal_map is not None:
        w.materials[floor]["normalTexture"] = {"index": w.add_texture(normal_map)}
    if anisotropy_texture is not None:
        w.materials[floor]["extensions"]["KHR_materials_anisotropy"]["anisotropyTexture"] = {
            "index": w.add_texture(anisotropy_texture)}
    lamp = w.add_material("Lamp", base_color=(0.8, 0.8, 0.8), emissive=(1, 1, 1), emissive_strength=6.0)
    faces = room_faces(1.0, 2.0, wall, floor)
    c, u, v, _ = faces.pop("Floor")
    w.add_quads({**faces, "Lamp": ((0, 1.2, -0.99), (0.7, 0, 0), (0, 0.35, 0), lamp)}, normals=True)
    p, i = quad(c, u, v)
    uvs = (p[:, [0, 2]] + 1.0)  # 0..2: two repeats of the map
    w.add_node("Floor", mesh=w.add_mesh("Floor", p, i, floor, normals=np.tile((0, 1, 0), (4, 1)), uvs=uvs,
                                        tangents=None if tangent is None else np.tile(tangent, (4, 1))))
    w.write(path)
    return path


def capture(path: Path, converge: int = 16) -> np.ndarray:
    from glint.cli import main

    out = path.with_suffix(".exr")
    assert main(["capture", str(path), "-o", str(out), "--size", f"{SIZE}x{SIZE}", "--eye", ",".join(map(str, EYE)),
                 "--target", "0,0.6,-0.6", "--fov", str(FOV), "-q", "draft", "--samples", "32",
                 "--texels-per-metre", "8", "--no-denoise", "--converge", str(converge), "--supersample", "2",
                 "--bake-dir", str(path.with_suffix(".bake"))]) == 0
    return read_image(out)[..., :3]


def mitsuba_image(path: Path, cache: str, spp: int = 256) -> np.ndarray:
    """Mitsuba 3's image of the scene at `path` (bench/mitsuba_scene.py, the fastest variant that
    works here, `spp` samples per pixel), read from tests/data/mitsuba/`cache`.npz when its key
    matches the scene, sensor, variant and code (tests/mitsuba_cache.py), else rendered."""
    import mitsuba as mi
    import mitsuba_cache

    from glint.bench.mitsuba_scene import convert, render, sensor_dict
    from glint.core.scene import Camera

    variant = mitsuba_cache.auto_variant()
    mi.set_variant(variant)
    eye = np.array(EYE)
    forward = np.array([0.0, 0.6, -0.6]) - eye
    forward /= np.linalg.norm(forward)
    up = np.array([0.0, 1.0, 0.0]) - forward[1] * forward
    camera = Camera("c", eye, forward, up / np.linalg.norm(up), math.radians(FOV))
    scene, sensor = load_scene(path), sensor_dict(camera, SIZE, SIZE, spp=spp)

    def live():
        scene_dict, _ = convert(scene, [sensor])
        return render(mi.load_dict(scene_dict), spp=spp)

    return mitsuba_cache.reference(cache, live, variant=variant, code=[mitsuba_image], scene=scene, sensor=sensor,
                                   spp=spp)


def luminance(image: np.ndarray) -> np.ndarray:
    return image @ np.array([0.2126, 0.7152, 0.0722])


def block_error(image: np.ndarray, reference: np.ndarray, rows: slice, block: int = 4) -> float:
    """Mean over 4 x 4-pixel blocks of the floor rows of |L - L_ref| / mean L_ref (block luminance)."""
    a, b = luminance(image[rows]), luminance(reference[rows])
    h, w = (a.shape[0] // block) * block, (a.shape[1] // block) * block
    a = a[:h, :w].reshape(h // block, block, w // block, block).mean(axis=(1, 3))
    b = b[:h, :w].reshape(h // block, block, w // block, block).mean(axis=(1, 3))
    return float(np.abs(a - b).mean() / b.mean())


@pytest.mark.slow
def test_normal_mapped_floor_matches_mitsuba(tmp_path):
    """The banded normal map on the glossy metal floor: glint's converged capture against Mitsuba 3
    (32 spp) rendering the same scene, mean block error (4 x 4-pixel blocks, lower half of the
    image: the floor) at most 0.15 of the mean. Measured: 0.105 since the still camera's third projection
    step (4d7acc3; 0.111 before it, 0.113 when the lobes were first fitted to the glTF BRDF, issue 24;
    0.18 before that, when glint's planar reflection of this room was 18 % darker, the same as the
    floor without a normal map: the normal map adds no error of its own). The map with its green
    channel flipped must be at least 0.2 off, well past the 0.15 a right map must meet (measured
    0.243; 0.253 before the third step, 0.27 when the bound of 0.25 was set; without a normal map
    0.60).

    Deliberate bugs this catches (tried): the normal map ignored (MAT_NORMAL_TEXTURE never set in
    viewer/gpu_materials.py): 0.78; the green channel flipped (tn.y negated in raster_surface.glsl
    `normal_mapped`): 0.37; the tangent frame wrong (b = -w n x t, the handedness of
    viewer/tangent_frames.py `tangents` reversed): 0.37; t and b swapped in `normal_mapped`: 0.69.
    The Mitsuba reference is cached in tests/data/mitsuba/normal_mapped_floor.npz with a key of its
    inputs and code (tests/mitsuba_cache.py); a stale key renders it as before and warns."""
    reference = mitsuba_image(write_scene(tmp_path / "reference.glb", normal_map=band_normal_map()),
                              "normal_mapped_floor", spp=32)
    image = capture(write_scene(tmp_path / "floor.glb", normal_map=band_normal_map()))
    floor = slice(SIZE // 2, SIZE)
    assert np.isfinite(image).all()
    error = block_error(image, reference, floor)
    assert error <= 0.15, error
    # the test can tell: the map with its green channel flipped is far off
    flipped = capture(write_scene(tmp_path / "flipped.glb", normal_map=band_normal_map(flip_green=True)))
    assert block_error(flipped, reference, floor) >= 0.2


def test_mikktspace_tangents_of_a_cylinder_and_a_plane():
    """MikkTSpace's rule against analytic frames: on a cylinder around y with u around it (u = angle
    / 2 pi) and v down its height, the tangent is the circumference direction d/d(angle) and w = +1
    (b = n x t points up, towards -v); on a plane whose uvs are mirrored in u, t = -x and w = -1 on
    the mirrored half, +1 on the other, and the vertices the halves share are split (one per
    handedness). Deliberate bugs this catches (tried): w's sign reversed (w = sign of the uv area):
    every w wrong; no split by handedness (groups by vertex only): the seam's tangents are the
    average of +x and -x, length 0, so they fall back to the axis."""
    k = 16
    angle = np.linspace(0, 2 * np.pi, k + 1)
    ring = np.stack([np.cos(angle), np.zeros_like(angle), -np.sin(angle)], axis=1)  # CCW seen from +y
    positions = np.concatenate([ring + (0, 1, 0), ring])
    normals = np.concatenate([ring, ring])
    uvs = np.concatenate([np.stack([angle / (2 * np.pi), np.zeros(k + 1)], 1),
                          np.stack([angle / (2 * np.pi), np.ones(k + 1)], 1)])
    tri = np.array([[i + k + 1, i + k + 2, i + 1] for i in range(k)] + [[i + k + 1, i + 1, i] for i in range(k)])
    face_n = np.cross(positions[tri[:, 1]] - positions[tri[:, 0]], positions[tri[:, 2]] - positions[tri[:, 0]])
    assert np.all(np.einsum("ij,ij->i", face_n, normals[tri].mean(axis=1)) > 0)
    source, out_tri, t = surface_tangents(positions, normals, uvs, tri)
    expected = np.stack([-np.sin(angle), np.zeros_like(angle), -np.cos(angle)], axis=1)  # d ring / d angle
    np.testing.assert_allclose(t[:, :3], np.concatenate([expected, expected])[source], atol=1e-6)
    np.testing.assert_array_equal(t[:, 3], 1.0)
    assert len(source) == len(positions)

    # A plane at y = 0 facing +y, the left half's uvs mirrored in u at x = 0.
    x = np.array([-1.0, 0.0, 1.0])
    positions = np.array([[a, 0.0, z] for z in (-1.0, 1.0) for a in x])
    normals = np.tile((0.0, 1.0, 0.0), (6, 1))
    uvs = np.array([[abs(p[0]), (p[2] + 1) / 2] for p in positions])
    tri = np.array([[0, 3, 4], [0, 4, 1], [1, 4, 5], [1, 5, 2]])
    source, out_tri, t = surface_tangents(positions, normals, uvs, tri)
    corners = t[out_tri]  # (4, 3, 4): left half then right half
    np.testing.assert_allclose(corners[:2, :, :3], np.tile((-1.0, 0.0, 0.0), (2, 3, 1)), atol=1e-9)
    np.testing.assert_allclose(corners[2:, :, :3], np.tile((1.0, 0.0, 0.0), (2, 3, 1)), atol=1e-9)
    np.testing.assert_array_equal(corners[:2, :, 3], -1.0)
    np.testing.assert_array_equal(corners[2:, :, 3], 1.0)
    assert len(source) == 8 and sorted(np.bincount(source)) == [1, 1, 1, 1, 2, 2]  # the seam's two split


def test_tangent_attribute_is_read_transformed_and_preferred(tmp_path):
    """A TANGENT in the file wins over MikkTSpace's, in world space: a floor whose file tangent is
    +z (w = -1) under a node mirrored in x keeps t = +z and gets w = +1 (a mirroring matrix flips
    the handedness; glTF 3.7.2.1). Deliberate bugs this catches (tried): w not flipped under the
    mirror: w = -1; TANGENT ignored: t = -x (the uvs' u direction after the mirror)."""
    w = GltfWriter()
    m = w.add_material("M")
    p, i = quad((0, 0, 0), (1, 0, 0), (0, 0, -1))
    w.add_node("Plane", mesh=w.add_mesh("Plane", p, i, m, normals=np.tile((0, 1, 0), (4, 1)),
                                        uvs=(p[:, [0, 2]] + 1) / 2, tangents=np.tile((0, 0, 1, -1), (4, 1))),
               scale=(-1, 1, 1))
    w.add_node("Lamp", light=w.add_light("Lamp", "point", intensity=10.0), translation=(0, 1, 0))
    obj = load_scene(w.write(tmp_path / "t.glb")).objects[0]
    source, _, t = surface_tangents(obj.positions, obj.normals, obj.uvs, obj.indices, obj.tangents)
    np.testing.assert_allclose(t[:, :3], np.tile((0, 0, 1), (len(t), 1)), atol=1e-6)
    np.testing.assert_array_equal(t[:, 3], 1.0)
    mikk = tangents(obj.positions, obj.normals, obj.uvs, obj.indices)
    np.testing.assert_allclose(mikk[..., :3].reshape(-1, 3), np.tile((-1, 0, 0), (mikk.size // 4, 1)), atol=1e-6)


@pytest.mark.slow
def floor_lobes() -> list[dict]:
    """The floor's lobes as the loader maps them (metal 0.9, roughness 0.3, anisotropy strength 0.8: the
    fitted table's narrow lobe and GGX's tail), as extras.glint lobes: the lobes compared with them
    differ only in the widths under test."""
    return [{"kind": "reflect", "ks": list(lobe.ks), "mx": lobe.mx, "my": lobe.my, "r0": lobe.r0, "alpha": lobe.alpha}
            for lobe in map_pbr(GltfPbr(base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=0.3, anisotropy=0.8))[1]]


def widths(lobes: list[dict], mx_of) -> list[dict]:
    """Each lobe with its widths (mx, my) replaced by the pair mx_of(mx, my) returns."""
    return [{**lb, "mx": mx_of(lb["mx"], lb["my"])[0], "my": mx_of(lb["mx"], lb["my"])[1]} for lb in lobes]


def test_anisotropy_rotation_of_90_degrees_swaps_the_widths(tmp_path):
    """KHR_materials_anisotropy: the floor (metal, roughness 0.3, strength 0.8) with
    anisotropyRotation pi/2 captures as the same floor whose lobe has mx and my swapped (an
    extras.glint lobe, no rotation), converged over 64 frames: mean |difference| on the floor rows
    at most 3 % of the mean (measured: 1.6 %, the quasi-random samples' orientation differs); the
    unrotated floor differs by 44 %. Deliberate bug this catches (tried): the rotation not applied
    (raster_surface.glsl `anisotropy_direction` with rotation (1, 0)): 44 %."""
    lobes = floor_lobes()

    def floor(name, rotation=None, lobe=None):
        ext = None if lobe else {"KHR_materials_anisotropy": {"anisotropyStrength": 0.8,
                                                              **({"anisotropyRotation": rotation} if rotation else {})}}
        extras = {"glint": {"lobes": lobe}} if lobe else None
        return capture(write_scene(tmp_path / f"{name}.glb", normal_map=None, floor_extensions=ext,
                                   floor_extras=extras), converge=64)[SIZE // 2:]

    rotated = floor("rotated", rotation=math.pi / 2)
    swapped = floor("swapped", lobe=widths(lobes, lambda mx, my: (my, mx)))
    plain = floor("plain")
    assert np.isfinite(rotated).all()
    difference = float(np.abs(rotated - swapped).mean() / swapped.mean())
    assert difference <= 0.03, difference
    assert float(np.abs(plain - swapped).mean() / swapped.mean()) >= 0.06


def test_anisotropy_texture_turns_and_narrows_the_lobe(tmp_path):
    """KHR_materials_anisotropy's texture, per pixel: RG is the direction in the tangent frame
    (2 x texel - 1), B scales the strength. A uniform texture of direction +y (RG = (128, 255)) and
    strength factor 1 must capture as the lobe with mx and my swapped; B = 128 (s = 0.5) as the lobe
    whose tangent width is my + (mx - my) s^2 (an extras.glint lobe of those widths, no texture).
    Mean |difference| on the floor rows, converged over 64 frames, at most 3 % of the mean
    (quasi-random sample orientation; the rotation test above measures 1.6 % for the same
    comparison). Deliberate bugs this catches (tried): the texture's RG direction ignored (the
    floor stays along t): 44 %; its B ignored (s = 1): 29 %; s applied linearly,
    mx' = my + (mx - my) s: 13 %."""
    lobes = floor_lobes()

    def floor(name, texture=None, lobe=None):
        ext = None if lobe else {"KHR_materials_anisotropy": {"anisotropyStrength": 0.8}}
        extras = {"glint": {"lobes": lobe}} if lobe else None
        image = None if texture is None else np.tile(np.array(texture, np.uint8), (4, 4, 1))
        return capture(write_scene(tmp_path / f"{name}.glb", normal_map=None, floor_extensions=ext,
                                   floor_extras=extras, anisotropy_texture=image), converge=64)[SIZE // 2:]

    def difference(a, b):
        return float(np.abs(a - b).mean() / b.mean())

    turned = floor("turned", texture=(128, 255, 255))
    swapped = floor("swapped", lobe=widths(lobes, lambda mx, my: (my, mx)))
    assert np.isfinite(turned).all()
    assert difference(turned, swapped) <= 0.03, difference(turned, swapped)
    s = 128 / 255
    narrowed = floor("narrowed", texture=(255, 128, 128))
    expected = floor("expected", lobe=widths(lobes, lambda mx, my: (my + (mx - my) * s * s, my)))
    assert difference(narrowed, expected) <= 0.03, difference(narrowed, expected)
