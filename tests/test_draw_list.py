"""GPU-driven drawing (viewer/draw_list.py): the culling compute pass against numpy, and a
multi-draw of interleaved textured materials against the analytic radiance of each object."""
from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import FAST

from glint.scenes.generate import LAMBERT  # a Lambertian glTF material: the tests' expected kd is the base colour
from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.core.bake_dir import Bake
from glint.scenes.gltf_writer import GltfWriter
from glint.services import bake_scene
from glint.viewer.camera import ViewCamera, frustum_planes, in_frustum
from glint.viewer.draw_list import COMMAND_BYTES, DRAW_STATES, DrawList
from glint.viewer.gl_bindings import SCENE_OBJECT_BINDING
from glint.viewer.gpu_objects import SCENE_OBJECT_DTYPE, GpuObject
from glint.viewer.renderer import Renderer


class BoxesOnly:
    """What DrawList.cull reads of a GpuScene: objects with materials that bind different
    textures (so the draw order is not the object order) and the object table; no meshes."""

    def __init__(self, ctx, bounds: np.ndarray, triangles: np.ndarray, materials: np.ndarray):
        self.objects = [GpuObject(f"box {k}", int(m), "diffuse", int(t), b, 0, 0) for k, (b, t, m) in
                        enumerate(zip(bounds, triangles, materials))]
        table = np.zeros(len(bounds), SCENE_OBJECT_DTYPE)
        table["lo"][:, :3], table["hi"][:, :3] = bounds[:, 0], bounds[:, 1]
        table["info"][:, 0], table["info"][:, 3] = materials, 3 * triangles
        self.object_buffer = ctx.buffer(table.tobytes())
        self.object_binding = SCENE_OBJECT_BINDING
        self.textures = [ctx.texture((1, 1), 4) for _ in range(4)]
        self.material_count = len(self.textures)

    def material_textures(self, material: int) -> tuple:
        return (self.textures[material],) * 5

    def material_texture_kinds(self, material: int) -> int:
        return 0  # what the textures stand for does not matter to culling


def test_culling_matches_numpy_for_every_object(ctx):
    """5000 random boxes, a camera, a clip plane and a hidden set: every object's state from
    shaders/cull.comp equals the numpy reference (viewer/camera.py in_frustum, the clip plane's
    farthest corner, the hidden set, empty objects), and its draw command draws it exactly when
    it is DRAWN. Boxes within 1e-3 of deciding a plane test are left out of the comparison
    (float32 on the GPU against float64 here).

    Deliberate bugs this catches (tried): the nearest corner instead of the farthest (`step` of
    -plane): 476 of 5000 states differ; the clip plane's sign flipped: 4217 differ; the state
    written at the command's index instead of the object's: 3347 differ."""
    rng = np.random.default_rng(7)
    n = 5000
    lo = rng.uniform(-12, 12, (n, 3))
    bounds = np.stack([lo, lo + rng.uniform(0.01, 2.0, (n, 3))], axis=1)
    triangles = np.where(rng.random(n) < 0.05, 0, rng.integers(1, 50, n))
    scene = BoxesOnly(ctx, bounds, triangles, rng.integers(0, 4, n))
    draws = DrawList(ctx, scene)
    camera = ViewCamera(eye=(1.0, 2.0, 9.0), forward=(-0.2, -0.1, -1.0), yfov=math.radians(50), znear=0.1, zfar=15.0)
    view_proj = camera.view_projection(16 / 9)
    clip = np.array([0.3, 0.9, 0.1, 0.5])
    hidden = set(rng.choice(n, 300, replace=False).tolist())
    draws.cull(view_proj, region=1, hidden=hidden, clip_plane=clip)

    expected = np.full(n, DRAW_STATES["DRAWN"])
    planes = np.vstack([clip / np.linalg.norm(clip[:3]), *(p / np.linalg.norm(p[:3]) for p in frustum_planes(view_proj))])
    margin = np.full(n, np.inf)
    for i in range(n):
        for p in planes:
            far = np.where(p[:3] >= 0, bounds[i, 1], bounds[i, 0])
            margin[i] = min(margin[i], abs(p[:3] @ far + p[3]))
        if i in hidden:
            expected[i] = DRAW_STATES["HIDDEN"]
        elif triangles[i] == 0:
            expected[i] = DRAW_STATES["EMPTY"]
        elif np.all((np.array([[x, y, z] for x in bounds[i, :, 0] for y in bounds[i, :, 1] for z in bounds[i, :, 2]])
                     @ clip[:3] + clip[3]) < 0):
            expected[i] = DRAW_STATES["BEHIND_PLANE"]
        elif not in_frustum(bounds[i], view_proj):
            expected[i] = DRAW_STATES["OUTSIDE_VIEW"]
    clear = margin > 1e-3
    states = draws.states(1)
    assert clear.sum() > 4900
    assert np.array_equal(states[clear], expected[clear]), f"{(states != expected)[clear].sum()} states differ"
    assert len(set(expected[clear].tolist())) == 5  # every state occurs

    commands = np.frombuffer(draws.command_buffer.read(size=20 * n, offset=20 * n), np.uint32).reshape(n, 5)
    objects = draws.order
    assert np.array_equal(commands[:, 4], objects)
    assert np.array_equal(commands[:, 0], 3 * triangles[objects])
    assert np.array_equal(commands[:, 1], (states[objects] == DRAW_STATES["DRAWN"]).astype(np.uint32))
    # region 0 was not written by the region 1 cull
    assert draws.states(0).shape == (n,) and len(draws.batches) == 4 and not np.array_equal(objects, np.arange(n))
    draws.release()


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB decoding (IEC 61966-2-1), written out here as the reference."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


