"""glTF alpha coverage (alphaMode MASK and BLEND, alphaCutoff): loading, the bake's rays and texels,
the raster passes' discard.

The scenes are made here: a 1.2 m floor, above it at 0.5 m a 0.6 m "leaf" quad whose base colour
texture's alpha is an annulus (opaque between 0.25 and 0.8 of its half size, cut out inside and
outside), and a small square lamp 2 m up facing down. The leaf casts a ring-shaped shadow with a
lit centre; with the alpha ignored it casts a full square one.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.core.bake_dir import Bake
from glint.scenes.gltf_writer import GltfWriter, quad
from glint.services import bake_scene

R_IN, R_OUT = 0.25, 0.8  # the annulus, in units of the leaf's half size
LEAF_HALF, LEAF_HEIGHT = 0.3, 0.5
FLOOR_HALF = 0.6
LAMP_HALF, LAMP_HEIGHT, LAMP_RADIANCE = 0.1, 2.0, 100.0
LEAF_UV = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], float)  # of quad()'s corners


def ring_alpha(n: int = 64) -> np.ndarray:
    """(n, n) uint8 alpha: 255 on the annulus, 0 elsewhere (symmetric under flips and transposes)."""
    c = (np.arange(n) + 0.5) / n * 2 - 1
    r = np.hypot(*np.meshgrid(c, c))
    return np.where((r >= R_IN) & (r <= R_OUT), 255, 0).astype(np.uint8)


def green_texture(alpha: np.ndarray | None, green: int) -> np.ndarray:
    """RGBA uint8: green `green`, alpha `alpha` (default: the ring)."""
    alpha = ring_alpha() if alpha is None else alpha
    image = np.zeros(alpha.shape + (4,), np.uint8)
    image[..., 1] = green
    image[..., 3] = alpha
    return image


def write_leaf_scene(path: Path, mode: str | None = "MASK", cutoff: float | None = None,
                     base_alpha: float = 1.0, texture_alpha: np.ndarray | None = None, lamp: bool = True) -> Path:
    w = GltfWriter()
    floor = w.add_material("Floor", base_color=(0.5, 0.5, 0.5), roughness=1.0)
    leaf = w.add_material("Leaf", base_color=(0.3, 0.6, 0.2, base_alpha), roughness=1.0,
                          base_color_texture=green_texture(texture_alpha, 160), alpha_mode=mode, alpha_cutoff=cutoff)
    p, i = quad((0, 0, 0), (FLOOR_HALF, 0, 0), (0, 0, -FLOOR_HALF))
    w.add_node("Floor", mesh=w.add_mesh("Floor", p, i, floor, normals=np.tile([0, 1, 0], (4, 1))))
    p, i = quad((0, LEAF_HEIGHT, 0), (LEAF_HALF, 0, 0), (0, 0, -LEAF_HALF))
    w.add_node("Leaf", mesh=w.add_mesh("Leaf", p, i, leaf, normals=np.tile([0, 1, 0], (4, 1)), uvs=LEAF_UV))
    if lamp:
        lamp = w.add_material("Lamp", base_color=(0, 0, 0), emissive=(1, 1, 1), emissive_strength=LAMP_RADIANCE)
        p, i = quad((0, LAMP_HEIGHT, 0), (LAMP_HALF, 0, 0), (0, 0, LAMP_HALF))
        w.add_node("Lamp", mesh=w.add_mesh("Lamp", p, i, lamp, normals=np.tile([0, -1, 0], (4, 1))))
    path = Path(path)
    w.write(path)
    return path


# -- loading --------------------------------------------------------------------------------------
def test_loader_reads_mode_cutoff_factor_and_texture_alpha(tmp_path):
    scene = load_scene(write_leaf_scene(tmp_path / "a.glb", "MASK", 0.3, base_alpha=0.8))
    leaf = scene.materials[1]
    assert (leaf.alpha_mode, leaf.alpha_cutoff, leaf.alpha) == ("MASK", 0.3, pytest.approx(0.8))
    assert leaf.alpha_texture.shape == (64, 64) and leaf.kd_texture.shape == (64, 64, 3)
    np.testing.assert_array_equal(leaf.alpha_texture, ring_alpha() / 255.0)  # linear, not sRGB-decoded
    assert scene.materials[0].alpha_mode == "OPAQUE" and scene.materials[0].alpha_texture is None

    default = load_scene(write_leaf_scene(tmp_path / "b.glb", "MASK")).materials[1]
    assert default.alpha_cutoff == 0.5  # the glTF default
    opaque = load_scene(write_leaf_scene(tmp_path / "c.glb", None)).materials[1]
    assert opaque.alpha_mode == "OPAQUE" and opaque.alpha_texture is None  # OPAQUE ignores alpha
    blend = load_scene(write_leaf_scene(tmp_path / "d.glb", "BLEND")).materials[1]
    assert blend.alpha_mode == "BLEND"


# -- the bake: analytic cases ---------------------------------------------------------------------
def disc_fraction(radius: float, height: float) -> float:
    """Cosine-weighted fraction of the hemisphere a disc covers, seen from a point on its axis:
    sin^2 of its half-angle (E under a uniform disc of radiance L is pi L sin^2)."""
    return radius ** 2 / (radius ** 2 + height ** 2)


def square_fraction(half: float, height: float) -> float:
    """The same for a square of half size `half` centred above the point: four times the form factor
    from a point to a parallel a x b rectangle above its corner (Howell's catalogue, B-3):
    1 / (2 pi) [A / sqrt(1 + A^2) atan(B / sqrt(1 + A^2)) + B / sqrt(1 + B^2) atan(A / sqrt(1 + B^2))]."""
    A = B = half / height
    f = (A / math.sqrt(1 + A * A) * math.atan(B / math.sqrt(1 + A * A))
         + B / math.sqrt(1 + B * B) * math.atan(A / math.sqrt(1 + B * B))) / (2 * math.pi)
    return 4 * f


def irradiance_under_leaf(path: Path, *, sky: bool = False, sun: bool = False, samples: int = 8192):
    """E and the back-face fraction at the floor point under the leaf's centre: lit by a constant
    sky of radiance 1 (reached by the cosine-sampled path rays alone) or by a directional light of
    1 W/m^2 straight down (shadow rays alone)."""
    from glint.bake.irradiance import compute_irradiance
    from glint.bake.raytrace import RayTracer
    from glint.core.scene import DirectionalLight, Sky

    path.with_name(path.stem + ".glint.toml").write_text("[sky]\nradiance = 1.0\n")  # a scene needs a light
    scene = load_scene(path)
    scene.sky = Sky(radiance=np.ones(3, np.float32)) if sky else None
    if sun:
        scene.directional_lights.append(DirectionalLight(np.array([0.0, -1.0, 0.0]), np.ones(3)))
    r = compute_irradiance(scene, RayTracer(scene), [[0.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]], samples)
    return float(r.irradiance[0, 0]), float(r.backface[0])


def test_path_and_shadow_rays_pass_the_cut_out_analytically(tmp_path):
    """Under the ring's hole, lit by a constant sky only through cosine-sampled path rays, E / pi is
    1 minus the annulus' cosine-weighted solid angle, and the back-face statistic is that solid angle
    (the leaf is single-sided, facing up: the floor sees its back); a directional light straight
    down reaches the point through the hole with its full 1 W/m^2 (the shadow rays).

    Deliberate bugs this catches (tried): path rays ignoring alpha (no `uniform`-driven loop: the
    plain RayTracer.intersect_hits in bake/irradiance.py) give E / pi = 1 - 0.31 (the square) and a
    back-face fraction of 0.31; shadow rays ignoring alpha (the plain occlusion query) give 0 W/m^2
    from the directional light."""
    path = write_leaf_scene(tmp_path / "sky.glb", lamp=False)
    h = LEAF_HEIGHT
    # the annulus: the texture's radii in metres (the 64-texel staircase of its edges: < 1 %)
    ring = disc_fraction(R_OUT * LEAF_HALF, h) - disc_fraction(R_IN * LEAF_HALF, h)
    E, back = irradiance_under_leaf(path, sky=True)
    assert E / math.pi == pytest.approx(1 - ring, abs=0.01)
    assert back == pytest.approx(ring, abs=0.01)
    assert square_fraction(LEAF_HALF, h) - ring > 0.1  # what an uncut leaf would block instead
    E, _ = irradiance_under_leaf(path, sun=True, samples=16)
    assert E == pytest.approx(1.0, abs=1e-6)


def test_blend_lets_one_minus_alpha_through(tmp_path):
    """A BLEND leaf of uniform alpha 0.4 (opaque texture, baseColorFactor alpha 0.4): under it the
    sky gives E / pi = 1 - 0.4 x the square's cosine-weighted solid angle (path rays pass with
    probability 0.6) and the directional light 0.6 W/m^2 (shadow rays weighted by 1 - alpha).

    Deliberate bug this catches (tried): BLEND treated as MASK with the default cutoff (alpha 0.4 <
    0.5: fully cut out) gives E / pi = 1 and 1 W/m^2."""
    path = write_leaf_scene(tmp_path / "blend.glb", "BLEND", base_alpha=0.4, lamp=False,
                            texture_alpha=np.full((8, 8), 255, np.uint8))
    E, _ = irradiance_under_leaf(path, sky=True)
    assert E / math.pi == pytest.approx(1 - 0.4 * square_fraction(LEAF_HALF, LEAF_HEIGHT), abs=0.01)
    E, _ = irradiance_under_leaf(path, sun=True, samples=16)
    assert E == pytest.approx(0.6, abs=1e-6)


# -- the bake against Mitsuba ---------------------------------------------------------------------
def floor_points(n: int) -> tuple[np.ndarray, np.ndarray]:
    """(x, z) of an n x n grid of pixel centres over [-0.5, 0.5]^2 on the floor (row: z, column: x)."""
    s = ((np.arange(n) + 0.5) / n * 2 - 1) * 0.5
    return np.meshgrid(s, s)


def floor_barycentrics(x, z, h=FLOOR_HALF):
    """Triangle and barycentrics on quad()'s floor (or leaf, h = LEAF_HALF): corners (-h, h), (h, h),
    (h, -h), (-h, -h) in (x, z); triangles (0, 1, 2) and (0, 2, 3)."""
    corners = np.array([[-h, h], [h, h], [h, -h], [-h, -h]])
    p = np.stack([np.ravel(x), np.ravel(z)], axis=1)
    tris = np.where(p[:, 0] - p[:, 1] >= 0, 0, 1)  # the diagonal from corner 0 to corner 2: x = z
    bary = np.zeros((len(p), 3))
    for t, (a, b, c) in enumerate(([0, 1, 2], [0, 2, 3])):
        A, B, C = corners[a], corners[b], corners[c]
        m = np.linalg.inv(np.array([B - A, C - A]).T)
        uv = (p - A) @ m.T
        sel = tris == t
        bary[sel] = np.stack([1 - uv[sel, 0] - uv[sel, 1], uv[sel, 0], uv[sel, 1]], axis=1)
    return tris, bary


def mitsuba_floor_irradiance(n: int, spp: int, mask: bool = True) -> np.ndarray:
    """(n, n) irradiance on the floor grid of `floor_points`, from Mitsuba 3 (scalar_rgb) with the leaf
    as a `mask` BSDF whose opacity is the texture's alpha (nearest: the 0/1 texels cut at their
    edges, where glint's bilinear alpha crosses the cutoff 0.5). The scene is built here from the
    numbers above, not through glint. Integrator `volpath`: Mitsuba's `path` treats null (mask)
    surfaces as opaque for its shadow rays (measured: a full square shadow), `volpath` traces
    through them. An orthographic camera between leaf and floor looks down: the floor's radiance
    is kd / pi x E (kd = 0.5). The scene is symmetric under x -> -x, z -> -z and x <-> z, so the
    image's orientation needs no care."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    T = mi.ScalarTransform4f

    def mesh(name, center, u, v, bsdf, uvs=None, emitter=None):
        positions, faces = quad(center, u, v)
        props = mi.Properties()
        props["bsdf"] = bsdf
        if emitter is not None:
            props["emitter"] = emitter
        m = mi.Mesh(name, 4, 2, props=props, has_vertex_texcoords=uvs is not None)
        params = mi.traverse(m)
        params["vertex_positions"] = type(params["vertex_positions"])(positions.astype(np.float32).ravel())
        params["faces"] = type(params["faces"])(faces.astype(np.uint32).ravel())
        if uvs is not None:
            params["vertex_texcoords"] = type(params["vertex_texcoords"])(uvs.astype(np.float32).ravel())
        params.update()
        return m

    def diffuse(rgb):
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(rgb)}}

    opacity = np.ascontiguousarray(ring_alpha()[..., None].astype(np.float32) / 255.0)
    leaf_bsdf = diffuse([0.3, 0.6, 0.2])
    if mask:
        leaf_bsdf = {"type": "mask", "bsdf": leaf_bsdf,
                     "opacity": {"type": "bitmap", "bitmap": mi.Bitmap(opacity), "raw": True,
                                 "filter_type": "nearest", "wrap_mode": "repeat"}}
    half = 0.5
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "volpath", "max_depth": -1},
        "floor": mesh("floor", (0, 0, 0), (FLOOR_HALF, 0, 0), (0, 0, -FLOOR_HALF), mi.load_dict(diffuse([0.5] * 3))),
        "leaf": mesh("leaf", (0, LEAF_HEIGHT, 0), (LEAF_HALF, 0, 0), (0, 0, -LEAF_HALF), mi.load_dict(leaf_bsdf),
                     uvs=LEAF_UV),
        "lamp": mesh("lamp", (0, LAMP_HEIGHT, 0), (LAMP_HALF, 0, 0), (0, 0, LAMP_HALF), mi.load_dict(diffuse([0] * 3)),
                     emitter=mi.load_dict({"type": "area", "radiance": {"type": "rgb", "value": [LAMP_RADIANCE] * 3}})),
        "sensor": {"type": "orthographic",
                   "to_world": T().look_at(origin=[0, 0.25, 0], target=[0, 0, 0], up=[0, 0, -1])
                   @ T().scale([half, half, 1]),
                   "film": {"type": "hdrfilm", "width": n, "height": n, "rfilter": {"type": "box"},
                            "pixel_format": "rgb"},
                   "sampler": {"type": "independent", "sample_count": spp}},
    })
    return np.pi * np.array(mi.render(scene, spp=spp))[..., 0] / 0.5


