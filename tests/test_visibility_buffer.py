"""The G-buffer through a visibility buffer (viewer/passes/gbuffer.py `visibility`, issue 27) against the
G-buffer the raster pass writes, target by target, on a scene that uses what the surface code reads:
textures minified at grazing angles (their MIP level comes from the derivatives the resolve works out),
a normal map with its tangent frame, MASK cut-outs, a clamped NEAREST sampler, vertex colours, the
back faces of a double-sided panel (its back-side light map) and of a single-sided one (dark), five
texture batches. The raster pass is the reference here because it is checked against Mitsuba and
analytic results elsewhere (tests/test_normal_map.py, test_alpha.py, test_two_sided.py,
test_texture_coordinates.py, test_draw_list.py) and computes everything the other way: the hardware's
interpolation and derivatives where the resolve re-projects the triangle. The textured tiles of
tests/test_draw_list.py run both ways too, against their analytic radiance.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import FAST

from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.core.bake_dir import Bake
from glint.core.constants import GB_DARK_BIT
from glint.scenes.generate import LAMBERT
from glint.scenes.gltf_writer import GltfWriter, quad
from glint.services import bake_scene
from glint.viewer.camera import ViewCamera
from glint.viewer.gl import GL
from glint.viewer.passes.gbuffer import oct_decode
from glint.viewer.renderer import Renderer

SIZE = (192, 128)


def checker(n: int = 64, cells: int = 8, rgb=((230, 200, 40), (20, 40, 160))) -> np.ndarray:
    """An (n, n, 3) uint8 checkerboard of `cells` x `cells` squares: strong contrast, so a wrong MIP
    level shows."""
    k = (np.arange(n) * cells // n)
    odd = (k[:, None] + k[None, :]) % 2 == 1
    return np.where(odd[..., None], np.array(rgb[1], np.uint8), np.array(rgb[0], np.uint8)).astype(np.uint8)


def bumps(n: int = 32) -> np.ndarray:
    """A normal map of bands tilted +-0.4 along u (tangent space, encoded 0..255)."""
    x = np.where((np.arange(n) // 4) % 2 == 0, 0.4, -0.4)
    nrm = np.stack([np.broadcast_to(x, (n, n)), np.zeros((n, n)), np.ones((n, n))], axis=-1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    return np.round((nrm * 0.5 + 0.5) * 255).astype(np.uint8)


def write_scene(path):
    """An open yard under a constant sky, seen low over its floor: the floor tiled 12 x with a checker;
    a metal wall behind it with a normal map (lobes: a tangent frame, normal-mapped flag); a leaf
    (MASK, alpha 0 outside a disc) in front of it; a quad with a clamped NEAREST checker; a quad
    with vertex colours; a double-sided and a single-sided panel, each turned away from the camera;
    behind the camera a checker backdrop, which the wall's mirror pass shows."""
    w = GltfWriter()
    floor = w.add_material("Floor", base_color=(1, 1, 1), base_color_texture=checker(), extensions=LAMBERT)
    wall = w.add_material("Wall", base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=0.35)
    w.materials[wall]["normalTexture"] = {"index": w.add_texture(bumps())}
    alpha = np.zeros((32, 32, 4), np.uint8)
    yy, xx = np.mgrid[:32, :32]
    alpha[..., 1] = 200
    alpha[..., 3] = np.where((xx - 15.5) ** 2 + (yy - 15.5) ** 2 < 12 ** 2, 255, 0)
    leaf = w.add_material("Leaf", base_color=(1, 1, 1), base_color_texture=alpha, alpha_mode="MASK",
                          extensions=LAMBERT)
    nearest = w.add_material("Nearest", base_color=(1, 1, 1), base_color_texture=checker(8, 4), extensions=LAMBERT,
                             sampler={"magFilter": 9728, "wrapS": 33071, "wrapT": 33071})
    plain = w.add_material("Plain", base_color=(0.8, 0.8, 0.8), extensions=LAMBERT)
    two = w.add_material("Two-sided", base_color=(0.3, 0.7, 0.4), double_sided=True, extensions=LAMBERT)
    one = w.add_material("One-sided", base_color=(0.7, 0.3, 0.4), extensions=LAMBERT)

    p, i = quad((0, 0, -3), (4, 0, 0), (0, 0, -5))
    w.add_node("Floor", mesh=w.add_mesh("Floor", p, i, floor, normals=np.tile((0, 1, 0), (4, 1)),
                                        uvs=(p[:, [0, 2]] + (4.0, 8.0)) * 1.5))
    p, i = quad((0, 1.2, -7.9), (4, 0, 0), (0, 1.2, 0))
    w.add_node("Wall", mesh=w.add_mesh("Wall", p, i, wall, normals=np.tile((0, 0, 1), (4, 1)),
                                       uvs=(p[:, [0, 1]] - (-4.0, 2.4)) * (1.0, -1.0)))
    p, i = quad((-1.2, 0.9, -4), (0.5, 0, 0), (0, 0.5, 0))
    w.add_node("Leaf", mesh=w.add_mesh("Leaf", p, i, leaf, normals=np.tile((0, 0, 1), (4, 1)),
                                       uvs=np.array([[0, 1], [1, 1], [1, 0], [0, 0]], float)))
    p, i = quad((1.3, 0.8, -4.5), (0.4, 0, 0.2), (0, 0.4, 0))
    w.add_node("Nearest", mesh=w.add_mesh("Nearest", p, i, nearest, normals=np.tile((-0.45, 0, 0.9), (4, 1)),
                                          uvs=np.array([[-0.2, 1.2], [1.2, 1.2], [1.2, -0.2], [-0.2, -0.2]], float)))
    p, i = quad((0.2, 0.45, -2.6), (0.3, 0, 0), (0, 0.3, 0))
    colors = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]], float)
    w.add_node("Coloured", mesh=w.add_mesh("Coloured", p, i, plain, normals=np.tile((0, 0, 1), (4, 1)),
                                           colors=colors))
    p, i = quad((0, 1.2, 1.9), (-4, 0, 0), (0, 1.2, 0))  # behind the camera, facing the wall: its mirror's
    w.add_node("Backdrop", mesh=w.add_mesh("Backdrop", p, i, floor, normals=np.tile((0, 0, -1), (4, 1)),
                                           uvs=(p[:, [0, 1]] + (4.0, 0.0)) * 2.0))
    for name, material, x in (("Two-sided", two, -0.5), ("One-sided", one, 0.9)):
        p, i = quad((x, 1.5, -3.5), (0, 0.3, 0), (0.3, 0, 0))  # front face along -z: seen from behind
        w.add_node(name, mesh=w.add_mesh(name, p, i, material, normals=np.tile((0, 0, -1), (4, 1))))
    w.write(path)
    path.with_name(path.stem + ".glint.toml").write_text("[sky]\nradiance = 1.0\n")
    return path


