"""Glossy end to end: glint's walkthrough and converged captures against Mitsuba 3 rendering the same
scene (bench/mitsuba_scene.py with the section 3.3 BSDF plugin, bench/mitsuba_bsdf.py).

The scene (`write_scene`): a glossy ball (curved role: cube-map look-ups, section 4.4) on a glossy
floor (planar role: mirror-buffer look-ups, section 4.5), both of one material, under a constant
sky, with an emissive panel behind the ball. Materials with r0 < 1 as glTF gives them: a dielectric
(metallic 0, base 0.4: kd 0.4 and a lobe of r0 0.04) and a coloured metal (metallic 1, base
COPPER: ks = COPPER, kd 0), each at Beckmann m 0.05 and 0.2 (roughness sqrt(m)).

Metrics, on linear radiance, per region -- the ball's and the floor's pixels, found by casting 4
rays per pixel through the scene's own triangles (test_capture_vs_mitsuba.object_ids) and eroded
by one pixel:
- signed bias sum(glint - Mitsuba) / sum(Mitsuba);
- relative MAE of the 4 x 4-pixel block means (whole blocks inside the region): the reference's
  per-pixel noise at its few samples averages out in a block.
The bounds and the figures measured, with the deliberate bugs each test catches, are in the
tests' docstrings.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_capture_vs_mitsuba import object_ids

from glint.bake.material_mapping import GltfPbr, map_pbr
from glint.bake.gltf_loader import load_scene
from glint.scenes.gltf_writer import GltfWriter, quad

SIZE = 64
EYE, TARGET, FOV = (0.0, 1.1, 1.6), (0.0, 0.25, 0.0), 50.0
SKY = 0.5                  # constant sky radiance
PANEL = 6.0                # the emissive panel's radiance
COPPER = (0.95, 0.64, 0.54)
BALL_CENTRE, BALL_RADIUS = (0.0, 0.5, 0.0), 0.3
FLOOR_EMISSION = (0.3, 0.25, 0.2)   # the floor as an emitter (under a glossy ball)
BALL_EMISSION = (0.5, 0.8, 1.6)     # the ball as an emitter (over a glossy floor)
BLOCK = 4


def write_scene(path: Path, kind: str, m: float, glossy: str) -> Path:
    """A ball floating over a floor, the panel behind them, the constant sky. The `glossy` object
    ("Ball" or "Floor") has the material `kind` ("dielectric" or "metal") at Beckmann m; the other
    one is an emitter without diffuse reflection (kd 0): what the glossy one reflects is the sky
    and emitters only, so no light that reaches a surface via a glossy one (the bake's transport
    ends at lobes) enters the comparison."""
    import trimesh

    w = GltfWriter()
    metal = kind == "metal"
    material = w.add_material("Glossy", base_color=COPPER if metal else (0.4, 0.4, 0.4),
                              metallic=1.0 if metal else 0.0, roughness=float(np.sqrt(m)))
    emitters = {name: w.add_material(name, base_color=(0, 0, 0), emissive=colour, emissive_strength=1.0)
                for name, colour in (("Panel", (PANEL,) * 3), ("Floor", FLOOR_EMISSION), ("Ball", BALL_EMISSION))}
    p, i = quad((0, 0, 0), (1.5, 0, 0), (0, 0, -1.5))
    floor = material if glossy == "Floor" else emitters["Floor"]
    ball = material if glossy == "Ball" else emitters["Ball"]
    w.add_node("Floor", mesh=w.add_mesh("Floor", p, i, floor, normals=np.tile([0, 1, 0], (4, 1))))
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=BALL_RADIUS)
    w.add_node("Ball", mesh=w.add_mesh("Ball", sphere.vertices + BALL_CENTRE, sphere.faces, ball,
                                       normals=sphere.vertex_normals))
    w.add_quads({"Panel": ((0.0, 0.7, -1.2), (0.6, 0, 0), (0, 0.3, 0), emitters["Panel"])}, normals=True)
    path = Path(path)
    w.write(path)
    path.with_name(path.stem + ".glint.toml").write_text(f"[sky]\nradiance = {SKY}\n")
    return path


def capture(path: Path, converge: int = 0) -> np.ndarray:
    """`glint capture` of the scene (supersample 2), the walkthrough or `converge` still frames."""
    from glint.cli import main
    from glint.core.image_io import read_image

    out = path.with_name(f"{path.stem}-{converge}.exr")
    extra = ["--converge", str(converge)] if converge else []
    assert main(["capture", str(path), "-o", str(out), "--size", f"{SIZE}x{SIZE}", "--eye", ",".join(map(str, EYE)),
                 "--target", ",".join(map(str, TARGET)), "--fov", str(FOV), "--supersample", "2", "-q", "draft",
                 "--samples", "64", "--texels-per-metre", "8", "--bake-dir", str(path.with_suffix(".bake")),
                 *extra]) == 0
    return read_image(out)[..., :3].astype(np.float64)


def camera():
    from glint.core.scene import Camera

    eye = np.array(EYE)
    forward = np.array(TARGET) - eye
    forward /= np.linalg.norm(forward)
    up = np.array([0.0, 1.0, 0.0]) - forward[1] * forward
    return Camera("c", eye, forward, up / np.linalg.norm(up), np.radians(FOV))


def mitsuba_image(path: Path, spp: int) -> np.ndarray:
    import mitsuba as mi

    from glint.bench.mitsuba import choose_variant
    from glint.bench.mitsuba_scene import convert, render, sensor_dict

    choose_variant("auto")
    scene_dict, _ = convert(load_scene(path), [sensor_dict(camera(), SIZE, SIZE, spp=spp)])
    return render(mi.load_dict(scene_dict), spp=spp).astype(np.float64)


def regions(path: Path) -> dict[str, np.ndarray]:
    """Boolean masks of the ball's and the floor's pixels (eroded by one pixel)."""
    from scipy import ndimage

    scene = load_scene(path)
    ids = object_ids(scene, camera(), SIZE, sub=2)
    names = [o.name for o in scene.objects]
    return {name: ndimage.binary_erosion(ids == names.index(name)) for name in ("Ball", "Floor")}


def figures(image: np.ndarray, reference: np.ndarray, mask: np.ndarray) -> tuple[float, float]:
    """(signed bias, relative MAE of the BLOCK x BLOCK block means wholly inside `mask`)."""
    bias = float((image[mask] - reference[mask]).sum() / reference[mask].sum())
    n = SIZE // BLOCK

    def blocks(a):
        return a.reshape(n, BLOCK, n, BLOCK, -1).mean(axis=(1, 3))

    inside = mask.reshape(n, BLOCK, n, BLOCK).all(axis=(1, 3))
    a, b = blocks(image)[inside], blocks(reference)[inside]
    return bias, float(np.abs(a - b).sum() / b.sum())


def pattern_excess(kind: str, m: float, glossy: str, inside: np.ndarray) -> np.ndarray:
    """Per pixel, what the walkthrough's estimator gives for uniform light over what the lobe
    integral is: the Eq. 4.25 estimate of the lobe's regular pattern (viewer/lobe_patterns.py, the
    numpy twin of the shader's patterns) for L = 1, over the lobe's directional albedo (4096
    importance samples of core/bsdf.py, Eq. 4.4), at the pixel's view angle (its centre ray against
    the floor's plane or the ball's sphere), over the pixels `inside`. It is above 1 towards grazing views: the normalised
    estimator does not lose the part of the lobe that the horizon cuts off (for m 0.2: 1.03 at
    normal view, 1.12 at 60 degrees, 1.5 at 80). 1 outside the `glossy` object, and for the
    dielectric, whose image is mostly diffuse light. The walkthrough is compared with Mitsuba's
    image times this: the estimator as the thesis defines it."""
    from glint.core import bsdf
    from glint.viewer import lobe_patterns as lp

    excess = np.ones((SIZE, SIZE))
    if kind != "metal":
        return excess
    cam = camera()
    eye, forward, up = (np.asarray(a, np.float64) for a in (cam.eye, cam.forward, cam.up))
    s = (np.arange(SIZE) + 0.5) / SIZE * 2 - 1
    x, y = np.meshgrid(s, -s)
    t = np.tan(cam.yfov / 2)
    d = forward + x[..., None] * t * np.cross(forward, up) + y[..., None] * t * up
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    if glossy == "Floor":
        cos_o = -d[..., 1]
    else:
        oc = eye - np.array(BALL_CENTRE)
        b = d @ oc
        hit = eye + (-b - np.sqrt(np.maximum(b * b - (oc @ oc - BALL_RADIUS ** 2), 0.0)))[..., None] * d
        cos_o = -np.sum((hit - BALL_CENTRE) / BALL_RADIUS * d, axis=-1)
    c = np.clip(cos_o[inside], 1e-3, 1.0)
    wo = np.stack([np.sqrt(1 - c * c), np.zeros_like(c), c], axis=-1)
    planar = glossy == "Floor"
    # the metal's lobes as the loader maps them (bake/material_mapping.py: fitted, Kurt's alpha ~ 1/2;
    # from roughness 0.2 two, GGX's tail the second): the estimates and the albedos summed, ks-weighted
    pattern_sum = albedo_sum = 0.0
    for lobe in map_pbr(GltfPbr(base_color=COPPER, metallic=1.0, roughness=float(np.sqrt(m))))[1]:
        ks, lm, r0, alpha = float(np.mean(lobe.ks)), lobe.mx, lobe.r0, lobe.alpha
        xi = lp.pattern_xi(lp.choose_pattern(lm, lm, planar), lp.samples_for_lobe(lm, lm, planar))
        _, f, pdf, cos_i = lp.pattern_samples(wo, xi, lm, lm, r0, alpha, "reflect")
        pattern_sum = pattern_sum + ks * lp.pattern_estimate(np.ones(f.shape + (1,)), f, pdf, cos_i)[..., 0]
        u = np.random.default_rng(0).random((4096, 2))
        wi = bsdf.sample_lobe(wo[:, None], u[:, 0], u[:, 1], lm, lm, "reflect")
        f = bsdf.lobe_value(wi, wo[:, None], lm, lm, r0, alpha, "reflect")
        pdf = bsdf.lobe_pdf(wi, wo[:, None], lm, lm, "reflect")
        ok = (wi[..., 2] > 0) & (pdf > 0)
        albedo_sum = albedo_sum + ks * np.where(ok, f * np.maximum(wi[..., 2], 0.0) / np.where(ok, pdf, 1.0),
                                                0.0).mean(axis=-1)
    excess[inside] = pattern_sum / albedo_sum
    return excess


def compare(tmp_path, kind: str, m: float, glossy: str) -> dict[str, tuple[float, float]]:
    """(bias, block MAE) of the glossy object's region: the converged capture (32 still frames)
    against Mitsuba (64 spp), the walkthrough against Mitsuba times `pattern_excess`."""
    path = write_scene(tmp_path / "scene.glb", kind, m, glossy)
    reference = mitsuba_image(path, spp=64)
    walkthrough, still = capture(path), capture(path, converge=32)
    assert np.isfinite(walkthrough).all() and np.isfinite(still).all()
    mask = regions(path)[glossy]
    assert mask.sum() >= 300
    out = {"still": figures(still, reference, mask),
           "walkthrough": figures(walkthrough, reference * pattern_excess(kind, m, glossy, mask)[..., None], mask)}
    for name, (bias, mae) in out.items():
        print(f"{kind} m {m} {glossy} {name}: bias {bias:+.4f}, block MAE {mae:.4f}")
    return out


CASES = [("dielectric", 0.05), ("dielectric", 0.2), ("metal", 0.05), ("metal", 0.2)]


@pytest.mark.slow
@pytest.mark.parametrize("kind,m", CASES)
def test_glossy_ball_matches_mitsuba(tmp_path, kind, m):
    """The ball (cube map): |bias| at most 2 % in both modes, block MAE at most 5 % (the
    dielectric's light-mapped diffuse part carries the draft bake's noise).

    Measured (bias / MAE, still; walkthrough against Mitsuba x pattern_excess), in %, with the lobes
    fitted to the glTF BRDF (issue 24: Kurt's alpha ~ 1/2; before, alpha = 0, the metal 0.2 ball read
    +0.80 / 0.65 and +0.74 / 2.2):
    dielectric 0.05: +0.15 / 3.3; +0.16 / 3.3.   dielectric 0.2: -0.77 / 1.9; -0.39 / 1.9.
    metal 0.05: +0.28 / 0.39; +0.21 / 0.42.        metal 0.2: +1.48 / 0.82; +1.79 / 2.1.
    Deliberate bugs this catches (tried):
    - no Fresnel term (schlick_F = 1 in shaders/bsdf.glsl): the dielectric's bias +161 % (0.05)
      and +151 .. +159 % (0.2), both modes;
    - Eq. 4.25's weight without its cosine (w = f in lobe_sampling.glsl add_pattern_sample):
      metal 0.2 walkthrough bias -2.8 % (its raw excess over Mitsuba falls from 5.8 % to 2.1 %
      while pattern_excess predicts 5.0 %)."""
    out = compare(tmp_path, kind, m, "Ball")
    for name, (bias, mae) in out.items():
        assert abs(bias) <= 0.02, (name, bias)
        assert mae <= 0.05, (name, mae)


# Per case: (|bias| bound, block MAE bound) of the still camera and of the walkthrough.
FLOOR_BOUNDS = {("dielectric", 0.05): ((0.04, 0.05), (0.04, 0.06)),
                ("dielectric", 0.2): ((0.04, 0.05), (0.04, 0.06)),
                ("metal", 0.05): ((0.04, 0.06), (0.07, 0.10)),
                ("metal", 0.2): ((0.04, 0.20), (0.20, 0.30))}


@pytest.mark.slow
@pytest.mark.parametrize("kind,m", CASES)
def test_glossy_floor_matches_mitsuba(tmp_path, kind, m):
    """The floor (mirror buffer): the bounds of FLOOR_BOUNDS. Measured (bias / MAE), in %:
    still: dielectric 0.05 +0.19 / 2.6, dielectric 0.2 +0.16 / 2.9, metal 0.05 -1.3 / 3.2,
    metal 0.2 +1.3 / 13.5 (the reference's noise: a rough metal reflecting a small bright panel at
    64 spp); walkthrough against Mitsuba x pattern_excess: dielectric +0.6 / 2.8 and +1.0 / 2.7,
    metal 0.05 +2.4 / 6.7 (+6.0 / 8.9 with the lobes fitted to the glTF BRDF, issue 24: Kurt's
    alpha ~ 1/2, whose f cos / p grows towards the horizon, docs/SCENES.md "glTF materials: how
    close"), metal 0.2 +13.2 / 20 (+11.4 / 18.7 fitted; the planar patterns' excess beyond
    pattern_excess: their 10 samples of a wide lobe read the panel and the ball at separate,
    finely filtered look-ups, ghosts that the bounds of this case allow; docs/BENCHMARKS.md).
    Deliberate bugs this catches (tried):
    - mirror-buffer radiance x 0.92 (mirror_buffer.glsl mirror_radiance_at): the metal floor's
      still bias -9.2 % (m 0.05) and -6.8 % (m 0.2), past the 4 % bound;
    - no Fresnel term: the dielectric's bias +165 .. +204 %."""
    (still_bias, still_mae), (walk_bias, walk_mae) = FLOOR_BOUNDS[(kind, m)]
    out = compare(tmp_path, kind, m, "Floor")
    bias, mae = out["still"]
    assert abs(bias) <= still_bias and mae <= still_mae, out
    bias, mae = out["walkthrough"]
    assert abs(bias) <= walk_bias and mae <= walk_mae, out