BAKE_SETTINGS = {"quality": "preview", "samples": 256, "texels_per_metre": 64.0, "denoise": False}
GRID = 40


def baked_floor_irradiance(path: Path, bake_dir: Path) -> np.ndarray:
    scene = load_scene(path)
    bake_scene(scene, resolve_settings(scene.bake_settings, **BAKE_SETTINGS), bake_dir, progress=False)
    bake = Bake(bake_dir)
    tris, bary = floor_barycentrics(*floor_points(GRID))
    floor = [o["name"] for o in bake.manifest["objects"]].index("Floor")
    return bake.irradiance(floor, tris, bary)[:, 0].reshape(GRID, GRID)


def test_texels_in_cut_outs_are_left_to_dilation(tmp_path):
    """The leaf's light map: texels in the ring's hole and outside it are not path traced (A = 0,
    filled by dilation), those on the ring are (A = 1).

    Deliberate bug this catches (tried): no cut-out test in bake/lightmap.py (`_cut_out` returning
    all False): the hole's texels are traced, A = 1 there."""
    path = write_leaf_scene(tmp_path / "leaf.glb")
    scene = load_scene(path)
    settings = resolve_settings(scene.bake_settings, quality="draft", samples=4, texels_per_metre=64.0,
                                denoise=False)
    bake_scene(scene, settings, tmp_path / "leaf.bake", progress=False)
    bake = Bake(tmp_path / "leaf.bake")
    leaf = [o["name"] for o in bake.manifest["objects"]].index("Leaf")
    r = np.array([0.0, 0.52, 0.95]) * LEAF_HALF  # the hole, the ring, outside the ring
    tris, bary = floor_barycentrics(r / math.sqrt(2), r / math.sqrt(2), LEAF_HALF)
    mesh = bake.meshes[leaf]
    corners = mesh["indices"][tris].astype(np.int64)
    uv = np.einsum("kj,kjc->kc", bary, mesh["lm_uv"][corners])
    from glint.core.image_io import sample_bilinear

    baked = sample_bilinear(bake.lightmap(int(mesh["lm_page"][corners[0, 0]]))[..., 3:4], uv)[:, 0]
    np.testing.assert_array_equal(baked, [0.0, 1.0, 0.0])
    assert bake.manifest["materials"][1]["alpha_mode"] == "MASK"


