"""Work a scene does not need is skipped, and the `skipping` section says so (viewer/skipping.py).

Purpose-made scenes: an all-diffuse room (nothing view-dependent to do), a glossy sphere in a
corner of the view (specular tiles only where it shows: counted here from the G-buffer's ids and
bounded by a numpy ray cast of the sphere), a glossy floor behind the camera and seen from below
(its mirror pass skipped, and the frame identical to the frame without its lobes), re-bakes after
a lobe, a kd and no change (asserted on the files, not only the record), and the
`glint capture --stats` JSON.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import quad, write_room
from test_pipeline import bake
from test_specular import pinhole_rays

from glint.cli import main
from glint.core.bake_dir import Bake
from glint.core.skipped import NO_LOBE, PLANAR
from glint.scenes.gltf_writer import GltfWriter
from glint.viewer.camera import ViewCamera
from glint.viewer.passes.gbuffer import read_gbuffer
from glint.viewer.renderer import Renderer
from glint.viewer.skipping import skipping_section

TILE = 8  # the shading pass's tiles (shaders: LOCAL_SIZE)
GLOSSY = [{"kind": "reflect", "ks": [1, 1, 1], "mx": 0.1, "my": 0.1, "r0": 0.04}]
BAKE_ARGS = ["-q", "draft", "--samples", "8", "--texels-per-metre", "6", "--no-denoise"]


def tiles(width: int, height: int) -> int:
    return math.ceil(width / TILE) * math.ceil(height / TILE)


def tile_set(mask: np.ndarray) -> set:
    """8 x 8 tiles (counted from the bottom row, as GL's) holding a True pixel of an image-row mask."""
    rows, cols = np.nonzero(mask[::-1])
    return {(r // TILE, c // TILE) for r, c in zip(rows, cols)}


def write_stage(path: Path, *, sphere=None, floor_double_sided=False, sidecar: str = "") -> Path:
    """A diffuse back wall (z = -1), a glossy double-sidable floor (y = 0, 2 x 2 m, a planar
    reflector), a lamp above; `sphere` = (centre, radius) adds a glossy icosphere (curved: cube map)."""
    import trimesh

    w = GltfWriter()
    wall = w.add_material("Wall", base_color=(0.6, 0.6, 0.6))
    floor = w.add_material("Floor", base_color=(0.5, 0.5, 0.5), double_sided=floor_double_sided,
                           extras={"glint": {"lobes": GLOSSY}})
    lamp = w.add_material("Lamp", emissive=(1, 1, 1), emissive_strength=6.0)
    for name, (c, u, v, m) in {"Back": ((0, 1, -1), (2, 0, 0), (0, 1, 0), wall),
                               "Floor": ((0, 0, 0), (1, 0, 0), (0, 0, -1), floor),
                               "Lamp": ((0, 1.9, 0), (0.3, 0, 0), (0, 0, 0.3), lamp)}.items():
        p, i = quad(c, u, v)  # the lamp faces down
        w.add_node(name, mesh=w.add_mesh(name, p, i, m))
    if sphere is not None:
        ball = trimesh.creation.icosphere(subdivisions=3, radius=sphere[1])
        shiny = w.add_material("Shiny", base_color=(0.2, 0.2, 0.2), extras={"glint": {"lobes": GLOSSY}})
        w.add_node("Sphere", mesh=w.add_mesh("Sphere", ball.vertices, ball.faces, shiny, normals=ball.vertex_normals),
                   translation=tuple(sphere[0]))
    w.write(path)
    if sidecar:
        path.with_name(path.stem + ".glint.toml").write_text(sidecar)
    return path


def render(ctx, b, camera, size):
    with Renderer(ctx, b, supersample=1) as r:
        r.render(camera, *size)
        return r.read_linear(), r.stats


# -- (1) nothing view-dependent: nothing done ------------------------------------------------------
def test_all_diffuse_scene_skips_all_view_dependent_work(ctx, tmp_path):
    path = write_room(tmp_path / "room.glb")
    bake(path, tmp_path / "room.bake")
    b = Bake(tmp_path / "room.bake")
    size = (40, 24)
    with Renderer(ctx, b, supersample=1) as r:
        r.render(ViewCamera.from_manifest(b.model.cameras[0]), *size)
        stats = r.stats
    s = skipping_section(stats, b.model)
    assert not (tmp_path / "room.bake" / "cubemaps").exists()  # no cube map file at all
    assert s["cube_maps"]["objects"] == 8 and s["cube_maps"]["baked"] == 0  # write_room: 7 quads + a box
    assert s["cube_maps"]["without_by_reason"][NO_LOBE]["count"] == 8
    spec = s["specular"]
    assert spec["tiles"] == 5 * 3 == tiles(*size)
    assert spec["tiles_dispatched"] == 0 and spec["tiles_skipped"]["count"] == 15
    assert spec["tiles_skipped"]["fraction"] == 1.0 and spec["pixels_with_lobes"] == 0
    assert spec["dispatch"].startswith("skipped")
    assert s["mirror"]["reflectors"] == 0 and s["mirror"]["passes_run"] == 0
    # no pass ran that was not needed: nothing was timed for them
    assert not {"specular", "mirror_passes", "mirror_mips"} & set(stats["gpu_ms"])


# -- (2) specular tiles only where the glossy sphere shows -----------------------------------------
def test_specular_tiles_are_those_the_glossy_sphere_covers(ctx, tmp_path):
    centre, radius = np.array([-1.1, 1.5, -0.4]), 0.2
    path = write_stage(tmp_path / "s.glb", sphere=(centre, radius), sidecar='[objects."Sphere"]\ncubemap_size = 8\n')
    bake(path, tmp_path / "s.bake")
    b = Bake(tmp_path / "s.bake")
    size, eye, target, yfov = (64, 48), (0.0, 0.8, 1.6), (0.0, 0.8, 0.0), 1.0
    camera = ViewCamera.look_at(eye, target, yfov=yfov, znear=0.01, zfar=100)
    with Renderer(ctx, b, supersample=1, mirror_budget=0) as r:
        r.render(camera, *size)
        stats = r.stats
        gb = read_gbuffer(r.gbuffer.targets)
    s = skipping_section(stats, b.model)
    names = [o.name for o in b.model.objects]
    assert s["cube_maps"]["baked"] == 1 and b.model.objects[names.index("Sphere")].cubemap
    assert s["cube_maps"]["without_by_reason"][PLANAR]["names"] == ["Floor"]
    assert s["mirror"]["skipped"]["budget 0"]["count"] == 1 and s["mirror"]["passes_run"] == 0
    # The sphere's pixels from the G-buffer's object ids (image rows), not from the specular counters.
    on_sphere = (gb["drawn"] & (gb["object"] == names.index("Sphere")))[::-1]
    covered = tile_set(on_sphere)
    # ... and bounded by a ray cast of the true sphere: pixels inside the icosphere's inscribed
    # sphere must be in it, pixels outside its circumscribed sphere must not.
    rays = pinhole_rays(eye, target, (0, 1, 0), yfov, *size)
    oc = np.asarray(eye) - centre
    b_ = rays @ oc
    miss = b_ ** 2 - (oc @ oc)  # + r^2 > 0: the ray meets a sphere of radius r
    inner, outer = miss + (0.98 * radius) ** 2 > 0, miss + radius ** 2 > 0
    assert inner.sum() > 20 and np.all(on_sphere[inner]) and not np.any(on_sphere[~outer])
    assert tile_set(inner) <= covered <= tile_set(outer)
    spec = s["specular"]
    assert spec["tiles"] == tiles(*size) == 48
    assert spec["tiles_dispatched"] == len(covered) and spec["tiles_skipped"]["count"] == 48 - len(covered)
    assert spec["pixels_with_lobes"] == on_sphere.sum()
    assert len(covered) <= 12  # a corner of the view, not the whole frame


def test_tiles_holding_planar_and_curved_pixels_shade_each_pixel_once(ctx, tmp_path):
    """The specular pass sorts tiles onto two lists, pixels reading their plane's mirror buffer and
    pixels reading a cube map, each run by its own program (viewer/passes/shading.py); a tile holding
    both kinds is on both lists and each program shades only its own pixels. Here a glossy sphere
    stands on the glossy floor, which gets its mirror pass, so the sphere's outline crosses tiles of
    floor. Expected counts come from the G-buffer's object ids, not from the lists: every floor and
    sphere pixel shaded exactly once, and the tiles dispatched those that hold either. Catches a tile
    queued on its first list only (the other kind's pixels in it unlit: too few pixels) and a
    program that shades every pixel of its tiles (pixels of both kinds shaded twice: too many)."""
    centre, radius = np.array([0.0, 0.25, -0.3]), 0.25
    path = write_stage(tmp_path / "s.glb", sphere=(centre, radius), sidecar='[objects."Sphere"]\ncubemap_size = 8\n')
    bake(path, tmp_path / "s.bake")
    b = Bake(tmp_path / "s.bake")
    size = (64, 48)
    camera = ViewCamera.look_at((0.0, 0.9, 1.4), (0.0, 0.2, -0.3), yfov=0.9, znear=0.01, zfar=100)
    with Renderer(ctx, b, supersample=1) as r:
        r.render(camera, *size)
        stats, image = r.stats, r.read_linear()
        gb = read_gbuffer(r.gbuffer.targets)
    s = skipping_section(stats, b.model)
    assert s["mirror"]["passes_run"] == 1
    names = [o.name for o in b.model.objects]
    on_sphere = (gb["drawn"] & (gb["object"] == names.index("Sphere")))[::-1]
    on_floor = (gb["drawn"] & (gb["object"] == names.index("Floor")))[::-1]
    both = tile_set(on_sphere) & tile_set(on_floor)
    assert on_sphere.sum() > 100 and on_floor.sum() > 500 and len(both) >= 4  # the case under test
    spec = s["specular"]
    assert spec["pixels_with_lobes"] == on_sphere.sum() + on_floor.sum()
    assert spec["tiles_dispatched"] == len(tile_set(on_sphere) | tile_set(on_floor))
    assert np.all(np.isfinite(image))


# -- (3) a mirror pass nobody would see is not run, and leaves the frame as without its lobes ------
@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    d = tmp_path_factory.mktemp("stage")
    path = write_stage(d / "stage.glb", floor_double_sided=True)
    bake(path, d / "stage.bake")
    with_lobes = Bake(d / "stage.bake")
    without = Bake(d / "stage.bake")  # the same light maps; the floor's lobes removed
    without.model = dataclasses.replace(without.model, materials=[
        dataclasses.replace(m, lobes=[]) if m.name == "Floor" else m for m in without.model.materials])
    return with_lobes, without


@pytest.mark.parametrize("view, reason", [
    (((0.0, 1.0, 1.5), (0.0, 2.0, 0.5)), "outside frustum"),   # looking 45 degrees up: the floor is below the view
    (((0.0, -1.0, 2.5), (0.0, 0.0, 0.0)), "seen from behind"),  # under the floor, seeing its lower side
    (((0.0, 1.0, 2.5), (0.0, 0.0, 0.0)), None),                 # above: the pass runs (the control)
])
def test_mirror_pass_skipped_for_an_unseen_reflector(ctx, stage, view, reason):
    with_lobes, without = stage
    camera = ViewCamera.look_at(*view, yfov=0.8, znear=0.01, zfar=100)
    size = (32, 24)
    frame, stats = render(ctx, with_lobes, camera, size)
    plain, _ = render(ctx, without, camera, size)
    m = skipping_section(stats, with_lobes.model)["mirror"]
    assert m["reflectors"] == 1
    assert plain.max() > 0.01  # an image, not black
    if reason is None:
        assert m["passes_run"] == 1 and sum(v["count"] for v in m["skipped"].values()) == 0
        assert not np.array_equal(frame, plain)  # here the lobes do show: the comparison can fail
        return
    assert m["passes_run"] == 0
    assert m["skipped"][reason]["count"] == 1 and m["skipped"][reason]["names"] == ["Floor"]
    assert sum(v["count"] for v in m["skipped"].values()) == 1
    assert not {"mirror_passes", "mirror_mips"} & set(stats["gpu_ms"])
    np.testing.assert_array_equal(frame, plain)


# -- (4) re-bakes: reuse asserted on the files -----------------------------------------------------
def snapshot(out: Path) -> dict:
    """{relative path: (inode, mtime, sha256)} of every file of a bake dir."""
    return {str(p.relative_to(out)): (p.stat().st_ino, p.stat().st_mtime_ns, hashlib.sha256(p.read_bytes()).hexdigest())
            for p in sorted(out.rglob("*")) if p.is_file()}


def test_rebake_reuses_charts_and_redoes_light_maps_for_kd_and_lobes(tmp_path, capsys):
    """A lobe edit re-bakes the light maps (the bake's paths scatter by the lobes) and reuses the
    charts, and the summary line says so; a kd edit likewise; no edit touches nothing."""
    path, out = write_room(tmp_path / "room.glb"), tmp_path / "room.bake"
    args = ["bake", str(path), *BAKE_ARGS, "-o", str(out)]
    assert main(args) == 0
    first = snapshot(out)
    pages = [k for k in first if k.startswith("lightmaps/")]
    assert pages and Bake(out).model.statistics.last_bake["light_maps"] == "re-baked"
    capsys.readouterr()

    write_room(path, floor_lobes=GLOSSY)  # a lobe only
    assert main(args) == 0
    line = capsys.readouterr().out.splitlines()[-1]
    assert line.startswith("skipped: ") and "unwrap reused; light maps re-baked (changed: lobes of Floor" in line
    assert "7 no view-dependent lobe, 1 planar: mirror pass instead" in line
    second = snapshot(out)
    assert second["meshes.npz"][2] == first["meshes.npz"][2]  # the charts: the same content (unwrap reused)
    assert all(second[page][2] != first[page][2] for page in pages)  # the floor now reflects light onto the walls
    record = Bake(out).model.statistics.last_bake
    assert record["light_maps"] == "re-baked" and record["unwrap"] == "reused" and "lobes of Floor" in record["changed"]

    write_room(path, floor_lobes=GLOSSY, kd=(0.3, 0.3, 0.3))  # a diffuse colour
    assert main(args) == 0
    assert "light maps re-baked (changed: kd of Wall, kd of Floor)" in capsys.readouterr().out
    third = snapshot(out)
    assert all(third[page][2] != second[page][2] for page in pages)  # new irradiance
    record = Bake(out).model.statistics.last_bake
    assert record["light_maps"] == "re-baked" and record["unwrap"] == "reused"

    assert main(args) == 0  # nothing changed: nothing done, not even the manifest rewritten
    assert capsys.readouterr().out.strip().endswith("up to date, nothing to do")
    assert snapshot(out) == third


# -- (5) `glint capture --stats` -----------------------------------------------------------------
def test_capture_stats_has_the_skipping_section(tmp_path):
    path = write_room(tmp_path / "room.glb", floor_lobes=GLOSSY)
    common = [str(path), "--size", "45x32", "--supersample", "1", *BAKE_ARGS, "--bake-dir", str(tmp_path / "b")]
    assert main(["capture", *common, "-o", str(tmp_path / "first.png")]) == 0  # bakes
    assert main(["capture", *common, "-o", str(tmp_path / "a.png"), "--stats", str(tmp_path / "a.json")]) == 0
    data = json.loads((tmp_path / "a.json").read_text())
    s = data["skipping"]
    assert set(s) == {"specular", "mirror", "cube_maps", "bake"}
    assert data["per_frame"][0]["skipping"] == {"specular": s["specular"], "mirror": s["mirror"]}
    # The room's camera: eye (0, 1, 0.9) looking down -Z, yfov 1 rad. Floor pixels: rays that meet
    # y = 0 inside the 2 x 2 m room (nothing in view stands on it: the box is below the view).
    rays = pinhole_rays((0, 1, 0.9), (0, 1, 0), (0, 1, 0), 1.0, 45, 32)  # an odd width: no pixel centre on a corner
    t = np.where(rays[..., 1] < 0, -1.0 / np.minimum(rays[..., 1], -1e-12), 1e9)
    x, z = rays[..., 0] * t, 0.9 + rays[..., 2] * t
    floor = (np.abs(x) < 1) & (np.abs(z) < 1)
    outside_by = np.maximum(np.abs(x), np.abs(z)) - 1  # < 0 inside the floor
    assert floor.sum() > 20 and np.nanmin(np.abs(outside_by)) > 1e-3  # no pixel centre on the floor's edge
    spec = s["specular"]
    assert spec["tiles"] == 6 * 4 and spec["pixels"] == 45 * 32
    assert spec["tiles_dispatched"] == len(tile_set(floor)) and spec["tiles_skipped"]["count"] == 24 - len(tile_set(floor))
    assert spec["pixels_with_lobes"] == floor.sum()
    assert spec["pixels_without_lobes"]["fraction"] == pytest.approx(1 - floor.sum() / (45 * 32), abs=1e-4)
    m = s["mirror"]
    assert m["reflectors"] == 1 and m["passes_run"] == 1 and m["merged"]["count"] == 0
    assert all(v["count"] == 0 for v in m["skipped"].values())
    c = s["cube_maps"]
    assert c["objects"] == 8 and c["baked"] == 0 and c["without"]["count"] == 8
    assert c["without_by_reason"][PLANAR]["names"] == ["Floor"] and c["without_by_reason"][NO_LOBE]["count"] == 7
    assert s["bake"]["this_command"]["status"] == "up-to-date"
    assert s["bake"]["last_bake"]["status"] == "full" and s["bake"]["last_bake"]["light_maps"] == "re-baked"
