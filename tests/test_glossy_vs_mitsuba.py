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

Mitsuba's images (64 spp, ~15-50 s each here) are cached: tests/data/mitsuba/glossy_*.npz, the
same renders saved with a key of their inputs and code (tests/mitsuba_cache.py); a test whose key
does not match renders with Mitsuba as before and warns. Refresh: tests/data/README.md.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_capture_vs_mitsuba import object_ids

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


def mitsuba_image(path: Path, spp: int, cache: str) -> np.ndarray:
    """Mitsuba 3's image of the scene at `path` (bench/mitsuba_scene.py, the fastest variant that
    works here, `spp` samples per pixel), read from tests/data/mitsuba/`cache`.npz when its key
    matches the scene, sensor, variant and code (tests/mitsuba_cache.py), else rendered."""
    import mitsuba as mi
    import mitsuba_cache

    from glint.bench.mitsuba_scene import convert, render, sensor_dict

    variant = mitsuba_cache.auto_variant()
    mi.set_variant(variant)
    scene, sensor = load_scene(path), sensor_dict(camera(), SIZE, SIZE, spp=spp)

    def live():
        scene_dict, _ = convert(scene, [sensor])
        return render(mi.load_dict(scene_dict), spp=spp)

    return mitsuba_cache.reference(cache, live, variant=variant, code=[mitsuba_image], scene=scene, sensor=sensor,
                                   spp=spp).astype(np.float64)


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


def compare(tmp_path, kind: str, m: float, glossy: str) -> dict[str, tuple[float, float]]:
    """(bias, block MAE) of the glossy object's region: the converged capture (32 still frames) and the
    walkthrough against Mitsuba (64 spp). The walkthrough's estimate reads the lobe's albedo under
    uniform light (viewer/lobe_albedo.py), so it is compared with Mitsuba as it is; with the thesis'
    Eq. 4.25 it was compared with Mitsuba times that estimator's excess over the albedo, which grows
    towards grazing views (x1.12 at 60 degrees, x1.5 at 80 for a metal lobe of m 0.2)."""
    path = write_scene(tmp_path / "scene.glb", kind, m, glossy)
    reference = mitsuba_image(path, spp=64, cache=f"glossy_{glossy.lower()}_{kind}_{m}")
    walkthrough, still = capture(path), capture(path, converge=32)
    assert np.isfinite(walkthrough).all() and np.isfinite(still).all()
    mask = regions(path)[glossy]
    assert mask.sum() >= 300
    out = {"still": figures(still, reference, mask),
           "walkthrough": figures(walkthrough, reference, mask)}
    for name, (bias, mae) in out.items():
        print(f"{kind} m {m} {glossy} {name}: bias {bias:+.4f}, block MAE {mae:.4f}")
    return out


CASES = [("dielectric", 0.05), ("dielectric", 0.2), ("metal", 0.05), ("metal", 0.2)]


@pytest.mark.slow
@pytest.mark.parametrize("kind,m", CASES)
def test_glossy_ball_matches_mitsuba(tmp_path, kind, m):
    """The ball (cube map): |bias| at most 2 % in both modes (3.5 % for the walkthrough of the metal
    of m 0.2), block MAE at most 5 % (the dielectric's light-mapped diffuse part carries the draft
    bake's noise).

    Measured (bias / MAE, still; walkthrough against Mitsuba), in %, with the lobes fitted to the glTF
    BRDF (issue 24: Kurt's alpha ~ 1/2; before, alpha = 0, the metal 0.2 ball read +0.80 / 0.65 and
    +0.74 / 2.2):
    dielectric 0.05: +0.15 / 3.3; -0.49 / 3.3.   dielectric 0.2: -0.77 / 1.9; +0.10 / 2.0.
    metal 0.05: +0.28 / 0.39; +0.25 / 0.43.        metal 0.2: +1.48 / 0.82; +1.87 / 2.1.
    With three lobes per rough metal row (fitted to Eq. 3.7; the copper of m 0.2, roughness 0.45, is
    six lobes, the widest m 0.93): metal 0.2 +1.27 / 1.4; +2.72 / 4.8 (the ring's seven samples of
    that widest lobe; Eq. 4.25 there: +18.5 / 15.1); the other cases within 0.5 of the above.
    (The walkthrough with the thesis' Eq. 4.25, before the albedo normalisation: -0.50 / 3.3,
    +0.70 / 2.0, +0.37 / 0.45, +3.66 / 2.5 against Mitsuba as it is.)
    Deliberate bugs this catches (tried):
    - no Fresnel term (schlick_F = 1 in shaders/bsdf.glsl): the dielectric's bias +161 % (0.05)
      and +151 .. +159 % (0.2), both modes;
    - the walkthrough's Eq. 4.25 normalisation (Renderer weights="eq4.25"), which leans towards the
      samples of large f cos / p: metal 0.2 walkthrough bias +3.66 %.
    The reference is cached in tests/data/mitsuba/glossy_ball_KIND_M.npz (module docstring)."""
    out = compare(tmp_path, kind, m, "Ball")
    for name, (bias, mae) in out.items():
        assert abs(bias) <= (0.035 if (kind, m, name) == ("metal", 0.2, "walkthrough") else 0.02), (name, bias)
        assert mae <= 0.05, (name, mae)