@pytest.mark.slow
def test_cut_out_shadow_matches_mitsuba(tmp_path):
    """The floor's baked irradiance under the ring-shaped leaf against Mitsuba 3 (mask BSDF), on a
    40 x 40 grid over the shadowed square: relative MAE sum|a - b| / sum(b) at most 6 %, signed
    bias within 3 %, and the lit centre of the ring (r < 5 cm) within 5 % of Mitsuba's.

    Deliberate bug this catches (tried): the bake ignoring alpha (`Coverage.any` forced False in
    bake/alpha.py) casts a full square shadow: relative MAE 51 %, bias -51 %, the centre 0 instead
    of 1.0 W/m^2. The cutoff test the wrong way round (alpha >= cutoff passes) inverts the ring:
    relative MAE 81 %. Measured as it stands: MAE 0.5 %, bias -0.03 %."""
    ours = baked_floor_irradiance(write_leaf_scene(tmp_path / "leaf.glb"), tmp_path / "leaf.bake")
    reference = mitsuba_floor_irradiance(GRID, spp=1024)
    x, z = floor_points(GRID)
    centre = np.hypot(x, z) < 0.05
    assert reference[centre].mean() > 0.9  # the ring's hole is lit (the reference's own sanity)
    mae = np.abs(ours - reference).sum() / reference.sum()
    bias = (ours - reference).sum() / reference.sum()
    print(f"relative MAE {mae:.4f}, bias {bias:+.4f}, centre {ours[centre].mean():.3f} "
          f"vs {reference[centre].mean():.3f}")
    assert mae <= 0.06
    assert abs(bias) <= 0.03
    assert ours[centre].mean() == pytest.approx(reference[centre].mean(), rel=0.05)