@pytest.fixture(scope="module")
def yard(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("yard")
    scene = load_scene(write_scene(tmp / "yard.glb"))
    bake_scene(scene, resolve_settings(scene.bake_settings, **FAST), tmp / "yard.bake", progress=False)
    return Bake(tmp / "yard.bake")


CAMERA = ViewCamera(eye=(0.0, 0.55, 0.5), forward=(0.0, -0.06, -1.0), yfov=math.radians(55))
ASIDE = ViewCamera(eye=(0.35, 0.4, 0.8), forward=(-0.2, -0.1, -1.0), yfov=math.radians(45))  # the frame before


def gbuffer_of(ctx, bake, visibility: bool) -> dict:
    with Renderer(ctx, bake, visibility=visibility) as r:
        r.render(ASIDE, *SIZE)  # leaves other texels in the mirror layer: each frame must write all of them
        r.render(CAMERA, *SIZE)
        assert r.gbuffer.visibility == visibility
        t = r.gbuffer.targets
        w, h = t["shade"].size
        words = {name: np.frombuffer(t[name].read(alignment=1), np.uint32).reshape(h, w, 4).copy()
                 for name in ("shade", "frame")}
        picks = [r.gbuffer.pick(x, y) for x in range(3, w, 17) for y in range(2, h, 13)]
        assert [p.names for p in r.mirror.plan_.passes] == [["Wall"]]
        mirror = {t: r.mirror.read(0, t) for t in ("radiance", "position", "normal")}
        return {**words, "depth": np.frombuffer(t["depth"].read(alignment=1), np.float32).reshape(h, w).copy(),
                "image": r.read_linear(), "batches": len(r.draws.batches), "picks": picks, "mirror": mirror}


def test_visibility_buffer_resolves_the_raster_gbuffer(ctx, yard):
    """Both ways on the yard (192 x 128), the raster renderer first (so state it leaves behind meets the
    second): the same depth bit for bit and the same ids, flags and picks on every pixel; the shading
    normal and tangent within 2e-4 rad (one step of the octahedral snorm16 encoding is ~1e-4); the
    anisotropy strength and metallic-roughness words within 2/65535; the wall's mirror pass the same
    texels drawn, position within 1e-4 m, normal within 2e-3 (half floats). Diffuse radiance kd/pi E
    x textures, the mirror's radiance and the shaded image: relative difference of a channel |a - b| /
    max(|a|, |b|) at most 1e-2, over 1e-3 on at most 1 % of the pixels. Measured: diffuse at most
    1.96e-3 apart, 0.18 % of the drawn pixels over 1e-3, all on the checker floor far away (its uv
    derivatives are differences of nearly equal numbers; the trilinear filter turns their rounding
    into a slightly other mix of two MIP levels); the image likewise (30 pixels).

    Deliberate bugs this catches (tried): the texture derivatives as each pixel's own forward
    difference instead of its 2 x 2 quad's (a MIP level unlike llvmpipe's): diffuse off by up to
    39 %, 27 % of the pixels over 1e-3 (in the resolve; in the fragment's quad_uv_derivatives, 3.89e-1
    and 27 %); the facing bit ignored (every pixel front-facing): the dark
    flag of the single-sided panel's back lost; dFdy's step taken along x: off by up to 98 %; a
    mirror pass's depth clear left to the depth mask a released renderer left off (moderngl's parked
    framebuffer without a depth buffer): the whole first mirror layer taken as drawn; the mirror layer's
    empty position texels left unwritten (the last frame's stay, ASIDE's): their comparison. The light-map
    page from the first vertex instead of the provoking (last) one changes nothing here (an
    object's vertices share their page), so it is not claimed."""
    raster, vis = gbuffer_of(ctx, yard, False), gbuffer_of(ctx, yard, True)
    assert raster["batches"] >= 5
    drawn = raster["depth"] < 1.0
    assert 0.5 < drawn.mean() < 1.0
    assert np.array_equal(raster["depth"], vis["depth"])
    assert np.array_equal(raster["shade"][..., 3][drawn], vis["shade"][..., 3][drawn])  # material, object
    assert np.array_equal(raster["frame"][..., 2][drawn] >> 16, vis["frame"][..., 2][drawn] >> 16)  # flags (GB_*_BIT)
    assert raster["picks"] == vis["picks"] and len({p for p in raster["picks"] if p}) >= 6  # the window's click
    dark = (raster["frame"][..., 2] & GB_DARK_BIT) != 0
    assert dark[drawn].sum() > 50, "the single-sided panel's back is in view"

    a, b = (g["shade"][..., :3].view(np.float32)[drawn] for g in (raster, vis))
    rel = np.abs(a - b) / np.maximum(np.maximum(np.abs(a), np.abs(b)), 1e-6)
    over = (rel.max(axis=1) > 1e-3).mean()
    print(f"diffuse: largest relative difference {rel.max():.2e}, {100 * over:.2f} % of the drawn pixels over 1e-3")
    assert rel.max() <= 1e-2 and over <= 0.01, f"diffuse differs by up to {rel.max():.2e}, {100 * over:.2f} % over 1e-3"
    for word, what in ((0, "normal"), (1, "tangent")):
        na, nb = (oct_decode(g["frame"][..., word][drawn]) for g in (raster, vis))
        angle = np.arctan2(np.linalg.norm(np.cross(na, nb), axis=1), np.sum(na * nb, axis=1))
        assert angle.max() <= 2e-4, f"{what} differs by up to {angle.max():.2e} rad"
    strength = (raster["frame"][..., 2] & 0xFFFF).astype(np.int64), (vis["frame"][..., 2] & 0xFFFF).astype(np.int64)
    assert np.abs(strength[0] - strength[1])[drawn].max() <= 2
    mr = [np.stack([g["frame"][..., 3] & 0xFFFF, g["frame"][..., 3] >> 16], -1).astype(np.int64) for g in (raster, vis)]
    assert np.abs(mr[0] - mr[1])[drawn].max() <= 2

    ma, mb = raster["mirror"], vis["mirror"]  # the wall's mirror pass
    seen = np.linalg.norm(ma["normal"][..., :3], axis=-1) > 0.5
    assert np.array_equal(seen, np.linalg.norm(mb["normal"][..., :3], axis=-1) > 0.5) and seen.sum() > 200
    rel = (np.abs(ma["radiance"] - mb["radiance"]) / np.maximum(np.maximum(np.abs(ma["radiance"]),
                                                                           np.abs(mb["radiance"])), 1e-6))[seen]
    rel = rel[..., :3].max(axis=-1)
    print(f"mirror radiance: largest relative difference {rel.max():.2e}, {(rel > 1e-3).mean() * 100:.2f} % over 1e-3")
    assert rel.max() <= 1e-2 and (rel > 1e-3).mean() <= 0.01
    assert np.abs(ma["position"] - mb["position"])[seen].max() <= 1e-4
    assert np.abs(ma["normal"] - mb["normal"])[seen].max() <= 2e-3
    for target in ("radiance", "position", "normal"):  # the empty texels: the sky's colour, nothing
        assert np.array_equal(ma[target][~seen], mb[target][~seen]), f"the mirror's empty {target} texels differ"

    ia, ib = raster["image"], vis["image"]
    rel = (np.abs(ia - ib) / np.maximum(np.maximum(np.abs(ia), np.abs(ib)), 1e-6)).max(axis=-1)
    print(f"image: largest relative difference {rel.max():.2e}, {(rel > 1e-3).sum()} pixels over 1e-3")
    assert (rel > 1e-3).mean() <= 0.01, f"{(rel > 1e-3).sum()} pixels differ by more than 1e-3 (up to {rel.max():.2e})"
    assert np.isfinite(ib).all()


def test_scene_with_levels_of_detail_keeps_the_raster_pass(ctx, yard):
    """A renderer that draws at a level of detail (the bake's cube-map renders) keeps the raster
    G-buffer (the resolve finds a pixel's triangle in its object's own index range), even when asked
    for a visibility buffer; and a software renderer (llvmpipe, this test's) does not pick the
    visibility buffer unless asked (docs/VIEWER.md: measured, see its table)."""
    with Renderer(ctx, yard, lod=1.0, visibility=True) as r:
        assert not r.gbuffer.visibility
    with Renderer(ctx, yard) as r:
        assert r.gbuffer.visibility is False


def test_frames_and_releases_leave_no_gl_error(ctx, yard):
    """Renderers made, drawn at two sizes (targets remade), with and without supersampling, walkthrough
    and still-camera frames, and released one after the other, either way, with a mirror pass, leave
    no GL error flag set, nor does a framebuffer made afterwards
    (glGetError after each: an error no check ties to its cause is one that goes unnoticed).

    Deliberate bugs this catches (tried): the mirror layers' framebuffers wrapped by moderngl's
    detect_framebuffer (as before this test): GL_INVALID_OPERATION from its attachment queries; a
    bound framebuffer released without parking moderngl's binding first (viewer/gl.py
    `release_framebuffer`): GL_INVALID_OPERATION at the next framebuffer moderngl makes."""
    gl = GL(ctx)
    gl.errors()
    for visibility, supersample in ((False, 1), (True, 2), (False, 2), (True, 1)):
        with Renderer(ctx, yard, visibility=visibility, supersample=supersample) as r:
            r.render(CAMERA, *SIZE)
            r.render(CAMERA, 96, 64)
            for _ in range(2):  # still-camera frames: the accumulation, the G-buffer kept
                r.render(CAMERA, 96, 64, mode="converge")
            r.read_linear()
            assert gl.errors() == [], (visibility, supersample)
    ctx.framebuffer([ctx.texture((4, 4), 4)]).release()
    assert gl.errors() == []


def grid(n: int, centre_z: float, half: float) -> dict:
    """A mesh dict (bake_dir layout) of an n x n grid of quads (2 n^2 triangles) in the plane z =
    centre_z, +-half in x and y, facing +z; light-map uv across the whole grid."""
    t = np.linspace(-half, half, n + 1)
    x, y = np.meshgrid(t, t)
    positions = np.stack([x, y, np.full_like(x, centre_z)], -1).reshape(-1, 3).astype(np.float32)
    k = np.arange(n)
    a = (k[None, :] + (n + 1) * k[:, None]).reshape(-1)
    quads = np.stack([a, a + 1, a + n + 2, a + n + 1], -1)
    indices = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]).astype(np.uint32)
    lm_uv = ((positions[:, :2] + half) / (2 * half)).astype(np.float32)
    return {"positions": positions, "normals": np.tile((0, 0, 1), (len(positions), 1)).astype(np.float32),
            "uvs": lm_uv.copy(), "lm_uv": lm_uv, "lm_page": np.zeros(len(positions), np.int32),
            "indices": indices, "vmapping": np.arange(len(positions))}


