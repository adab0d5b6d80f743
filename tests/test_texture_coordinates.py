"""The base colour as glTF defines it: the texture's coordinates (textureInfo.texCoord and
KHR_texture_transform: offset, rotation, scale and its own texCoord), its sampler (wrap modes,
magFilter NEAREST) and the vertex colours (COLOR_0). Sections below for the last two.

The scene is made here: two quads of 0.6 m facing +z, lit by a constant sky only (nothing
shadows them, so E = pi everywhere and the capture shows the base colour). Both have a
TEXCOORD_1 that is the quad's planar (u, v) ((0, 0) at the top-left corner, v downwards) and a
TEXCOORD_0 that is its transpose (v, u), a wrong set to read. The image is 8 x 8 texels in
2 x 2-texel blocks of 8 colours (channels 0 or 255, the same in sRGB and linear):
- "Set1" uses texCoord 1, no transform: it shows the image.
- "Example" uses texCoord 0 with KHR_texture_transform {offset (0, 1), rotation pi/2, scale
  (0.5, 0.5), texCoord 1}, the extension's example, which "utilizes only the lower left quadrant
  of the source image, rotated clockwise 90 degrees" (KHR_texture_transform README, Example
  JSON): it shows np.rot90(image[4:, :4], -1).
The references are those image operations, not glint's code; the colours are read at the
blocks' centres, where bilinear filtering reads one colour.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from conftest import capture_front

from glint.scenes.generate import LAMBERT  # a Lambertian glTF material: the tests' expected kd is the base colour
from glint.bake.gltf_loader import load_scene
from glint.scenes.gltf_writer import GltfWriter, quad

HALF, CENTRES = 0.3, {"Set1": -0.35, "Example": 0.35}  # quads' half size and x centres (y = 1, z = 0)
EXAMPLE = {"offset": [0.0, 1.0], "rotation": math.pi / 2, "scale": [0.5, 0.5], "texCoord": 1}
EYE, FOV, SIZE = (0.0, 1.0, 1.5), 60.0, 128


def image() -> np.ndarray:
    """(8, 8, 3) uint8: 4 x 4 blocks of 2 x 2 texels, each one of the 8 colours (0 / 255 channels)."""
    rng = np.random.default_rng(7)
    blocks = rng.permutation(np.tile(np.arange(8), 2)).reshape(4, 4)
    colours = np.array([[(c >> k) & 1 for k in range(3)] for c in range(8)], np.uint8) * 255
    return np.repeat(np.repeat(colours[blocks], 2, axis=0), 2, axis=1)


def expected(name: str) -> np.ndarray:
    """The image the quad shows, linear RGB in 0..1, by the spec's words (module docstring)."""
    img = image().astype(float) / 255.0
    return img if name == "Set1" else np.rot90(img[4:, :4], -1)


def write_scene(path: Path) -> Path:
    w = GltfWriter()
    img = image()
    mats = {"Set1": w.add_material("Set1", base_color=(1, 1, 1), base_color_texture=img, texcoord=1,
                                   extensions=LAMBERT),
            "Example": w.add_material("Example", base_color=(1, 1, 1), base_color_texture=img, extensions=LAMBERT,
                                      texture_transform=EXAMPLE)}
    for name, cx in CENTRES.items():
        p, i = quad((cx, 1.0, 0.0), (HALF, 0, 0), (0, HALF, 0))
        uv = np.stack([(p[:, 0] - cx) / (2 * HALF) + 0.5, 0.5 - (p[:, 1] - 1.0) / (2 * HALF)], axis=1)
        w.add_node(name, mesh=w.add_mesh(name, p, i, mats[name], normals=np.tile([0, 0, 1], (4, 1)),
                                         uvs=uv[:, ::-1], uvs1=uv))
    path = Path(path)
    w.write(path)
    path.with_name(path.stem + ".glint.toml").write_text("[sky]\nradiance = 1.0\n")
    return path


def block_centres(name: str):
    """(x, y, expected colour) at the centres of the blocks the quad shows."""
    ref = expected(name)
    n = len(ref) // 2 if name == "Set1" else len(ref)  # blocks per side
    step = 1 if name == "Example" else 2
    for r in range(n):
        for c in range(n):
            u, v = (c + 0.5) / n, (r + 0.5) / n
            yield (CENTRES[name] + (u - 0.5) * 2 * HALF, 1.0 - (v - 0.5) * 2 * HALF,
                   ref[r * step, c * step])