# -- the raster passes ----------------------------------------------------------------------------
CAPTURE_EYE, CAPTURE_FOV = (0.0, 1.0, 1.5), 30.0


def write_wall_scene(path: Path, mode: str | None, base_alpha: float = 1.0,
                     texture_alpha: np.ndarray | None = None) -> Path:
    """A red wall 1 m behind the leaf (facing the camera, centred at (0, 1, 0)), lit by a constant sky."""
    w = GltfWriter()
    wall = w.add_material("Wall", base_color=(0.8, 0.05, 0.05), roughness=1.0)
    leaf = w.add_material("Leaf", base_color=(0.1, 0.8, 0.1, base_alpha), roughness=1.0,
                          base_color_texture=green_texture(texture_alpha, 200), alpha_mode=mode)
    p, i = quad((0, 1, -1), (1, 0, 0), (0, 1, 0))
    w.add_node("Wall", mesh=w.add_mesh("Wall", p, i, wall, normals=np.tile([0, 0, 1], (4, 1))))
    p, i = quad((0, 1, 0), (LEAF_HALF, 0, 0), (0, LEAF_HALF, 0))
    w.add_node("Leaf", mesh=w.add_mesh("Leaf", p, i, leaf, normals=np.tile([0, 0, 1], (4, 1)), uvs=LEAF_UV))
    path = Path(path)
    w.write(path)
    path.with_name(path.stem + ".glint.toml").write_text("[sky]\nradiance = 1.0\n")
    return path


