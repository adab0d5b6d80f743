"""`glint bake` as a whole: bake dir contents, incremental re-bake, atomicity, determinism."""
from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import FAST, write_room

from glint.bake import pipeline
from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.core.bake_dir import Bake
from glint.core.image_io import read_image
from glint.scenes.gltf_writer import GltfWriter, quad, room_faces
from glint.services import bake_scene


def bake(path, out, **overrides):
    scene = load_scene(path)
    settings = resolve_settings(scene.bake_settings, **{**FAST, **overrides})
    return bake_scene(scene, settings, out, progress=False)


def lightmap_bytes(out):
    return {p.name: p.read_bytes() for p in sorted((out / "lightmaps").iterdir())}


def test_bake_dir_contents(room, tmp_path):
    out = tmp_path / "room.bake"
    report = bake(room, out)
    assert report.status == "full"
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["format"] == "glint-bake" and manifest["version"] == 1
    assert set(manifest["stages"]) >= {"geometry", "lightmaps"}
    stats = manifest["statistics"]["lightmaps"]
    assert stats["texels"] > 100 and stats["rays"] > stats["texels"] * FAST["samples"]
    # the stage's steps, timed in order: their sum within the stage, the tracing's two trace_seconds
    phases = stats["phase_seconds"]
    assert list(phases) == ["tracer", "samples", "tiles", "refine", "pages"]
    assert all(v >= 0 for v in phases.values()) and sum(phases.values()) <= stats["seconds"] + 1e-3
    assert abs(phases["tiles"] + phases["refine"] - stats["trace_seconds"]) <= 2e-3
    names = [o["name"] for o in manifest["objects"]]
    assert {"Floor", "Ceiling", "Lamp", "Box"} <= set(names)
    for page in manifest["lightmaps"]:
        image = read_image(out / page)
        assert image.shape[2] == 4 and np.all(np.isfinite(image))
    # only the committed directory is left: no temporary or old copies beside it
    assert sorted(p.name for p in tmp_path.iterdir()) == ["room.bake", "room.glb"]


def test_lightmap_is_plausible(room, tmp_path):
    """Ceiling-lit room: the floor under the lamp gets more light than the ceiling corners,
    and every baked value is finite and non-negative."""
    out = tmp_path / "room.bake"
    bake(room, out, samples=32)
    b = Bake(out)
    names = [o["name"] for o in b.manifest["objects"]]
    floor = names.index("Floor")
    centre = b.irradiance(floor, np.array([0]), np.array([[0.5, 0.0, 0.5]]))[0]  # diagonal midpoint = (0,0,0)
    assert centre.min() > 0
    # direct light of a 0.5 x 0.5 m lamp of radiance 8 at 2 m: ~ L*A/h^2 = 0.5; the closed room
    # (albedo 0.7) adds about as much again (radiosity balance: pi*L*A / (24 m^2 * 0.3) * 0.7 ~ 0.6)
    assert 0.6 < centre.mean() < 2.0


def test_second_bake_is_up_to_date(room, tmp_path):
    out = tmp_path / "room.bake"
    bake(room, out)
    before = lightmap_bytes(out)
    mtime = (out / "manifest.json").stat().st_mtime_ns
    report = bake(room, out)
    assert report.status == "up-to-date"
    assert "up to date" in report.summary
    assert (out / "manifest.json").stat().st_mtime_ns == mtime
    assert lightmap_bytes(out) == before


def test_camera_change_keeps_lightmaps(tmp_path, monkeypatch):
    out = tmp_path / "room.bake"
    path = write_room(tmp_path / "room.glb")
    bake(path, out)
    before = lightmap_bytes(out)
    # a new camera: no light map is re-baked
    write_room(path, sidecar='[cameras.extra]\neye = [0, 1, 0]\ntarget = [0, 0, -1]\nyfov = 40\n')

    def no_bake(*a, **k):
        raise AssertionError("light maps were re-baked")

    monkeypatch.setattr(pipeline, "_bake_geometry_and_lightmaps", no_bake)
    report = bake(path, out)
    assert report.status == "manifest"
    assert lightmap_bytes(out) == before
    manifest = json.loads((out / "manifest.json").read_text())
    assert "extra" in [c["name"] for c in manifest["cameras"]]


FLOOR_LOBE = {"kind": "reflect", "ks": [1, 1, 1], "mx": 0.1, "my": 0.1, "r0": 0.04}