def test_bake_reads_the_texcoord_set_and_the_texture_transform(tmp_path):
    """The bake's base colour (kd x texture, bake/irradiance.py `albedo`) where rays hit the quads
    is the reference image's colour.

    Deliberate bugs this catches (tried): TEXCOORD_0 read whatever texCoord says (both quads
    transposed); the transform's texCoord not overriding (Example transposed); the rotation's
    sign flipped (u' = cos u - sin v: another quadrant); offset applied before the scale
    (S T R: offset halved, another quadrant)."""
    from glint.bake.irradiance import _Transport
    from glint.bake.raytrace import RayTracer

    scene = load_scene(write_scene(tmp_path / "tex.glb"))
    tracer = RayTracer(scene)
    transport = _Transport(scene, tracer)
    for name in CENTRES:
        points = list(block_centres(name))
        o = np.array([[x, y, 1.0] for x, y, _ in points])
        d = np.tile([0.0, 0.0, -1.0], (len(o), 1))
        prim, b1, b2, _ = tracer.intersect_raw(o, d)
        assert (prim >= 0).all()
        mat = tracer.tri_material[prim]
        kd = transport.albedo(mat, prim, b1, b2)[0]
        np.testing.assert_allclose(kd, np.array([c for *_, c in points]), atol=1e-3, err_msg=name)


def test_capture_shows_the_texcoord_set_and_the_texture_transform(tmp_path):
    """The viewer's capture (G-buffer pass, constant light map of E = pi) at the blocks' centres
    shows the reference image's colours: each channel above 0.5 where it is 1, below 0.2 where 0.

    Deliberate bug this catches (tried): the rotation's sign flipped in the loader (the viewer
    samples the loader's uvs, as the bake does)."""

    img = capture_front(write_scene(tmp_path / "tex.glb"), SIZE, EYE, FOV)
    t = math.tan(math.radians(FOV) / 2) * EYE[2]
    for name in CENTRES:
        for x, y, colour in block_centres(name):
            r, c = int((1 - (y - 1) / t) / 2 * SIZE), int((1 + x / t) / 2 * SIZE)
            got = img[r, c]
            assert np.all(np.where(colour > 0.5, got > 0.5, got < 0.2)), (name, x, y, colour, got)


# -- samplers ---------------------------------------------------------------------------------
# Quads whose TEXCOORD_0 runs from -1 to 2 on both axes (three periods), each with an 4 x 4 image
# of random 0 / 255 channels and its own glTF sampler (glTF 5.26; 33071 CLAMP_TO_EDGE, 33648
# MIRRORED_REPEAT, 10497 REPEAT, 9728 NEAREST, 9729 LINEAR). The reference is the image padded by
# numpy per axis ("edge", "symmetric" (the edge texel repeated, then backwards), "wrap"): the
# texture as the sampler extends it, looked up directly in texels.
N = 4
SAMPLERS = {"ClampMirror": {"wrapS": 33071, "wrapT": 33648, "magFilter": 9728},
            "MirrorRepeat": {"wrapS": 33648, "wrapT": 10497, "magFilter": 9729}}
SAMPLER_CENTRES = {"ClampMirror": -0.35, "MirrorRepeat": 0.35}
PAD = {33071: "edge", 33648: "symmetric", 10497: "wrap"}


def sampler_image() -> np.ndarray:
    return np.random.default_rng(3).integers(0, 2, (N, N, 3)).astype(np.uint8) * 255


def extended(name: str) -> np.ndarray:
    """The image over uv -1..2 (plus one texel each side), linear, as its sampler wraps it."""
    s = SAMPLERS[name]
    img = sampler_image().astype(float) / 255.0
    img = np.pad(img, ((N + 1, N + 1), (0, 0), (0, 0)), mode=PAD[s["wrapT"]])
    return np.pad(img, ((0, 0), (N + 1, N + 1), (0, 0)), mode=PAD[s["wrapS"]])