def test_triangle_ids_past_two_to_the_seventeen(ctx, tmp_path):
    """The visibility buffer's one word per pixel holds the triangle's index in the whole scene's index
    buffer (visibility.glsl): here a grid of 80,000 triangles fills the view after a grid of 135,200
    behind the camera (culled), so every pixel's id exceeds 2^17, and the last object (a quad in front)
    comes after all of them. Both ways give the same depth, the same object and material ids on every pixel and the
    same light-mapped image (a gradient light map: a pixel resolved from another triangle reads
    another value) within 1e-3 on 99 % of the pixels.

    Deliberate bug this catches (tried): the triangle index kept in 17 bits (`vis_pack` masking with
    0x1FFFF): every grid pixel resolves a triangle of the culled grid behind the camera (its ids name object 0)."""
    from test_renderer import make_bake, material, quad

    page = np.ones((64, 64, 4), np.float32)
    ramp = np.linspace(0.2, 1.0, 64, dtype=np.float32)
    page[..., 0], page[..., 1] = ramp[None, :], ramp[:, None]
    meshes = [grid(260, 30.0, 1.0), grid(200, 0.0, 3.0), quad((0.8, 0.3, 0.5), (0.3, 0, 0), (0, 0.2, 0))]
    bake = make_bake(tmp_path / "b", meshes, [material("a"), material("grid"), material("front", kd=(0.2, 0.9, 0.2))],
                     [0, 1, 2], [page])
    camera = ViewCamera.look_at((0, 0, 2.5), (0, 0, 0), (0, 1, 0), math.radians(60), znear=0.01, zfar=100)
    out = {}
    for visibility in (False, True):
        with Renderer(ctx, bake, visibility=visibility) as r:
            r.render(camera, *SIZE)
            assert r.draws.record(0)["objects_drawn"] == 2  # the grid behind the camera is culled
            t = r.gbuffer.targets
            w, h = t["shade"].size
            out[visibility] = (np.frombuffer(t["shade"].read(alignment=1), np.uint32).reshape(h, w, 4)[..., 3].copy(),
                               np.frombuffer(t["depth"].read(alignment=1), np.float32).reshape(h, w).copy(),
                               r.read_linear())
    (ids_a, depth_a, image_a), (ids_b, depth_b, image_b) = out[False], out[True]
    assert (depth_a < 1.0).all() and np.array_equal(depth_a, depth_b)
    assert np.array_equal(ids_a, ids_b) and len(np.unique(ids_a)) == 2  # the grid and the front quad
    rel = (np.abs(image_a - image_b) / np.maximum(np.maximum(np.abs(image_a), np.abs(image_b)), 1e-6)).max(axis=-1)
    assert (rel > 1e-3).mean() <= 0.01, f"{(rel > 1e-3).mean():.1%} of the pixels over 1e-3 (up to {rel.max():.2e})"