def capture(path: Path, out: Path, size: int = 64, supersample: int = 1) -> np.ndarray:
    from glint.cli import main
    from glint.core.image_io import read_image

    eye = ",".join(map(str, CAPTURE_EYE))
    assert main(["capture", str(path), "-o", str(out), "--size", f"{size}x{size}", "--supersample",
                 str(supersample), "--eye", eye, "--target", "0,1,0", "--fov", str(CAPTURE_FOV),
                 "-q", "draft", "--samples", "64", "--texels-per-metre", "16", "--no-denoise",
                 "--bake-dir", str(out.with_suffix(".bake"))]) == 0
    return read_image(out)[..., :3]


def pixel(x: float, y: float, size: int = 64) -> tuple[int, int]:
    """(row, column) of the world point (x, y, 0) in the capture (pinhole, square image)."""
    t = math.tan(math.radians(CAPTURE_FOV) / 2) * CAPTURE_EYE[2]
    return int((1 - (y - 1) / t) / 2 * size), int((1 + x / t) / 2 * size)


def test_capture_shows_the_wall_through_the_holes(tmp_path):
    """G-buffer discard: through the ring's hole and outside the ring (inside the leaf's square) the
    capture shows the red wall, on the ring the green leaf.

    Deliberate bug this catches (tried): the fragment shader not discarding (`coverage_discards`
    in shaders/raster_surface.glsl returning false): the hole and the corners show the leaf, green."""
    image = capture(write_wall_scene(tmp_path / "mask.glb", "MASK"), tmp_path / "mask.exr")
    h = LEAF_HALF
    for x, y, what in ((0.0, 1.0, "wall"), (0.52 * h, 1.0, "leaf"), (-0.52 * h, 1.0, "leaf"),
                       (0.0, 1 - 0.52 * h, "leaf"), (0.9 * h, 1 + 0.9 * h, "wall"), (-0.9 * h, 1 - 0.9 * h, "wall")):
        r, g, _ = image[pixel(x, y)]
        assert (r > 2 * g) if what == "wall" else (g > 2 * r), (x, y, what, r, g)