def write_sampler_scene(path: Path) -> Path:
    w = GltfWriter()
    for name, cx in SAMPLER_CENTRES.items():
        mat = w.add_material(name, base_color=(1, 1, 1), extensions=LAMBERT, base_color_texture=sampler_image(),
                             sampler=SAMPLERS[name])
        p, i = quad((cx, 1.0, 0.0), (HALF, 0, 0), (0, HALF, 0))
        uv = np.stack([(p[:, 0] - cx) / (2 * HALF) + 0.5, 0.5 - (p[:, 1] - 1.0) / (2 * HALF)], axis=1)
        w.add_node(name, mesh=w.add_mesh(name, p, i, mat, normals=np.tile([0, 0, 1], (4, 1)),
                                         uvs=3 * uv - 1))
    path = Path(path)
    w.write(path)
    path.with_name(path.stem + ".glint.toml").write_text("[sky]\nradiance = 1.0\n")
    return path


def sampler_points(name: str, shift: float):
    """(x, y, expected) at every texel of the three periods, `shift` texels right of and below its
    centre: NEAREST reads that texel, LINEAR blends it with its right and lower neighbours."""
    ext, k = extended(name), 3 * N
    nearest = SAMPLERS[name]["magFilter"] == 9728
    for r in range(k):
        for c in range(k):
            u, v = (c + 0.5 + shift) / k, (r + 0.5 + shift) / k  # 0..1 over the quad
            a, b = r + 1, c + 1  # uv -1 is the padded image's texel 1
            if nearest:
                colour = ext[a, b]
            else:
                colour = ((1 - shift) ** 2 * ext[a, b] + shift * (1 - shift) * (ext[a, b + 1] + ext[a + 1, b])
                          + shift ** 2 * ext[a + 1, b + 1])
            yield (SAMPLER_CENTRES[name] + (u - 0.5) * 2 * HALF, 1.0 - (v - 0.5) * 2 * HALF, colour)


def test_bake_samples_through_the_glTF_sampler(tmp_path):
    """The bake's base colour (bake/irradiance.py `albedo`, core/image_io.py `sample_texture`) a
    quarter texel off the texel centres over uv -1..2 is the padded image's (nearest or bilinear).

    Deliberate bugs this catches (tried): CLAMP_TO_EDGE treated as REPEAT (`wrap_texel`);
    MIRRORED_REPEAT without the edge texel repeated (2 size - m instead of 2 size - 1 - m);
    magFilter NEAREST read as LINEAR; wrapS and wrapT swapped."""
    from glint.bake.irradiance import _Transport
    from glint.bake.raytrace import RayTracer

    scene = load_scene(write_sampler_scene(tmp_path / "samplers.glb"))
    tracer = RayTracer(scene)
    transport = _Transport(scene, tracer)
    for name in SAMPLERS:
        points = list(sampler_points(name, 0.25))
        o = np.array([[x, y, 1.0] for x, y, _ in points])
        prim, b1, b2, _ = tracer.intersect_raw(o, np.tile([0.0, 0.0, -1.0], (len(o), 1)))
        assert (prim >= 0).all()
        kd = transport.albedo(tracer.tri_material[prim], prim, b1, b2)[0]
        np.testing.assert_allclose(kd, np.array([c for *_, c in points]), atol=1e-3, err_msg=name)


def test_capture_samples_through_the_glTF_sampler(tmp_path):
    """The viewer's capture at the texels' centres over uv -1..2 shows the padded image's colours
    (each channel above 0.5 where it is 1, below 0.2 where 0), and a quarter texel off them the
    nearest quad reads its texel's colour, with the same thresholds.

    Deliberate bugs this catches (tried): the shader's `wrap_kd` ignoring the flags (all REPEAT);
    the S and T flags swapped in viewer/gpu_materials.py `sampler_flags`; the NEAREST snap to the
    texel's centre left out of `sample_kd`."""

    size = 256
    img = capture_front(write_sampler_scene(tmp_path / "samplers.glb"), size, EYE, FOV)
    t = math.tan(math.radians(FOV) / 2) * EYE[2]
    for name in SAMPLERS:
        shifts = (0.0, 0.25) if SAMPLERS[name]["magFilter"] == 9728 else (0.0,)
        for shift in shifts:
            for x, y, colour in sampler_points(name, shift):
                r, c = int((1 - (y - 1) / t) / 2 * size), int((1 + x / t) / 2 * size)
                got = img[r, c]
                assert np.all(np.where(colour > 0.5, got > 0.5, got < 0.2)), (name, shift, x, y, colour, got)