SKY = 1.0  # W/(m^2 sr): a constant sky and nothing to occlude it gives E = pi SKY on every quad
COLOURS = [(200, 30, 30), (30, 200, 30), (30, 30, 200), (220, 220, 40), (40, 220, 220), (220, 40, 220)]


def write_tiles(path) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """12 quads of 0.8 m facing up in a 4 x 3 grid at y = 0, each with its own material; every other
    one textured with a uniform image of its own colour (so the textured and untextured materials
    interleave in the object order). -> [(name, centre, expected linear colour kd x texture)]."""
    w = GltfWriter()
    tiles = []
    h = 0.4
    positions = np.array([[-h, 0, h], [h, 0, h], [h, 0, -h], [-h, 0, -h]], float)  # CCW from above
    uvs = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], float)
    for k in range(12):
        centre = np.array([(k % 4 - 1.5) * 1.0, 0.0, (k // 4 - 1) * 1.0])
        if k % 2:
            rgb = np.array(COLOURS[k // 2], np.uint8)
            image = np.tile(rgb, (4, 4, 1))
            m = w.add_material(f"Tile {k}", base_color=(1, 1, 1), roughness=1.0, base_color_texture=image,
                                   extensions=LAMBERT)
            expected = srgb_to_linear(rgb / 255.0)
        else:
            expected = np.array([0.1 + 0.07 * k, 0.8 - 0.06 * k, 0.3])
            m = w.add_material(f"Tile {k}", base_color=tuple(expected), roughness=1.0, extensions=LAMBERT)
        w.add_node(f"Tile {k}", mesh=w.add_mesh(f"Tile {k}", positions + centre, [[0, 1, 2], [0, 2, 3]], m,
                                                normals=np.tile([0.0, 1.0, 0.0], (4, 1)), uvs=uvs))
        tiles.append((f"Tile {k}", centre, np.asarray(expected, float)))
    w.write(path)
    path.with_name(path.stem + ".glint.toml").write_text(f"[sky]\nradiance = [{SKY}, {SKY}, {SKY}]\n")
    return tiles


@pytest.mark.parametrize("visibility", [False, True], ids=["raster", "visibility-buffer"])
def test_interleaved_textured_materials_each_draw_their_own(ctx, tmp_path, visibility):
    """Each of 12 up-facing quads under a constant sky shows kd x texture x SKY at its centre
    (E = pi SKY exactly: nothing occludes the sky, so every bake path returns SKY), within 1.5 %
    (half-float light maps and textures). The materials alternate textured / untextured, so the
    multi-draw's texture batches (viewer/draw_list.py `batches`) are not runs of the object order.

    The figure is the largest relative error of a channel. Deliberate bugs this catches (tried):
    every batch drawn with the last batch's textures: 5 textured tiles off by 33x to 54x; the
    material taken from object 0 (scene_objects[0].info.x): 11 tiles off by 0.58 to 61x; a
    batch's first command off by one (an object skipped, another drawn with a neighbour's
    textures): 7 tiles off by 9x to 76x. Through the visibility buffer (viewer/passes/gbuffer.py), whose
    resolve runs batch by batch over the pixels shaders/visibility_classify.comp listed: every batch
    resolved with the last batch's textures: 5 tiles off by 33x to 54x; the pixels of batch b
    read from batch b + 1's list: 11 tiles off by 1x to 76x."""
    path = tmp_path / "tiles.glb"
    tiles = write_tiles(path)
    scene = load_scene(path)
    bake_scene(scene, resolve_settings(scene.bake_settings, **FAST), tmp_path / "tiles.bake", progress=False)
    bake = Bake(tmp_path / "tiles.bake")
    size = (320, 240)
    camera = ViewCamera(eye=(0.0, 6.0, 0.0), forward=(0.0, -1.0, 0.0), up=(0.0, 0.0, -1.0), yfov=math.radians(50))
    with Renderer(ctx, bake, visibility=visibility) as r:
        r.render(camera, *size)
        image = r.read_linear()
        stats = r.stats
        assert len(r.draws.batches) == 7  # 6 textured materials and the untextured ones
        assert r.gbuffer.visibility == visibility
    assert stats["objects_drawn"] == 12 and stats["triangles"] == 24
    view_proj = camera.view_projection(size[0] / size[1])
    errors = {}
    for name, centre, expected in tiles:
        ndc = view_proj @ np.append(centre, 1.0)
        x, y = ndc[:2] / ndc[3]
        col, row = int((x + 1) / 2 * size[0]), int((1 - y) / 2 * size[1])
        got = image[row - 2:row + 3, col - 2:col + 3].reshape(-1, 3).mean(axis=0)
        errors[name] = float(np.max(np.abs(got / (expected * SKY) - 1)))
    bad = {k: round(v, 4) for k, v in errors.items() if not v <= 0.015}
    assert not bad, f"tiles off: {bad}"


def test_gl_calls_per_frame_do_not_grow_with_objects(ctx, tmp_path):
    """A walkthrough frame makes as many moderngl calls with 1000 objects as with 10 (the count of
    GL calls is what made the CPU time grow with objects: ~80 us per object and pass).

    Deliberate bug this catches (tried): one render_indirect per object instead of per batch:
    84 calls at 10 objects, 1074 at 1000."""
    import cProfile
    import pstats

    from glint.scenes.stress import many_objects

    calls = {}
    for objects in (10, 1000):
        case = many_objects(tmp_path / "scenes", objects, metal_every=None)
        scene = load_scene(case.path)
        out = tmp_path / f"{objects}.bake"
        bake_scene(scene, resolve_settings(scene.bake_settings, **FAST), out, progress=False)
        bake = Bake(out)
        camera = ViewCamera.from_manifest(bake.model.cameras[0])
        with Renderer(ctx, bake) as r:
            r.render(camera, 64, 36)
            profile = cProfile.Profile()
            profile.enable()
            r.render(camera, 64, 36)
            profile.disable()
            assert r.stats["objects_drawn"] > 0.9 * objects
        calls[objects] = sum(n for (f, _, name), (_, n, *_) in pstats.Stats(profile).stats.items()
                             if f == "~" and "mgl." in name)
    assert calls[1000] == calls[10], calls


def test_small_objects_are_dropped_as_numpy_projects_them(ctx):
    """With min_radius_ndc > 0 (the bake's cube-map faces), an object in view whose bounding sphere,
    wholly in front of the eye, projects to a radius under it is TOO_SMALL, unless it emits
    (lo.w = 1); numpy projects the same spheres (radius x cot(yfov / 2) / (depth - radius)).

    Deliberate bugs this catches (tried): the sphere's centre depth instead of its nearest point
    (w - radius): 27 states differ; emitters dropped too: 101 differ."""
    rng = np.random.default_rng(11)
    n = 3000
    lo = rng.uniform(-10, 10, (n, 3)) + np.array([0.0, 0.0, -12.0])
    bounds = np.stack([lo, lo + rng.uniform(0.005, 0.6, (n, 3))], axis=1)
    scene = BoxesOnly(ctx, bounds, np.ones(n, np.int64), np.zeros(n, np.int64))
    emitters = rng.random(n) < 0.1
    table = np.frombuffer(scene.object_buffer.read(), SCENE_OBJECT_DTYPE).copy()
    table["lo"][:, 3] = emitters
    scene.object_buffer.write(table.tobytes())
    draws = DrawList(ctx, scene)
    camera = ViewCamera(eye=(0.0, 0.0, 2.0), forward=(0.0, 0.0, -1.0), yfov=math.radians(60), znear=0.05, zfar=40.0)
    view_proj = camera.view_projection(1.0)
    limit = 2.0 * 0.5 / 32  # half a texel of a 32-texel face
    draws.cull(view_proj, min_radius_ndc=limit)
    states = draws.states(0)

    centre, radius = bounds.mean(axis=1), np.linalg.norm(bounds[:, 1] - bounds[:, 0], axis=1) / 2
    depth = (centre - camera.eye) @ camera.forward - radius
    projected = radius / np.tan(camera.yfov / 2) / np.where(depth > 0, depth, np.nan)
    visible = np.array([in_frustum(b, view_proj) for b in bounds])
    small = visible & ~emitters & (depth > 0) & (projected < limit)
    clear = visible & ~((depth > 0) & (np.abs(projected / limit - 1) < 1e-3))
    expected = np.where(small, DRAW_STATES["TOO_SMALL"], np.where(visible, DRAW_STATES["DRAWN"],
                                                                  DRAW_STATES["OUTSIDE_VIEW"]))
    assert small.sum() > 100 and (visible & ~small).sum() > 100 and (emitters & visible & (projected < limit)).sum() > 10
    assert np.array_equal(states[clear], expected[clear]), f"{(states != expected)[clear].sum()} states differ"
    draws.release()


def test_drawn_commands_are_packed_in_order_per_batch(ctx):
    """Where the driver offers glMultiDrawElementsIndirectCount, shaders/compact.comp packs each
    texture batch's drawn commands (instance count 1) to the front of its range, in the draw
    order, and writes their number, which the multi-draw reads (issue 27: draws the driver never
    sees). Against numpy packing the commands cull.comp wrote: 3,000 boxes in 4 batches (so each
    batch spans several of the scan's 256-command chunks), frustums that cull half and more, two
    regions. Exact equality of counts and packed commands.

    Deliberate bugs this catches (tried): the running offset not carried from one chunk to the
    next (`written +=` left out): every chunk after a batch's first overwrites its start and the
    counts hold the last chunk's; the inclusive scan used as the position (no - 1): every command
    one slot late."""
    rng = np.random.default_rng(27)
    n = 3000
    lo = rng.uniform(-10, 10, (n, 3)) + np.array([0.0, 0.0, -12.0])
    bounds = np.stack([lo, lo + rng.uniform(0.05, 0.6, (n, 3))], axis=1)
    scene = BoxesOnly(ctx, bounds, rng.integers(0, 3, n), rng.integers(0, 4, n))  # some empty
    draws = DrawList(ctx, scene, indirect_count=True)  # also on llvmpipe, where it is off by default
    if not draws.can_count:
        pytest.skip("the driver offers no glMultiDrawElementsIndirectCount")  # llvmpipe and NVIDIA do
    cameras = [ViewCamera(eye=(0.0, 0.0, 2.0), forward=(0.3, 0.0, -1.0), yfov=math.radians(50), znear=0.05, zfar=40.0),
               ViewCamera(eye=(0.0, 0.0, 2.0), forward=(-0.5, 0.2, -1.0), yfov=math.radians(40), znear=0.05, zfar=40.0)]
    draws.reserve(2)
    for region, camera in enumerate(cameras):
        draws.cull(camera.view_projection(1.0), region=region)
    B = len(draws.batches)
    assert B == 4
    for region in range(2):
        commands = np.frombuffer(draws.command_buffer.read(size=COMMAND_BYTES * n, offset=COMMAND_BYTES * n * region),
                                 np.uint32).reshape(n, 5)
        packed = np.frombuffer(draws.compact_buffer.read(size=COMMAND_BYTES * n, offset=COMMAND_BYTES * n * region),
                               np.uint32).reshape(n, 5)
        counts = draws.draw_counts(region)
        drawn = commands[:, 1] != 0
        assert 0.1 * n < drawn.sum() < 0.8 * n
        for b, (first, count, _) in enumerate(draws.batches):
            kept = commands[first:first + count][drawn[first:first + count]]
            assert count > 2 * 256 and counts[b] == len(kept) > 0
            assert np.array_equal(packed[first:first + len(kept)], kept)
    draws.release()


def test_counted_draws_give_the_same_pixels(ctx, tmp_path):
    """The tiles of `write_tiles` (7 texture batches), seen so that the frustum leaves some out,
    rendered with the GPU counting the packed draws and with every command handed to the driver:
    the same bytes (linear image). Deliberate bugs this catches (tried): each batch's count read
    from the next batch's slot: tiles missing; the count read past the region's counts: the GL
    error is raised (GlintError "could not draw with glMultiDrawElementsIndirectCount")."""
    path = tmp_path / "tiles.glb"
    write_tiles(path)
    scene = load_scene(path)
    bake_scene(scene, resolve_settings(scene.bake_settings, **FAST), tmp_path / "tiles.bake", progress=False)
    camera = ViewCamera(eye=(0.5, 2.0, 0.0), forward=(0.0, -1.0, 0.0), up=(0.0, 0.0, -1.0), yfov=math.radians(50))
    images = []
    with Renderer(ctx, Bake(tmp_path / "tiles.bake")) as r:
        if not r.draws.can_count:
            pytest.skip("the driver offers no glMultiDrawElementsIndirectCount")  # llvmpipe and NVIDIA do
        for counted in (True, False):
            r.draws.indirect_count = counted
            r.render(camera, 160, 120)
            images.append(r.read_linear())
            assert 0 < r.stats["objects_drawn"] < 12
    assert images[0].tobytes() == images[1].tobytes()
    assert (images[0].reshape(-1, images[0].shape[-1])[:, :3].max(axis=1) > 0).mean() > 0.5