def test_blend_coverage_is_resolved_by_supersampling(tmp_path):
    """BLEND of alpha 0.5 (uniform): with 4 x 4 supersampling every output pixel keeps exactly half
    of its samples (the 4 x 4 ordered dither), so inside the leaf the capture is the mean of the
    opaque leaf's capture and the wall's (a MASK leaf of alpha 0: all cut out), up to the bakes'
    noise (the wall's light map differs by the leaf's shadow, linear in its coverage).

    Deliberate bug this catches (tried): BLEND drawn opaque (no MAT_ALPHA_BLEND flag in
    viewer/gpu_materials.py) gives the opaque leaf, 2x off the mean."""
    solid = np.full((8, 8), 255, np.uint8)
    opaque = capture(write_wall_scene(tmp_path / "opaque.glb", None, texture_alpha=solid), tmp_path / "o.exr",
                     supersample=4)
    gone = capture(write_wall_scene(tmp_path / "gone.glb", "MASK", 0.0, texture_alpha=solid), tmp_path / "g.exr",
                   supersample=4)
    blend = capture(write_wall_scene(tmp_path / "blend.glb", "BLEND", 0.5, texture_alpha=solid),
                    tmp_path / "b.exr", supersample=4)
    r0, c0 = pixel(-0.8 * LEAF_HALF, 1 + 0.8 * LEAF_HALF)
    r1, c1 = pixel(0.8 * LEAF_HALF, 1 - 0.8 * LEAF_HALF)
    inside = (slice(r0, r1 + 1), slice(c0, c1 + 1))
    assert gone[inside][..., 0].mean() > 2 * opaque[inside][..., 0].mean()  # the two differ
    np.testing.assert_allclose(blend[inside].mean(axis=(0, 1)),
                               0.5 * (opaque[inside] + gone[inside]).mean(axis=(0, 1)), rtol=0.05)
    per_pixel = np.abs(blend[inside] - 0.5 * (opaque[inside] + gone[inside])).max()
    assert per_pixel < 0.15 * (opaque[inside] + gone[inside]).max()  # no dither pattern left