# -- vertex colours ---------------------------------------------------------------------------
# A quad with COLOR_0 affine in its planar (u, v) (so the two triangles' barycentric interpolation
# is exactly that function), baseColorFactor FACTOR and the block image of the first tests on
# TEXCOORD_0: glTF 3.9.2, the base colour is COLOR_0 x baseColorFactor x texture.
FACTOR = (0.5, 1.0, 0.8)


def vertex_colour(u, v) -> np.ndarray:
    u, v = np.asarray(u, float), np.asarray(v, float)
    return np.stack([0.1 + 0.8 * u, 0.9 - 0.8 * v, 0.2 + 0.3 * u + 0.4 * v], axis=-1)


def write_colour_scene(path: Path) -> Path:
    w = GltfWriter()
    mat = w.add_material("Coloured", base_color=FACTOR, base_color_texture=image(), extensions=LAMBERT)
    p, i = quad((0.0, 1.0, 0.0), (HALF, 0, 0), (0, HALF, 0))
    uv = np.stack([(p[:, 0]) / (2 * HALF) + 0.5, 0.5 - (p[:, 1] - 1.0) / (2 * HALF)], axis=1)
    w.add_node("Coloured", mesh=w.add_mesh("Coloured", p, i, mat, normals=np.tile([0, 0, 1], (4, 1)),
                                           uvs=uv, colors=vertex_colour(uv[:, 0], uv[:, 1])))
    path = Path(path)
    w.write(path)
    path.with_name(path.stem + ".glint.toml").write_text("[sky]\nradiance = 1.0\n")
    return path


def colour_points():
    """(x, y, expected base colour) at the image's block centres."""
    img = image().astype(float) / 255.0
    for r in range(4):
        for c in range(4):
            u, v = (c + 0.5) / 4, (r + 0.5) / 4
            yield (u - 0.5) * 2 * HALF, 1.0 - (v - 0.5) * 2 * HALF, \
                vertex_colour(u, v) * np.array(FACTOR) * img[2 * r, 2 * c]


def test_bake_multiplies_the_vertex_colours(tmp_path):
    """The bake's base colour on a quad with COLOR_0 is COLOR_0 x factor x texture.

    Deliberate bug this catches (tried): bake/irradiance.py `albedo` not multiplying the
    interpolated colours (the colours ignored)."""
    from glint.bake.irradiance import _Transport
    from glint.bake.raytrace import RayTracer

    scene = load_scene(write_colour_scene(tmp_path / "colours.glb"))
    tracer = RayTracer(scene)
    transport = _Transport(scene, tracer)
    points = list(colour_points())
    o = np.array([[x, y, 1.0] for x, y, _ in points])
    prim, b1, b2, _ = tracer.intersect_raw(o, np.tile([0.0, 0.0, -1.0], (len(o), 1)))
    assert (prim >= 0).all()
    kd = transport.albedo(tracer.tri_material[prim], prim, b1, b2)[0]
    np.testing.assert_allclose(kd, np.array([c for *_, c in points]), atol=1e-3)


def test_capture_multiplies_the_vertex_colours(tmp_path):
    """The capture (constant light map E = pi, so the diffuse radiance is the base colour) on the
    quad with COLOR_0 is COLOR_0 x factor x texture, within 0.03 (the dielectric's specular
    reflection of the sky adds a little).

    Deliberate bugs this catches (tried): raster_surface.glsl not multiplying v_color; the
    pipeline not writing `colors` into meshes.npz (the viewer's colours all 1)."""

    img = capture_front(write_colour_scene(tmp_path / "colours.glb"), SIZE, EYE, FOV)
    t = math.tan(math.radians(FOV) / 2) * EYE[2]
    for x, y, colour in colour_points():
        r, c = int((1 - (y - 1) / t) / 2 * SIZE), int((1 + x / t) / 2 * SIZE)
        np.testing.assert_allclose(img[r, c], colour, atol=0.03, err_msg=f"{x:.3f}, {y:.3f}")