@pytest.mark.parametrize("change", [{"floor_lobes": [FLOOR_LOBE]}, {"kd": (0.3, 0.3, 0.3)}], ids=["lobe", "kd"])
def test_material_change_rebakes_lightmaps_and_reuses_the_unwrap(tmp_path, monkeypatch, change):
    """A kd edit, and a new reflection lobe on the floor (the bake's paths scatter by the lobes,
    bake/scatter.py: the walls receive what the floor reflects), change the light maps; the charts
    are reused."""
    out = tmp_path / "room.bake"
    path = write_room(tmp_path / "room.glb")
    bake(path, out)
    before = lightmap_bytes(out)
    write_room(path, **change)
    import glint.bake.unwrap as unwrap_module

    def no_unwrap(*a, **k):
        raise AssertionError("geometry did not change, the unwrap must be reused")

    monkeypatch.setattr(unwrap_module, "unwrap", no_unwrap)
    report = bake(path, out)
    assert report.status == "lightmaps"
    assert lightmap_bytes(out) != before
    if "floor_lobes" in change:
        manifest = json.loads((out / "manifest.json").read_text())
        floor = next(m for m in manifest["materials"] if m["name"] == "Floor")
        assert floor["lobes"] and floor["lobes"][0]["mx"] == pytest.approx(0.1)


def test_geometry_change_rebakes_everything(tmp_path):
    out = tmp_path / "room.bake"
    path = write_room(tmp_path / "room.glb")
    bake(path, out)
    write_room(path, box_height=0.8)
    assert bake(path, out).status == "full"


def test_interrupted_bake_leaves_previous_bake_intact(tmp_path, monkeypatch):
    out = tmp_path / "room.bake"
    path = write_room(tmp_path / "room.glb")
    bake(path, out)
    before = lightmap_bytes(out)
    manifest = (out / "manifest.json").read_text()
    write_room(path, kd=(0.2, 0.5, 0.2))
    import glint.bake.lightmap as lightmap_module

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(lightmap_module, "compute_irradiance", interrupted)
    with pytest.raises(KeyboardInterrupt):
        bake(path, out, jobs=1)
    assert lightmap_bytes(out) == before
    assert (out / "manifest.json").read_text() == manifest
    assert sorted(p.name for p in tmp_path.iterdir()) == ["room.bake", "room.glb"]


def test_result_does_not_depend_on_worker_count(room, tmp_path, monkeypatch):
    import glint.bake.lightmap as lightmap_module

    monkeypatch.setattr(lightmap_module, "TILE", 64)  # several jobs, so two workers share them
    bake(room, tmp_path / "a.bake", jobs=1)
    bake(room, tmp_path / "b.bake", jobs=2)
    assert lightmap_bytes(tmp_path / "a.bake") == lightmap_bytes(tmp_path / "b.bake")


def test_instances_of_one_mesh_get_their_own_light_map_space(tmp_path):
    """One glTF mesh placed by two nodes (instancing, as exporters write repeated furniture) is two
    objects with disjoint light-map rectangles: each instance gets its own light. Catches instances
    sharing one chart (both would show the light of whichever was baked last)."""
    w = GltfWriter()
    wall = w.add_material("Wall", base_color=(0.7, 0.7, 0.7), roughness=1.0)
    lamp = w.add_material("Lamp", base_color=(0.8, 0.8, 0.8), emissive=(1, 1, 1), emissive_strength=8.0)
    w.add_quads({**room_faces(1.0, 2.0, wall, wall), "Lamp": ((0, 1.99, 0), (0.25, 0, 0), (0, 0, 0.25), lamp)})
    p, i = quad((0, 0.3, 0), (0.2, 0, 0), (0, 0.2, 0))
    panel = w.add_mesh("Panel", p, i, wall)
    w.add_node("PanelA", mesh=panel, translation=(-0.5, 0, 0))
    w.add_node("PanelB", mesh=panel, translation=(0.5, 0, 0))
    report = bake(w.write(tmp_path / "instances.glb"), tmp_path / "i.bake")
    names = [o["name"] for o in report.manifest["objects"]]
    assert names.count("PanelA") == 1 and names.count("PanelB") == 1
    with np.load(tmp_path / "i.bake" / "meshes.npz") as meshes:
        rects = []
        for name in ("PanelA", "PanelB"):
            k = names.index(name)
            uv, page = meshes[f"o{k}_lm_uv"], meshes[f"o{k}_lm_page"]
            rects.append((int(page[0]), uv.min(axis=0), uv.max(axis=0)))
    (pa, lo_a, hi_a), (pb, lo_b, hi_b) = rects
    overlap = np.all(np.minimum(hi_a, hi_b) > np.maximum(lo_a, lo_b))
    assert pa != pb or not overlap, rects