# Per case: (|bias| bound, block MAE bound) of the still camera and of the walkthrough.
FLOOR_BOUNDS = {("dielectric", 0.05): ((0.04, 0.05), (0.04, 0.06)),
                ("dielectric", 0.2): ((0.04, 0.05), (0.04, 0.06)),
                ("metal", 0.05): ((0.04, 0.06), (0.09, 0.12)),
                ("metal", 0.2): ((0.04, 0.20), (0.14, 0.22))}


@pytest.mark.slow
@pytest.mark.parametrize("kind,m", CASES)
def test_glossy_floor_matches_mitsuba(tmp_path, kind, m):
    """The floor (mirror buffer): the bounds of FLOOR_BOUNDS. Measured (bias / MAE), in %:
    still: dielectric 0.05 +0.19 / 2.6, dielectric 0.2 +0.16 / 2.9, metal 0.05 -1.3 / 3.2,
    metal 0.2 +1.3 / 13.5 (the reference's noise: a rough metal reflecting a small bright panel at
    64 spp); walkthrough against Mitsuba: dielectric +1.56 / 3.3 and +2.39 / 3.9, metal 0.05
    +6.04 / 9.0, metal 0.2 +11.6 / 18.8. Before the albedo normalisation (Eq. 4.25, compared with
    Mitsuba times that estimator's excess under uniform light): +1.41 / 3.0, +1.64 / 3.3,
    +5.97 / 8.9, +11.4 / 18.7; against Mitsuba as it is +1.41 / 3.0, +1.64 / 3.3, +6.18 / 9.0,
    +14.4 / 20.2. So the metal 0.05 floor's +6 % is not the normalisation (its lobe is narrow: the
    excess was 1 % there) but the planar look-ups' (docs/SCENES.md "glTF materials: how close"); its
    bound stays. With three lobes per rough metal row (this metal, roughness 0.22, is m 0.035, 0.071
    and 0.179) its walkthrough reads +8.15 / 10.7 (Eq. 4.25: +8.72 / 11.1), the bound 9 / 12 %;
    the rough metal of issue 24's room, against the glTF BRDF, went from 21 % to 4.8 % block MAE
    (docs/BENCHMARKS.md, "Issue 24: three lobes fitted to Eq. 3.7"). Still: -0.19 / 3.4; metal 0.2
    -2.3 / 8.1 still, +10.3 / 12.7 walkthrough (25 samples for its lobes of m >= 0.2). Metal 0.2: the planar patterns' excess: their 10 samples of a wide lobe read the
    panel and the ball at separate, finely filtered look-ups, ghosts that the bounds of this case
    allow (docs/BENCHMARKS.md); its walkthrough bias bound is now 14 % (was 20 %), which Eq. 4.25
    (+14.4 %) fails.
    Deliberate bugs this catches (tried):
    - mirror-buffer radiance x 0.92 (mirror_buffer.glsl mirror_radiance_at): the metal floor's
      still bias -9.2 % (m 0.05) and -6.8 % (m 0.2), past the 4 % bound;
    - no Fresnel term: the dielectric's bias +165 .. +204 %.
    The reference is cached in tests/data/mitsuba/glossy_floor_KIND_M.npz (module docstring)."""
    (still_bias, still_mae), (walk_bias, walk_mae) = FLOOR_BOUNDS[(kind, m)]
    out = compare(tmp_path, kind, m, "Floor")
    bias, mae = out["still"]
    assert abs(bias) <= still_bias and mae <= still_mae, out
    bias, mae = out["walkthrough"]
    assert abs(bias) <= walk_bias and mae <= walk_mae, out
