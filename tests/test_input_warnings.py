"""Messages that used to mislead (issue 22): a kd or ks above 1 clamped without a word, a scene far too dark
for the default exposure with no hint, an emitter counted as unlit surface, absurd coordinates reported as
a page count."""
import json
import re

import numpy as np

from glint.cli import main
from glint.scenes.gltf_writer import GltfWriter, room_faces

from conftest import FAST, error_of, write_room

FAST_ARGS = ["-q", FAST["quality"], "--samples", str(FAST["samples"]), "--texels-per-metre",
             str(FAST["texels_per_metre"]), "--no-denoise"]
TRIANGLE = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)


def _bake(scene, tmp_path, *args) -> int:
    return main(["bake", str(scene), "-o", str(tmp_path / "out.bake"), *FAST_ARGS, *args])


def _statistics(tmp_path) -> dict:
    return json.loads((tmp_path / "out.bake" / "manifest.json").read_text())["statistics"]["lightmaps"]


def test_kd_above_one_warns_once_per_material(tmp_path, capsys):
    """kd [1.5, 0.5, 0.5] on Wall and Floor: one summary line naming both and the value, saying clamped.
    Catches: kd above 1 clamped silently by the bake and the viewer (bake/irradiance.py, gpu_materials.py)."""
    from glint.bake.gltf_loader import load_scene

    scene = load_scene(write_room(tmp_path / "room.glb", kd=(1.5, 0.5, 0.5)))
    kd = max(scene.materials[0].kd)  # the base colour 1.5 as the glTF mapping made it (fresnel_mix's share)
    lines = [line for line in capsys.readouterr().err.splitlines() if "kd above 1" in line]
    assert kd > 1.4 and lines == ["glint: warning: 2 materials have kd above 1 (a surface that would create "
                                  f"light); clamped to 1: 'Wall' ({kd:g}), 'Floor' ({kd:g})"]


def test_ks_above_one_warns_naming_material_and_value(tmp_path, capsys):
    """A lobe with ks 2 (sidecar override of Floor): one line naming the material and 2. Catches: ks above 1
    clamped silently (bake/scatter.py clips it to 1, as the viewer does)."""
    from glint.bake.gltf_loader import load_scene

    load_scene(write_room(tmp_path / "room.glb", sidecar='[materials."Floor"]\nlobes = [ { ks = 2, m = 0.1 } ]\n'))
    err = capsys.readouterr().err
    assert ("glint: warning: room.glb: material 'Floor' has a lobe with ks 2 above 1 (it would reflect more "
            "light than it receives); clamped to 1") in err.splitlines()
    assert "kd above 1" not in err  # kd 0.7: nothing to say


def _point_lit_room(tmp_path, half: float, candela: float):
    w = GltfWriter()
    wall = w.add_material("Wall", base_color=(0.7, 0.7, 0.7), roughness=1.0)
    w.add_quads(room_faces(half, 2 * half, wall, wall))
    w.add_node("Bulb", light=w.add_light("Bulb", "point", intensity=candela), translation=(0, half, 0))
    path = tmp_path / "dim.glb"
    w.write(path)
    return path


def test_dark_scene_suggests_an_exposure(tmp_path, capsys):
    """A 10 m room lit by one 200 cd point light at its centre: 200/683 W/sr at 5 m gives the walls' centres
    E = 0.0117 W/m^2 direct, about 3x that with the 0.7 walls' bounces, so radiance 0.7/pi x 0.035 = 0.008
    W/(m^2 sr): 4.5 stops under middle grey 0.18 (corners less). The bake says it will look nearly black
    and suggests --exposure 4 to 6. Catches: the bake saying nothing (the capture came out black)."""
    assert _bake(_point_lit_room(tmp_path, 5.0, 200.0), tmp_path) == 0
    err = capsys.readouterr().err
    match = re.search(r"the scene will look nearly black at the default exposure: .* view or capture it with --exposure (\d+),", err)
    assert match and 4 <= int(match.group(1)) <= 6, err
    assert 0.18 / 2 ** 6 < _statistics(tmp_path)["median_radiance"] < 0.18 / 2 ** 4


def test_well_lit_scene_says_nothing_about_exposure(tmp_path, capsys):
    """The test room (an 8 W/(m^2 sr) lamp in 2 m): no exposure warning. Catches a warning that fires on
    every scene (e.g. comparing irradiance instead of radiance, or the threshold's sign reversed)."""
    assert _bake(write_room(tmp_path / "room.glb"), tmp_path) == 0
    assert "exposure" not in capsys.readouterr().err


def test_lone_emitter_is_not_unlit(tmp_path, capsys):
    """One emissive triangle, nothing else: its texels get no light, but it is seen by its emission, so
    neither the bake nor the fidelity line says "100 % of the surface gets no light". Catches: emitters'
    texels counted in unlit_texels (bake/lightmap.py)."""
    w = GltfWriter()
    lamp = w.add_material("Lamp", emissive=(1, 1, 1))
    w.add_node("Lamp", mesh=w.add_mesh("Lamp", TRIANGLE, np.array([[0, 1, 2]]), lamp,
                                        normals=np.tile([0.0, 0.0, 1.0], (3, 1))))
    scene = tmp_path / "lamp.glb"
    w.write(scene)
    assert _bake(scene, tmp_path) == 0
    err = capsys.readouterr().err
    assert "no light" not in err and "unlit" not in err, err
    stats = _statistics(tmp_path)
    assert stats["texels"] > 0 and stats["unlit_texels"] == 0 and stats["median_radiance"] is None


def test_absurd_coordinates_refused_at_load(tmp_path, capsys):
    """A quad 1e30 m across: refused in one line naming the object, its extent and the limit, before the
    unwrap (which said "would need about 4.3e55 pages"). Catches: no extent check at load."""
    w = GltfWriter()
    lamp = w.add_material("Lamp", emissive=(1, 1, 1))
    quad = np.array([[0, 0, 0], [1, 0, 0], [1, 0, -1], [0, 0, -1]], float) * 1e30
    w.add_node("Far", mesh=w.add_mesh("Far", quad, np.array([[0, 1, 2], [0, 2, 3]]), lamp,
                                       normals=np.tile([0.0, 1.0, 0.0], (4, 1))))
    scene = tmp_path / "far.glb"
    w.write(scene)
    assert error_of(capsys, _bake(scene, tmp_path)) == (
        "glint: far.glb: object 'Far' reaches 1e+30 m from the origin (bounding box x, y, z: 0..1e+30, 0..0, "
        "-1e+30..0 m); glint takes coordinates within 1e+06 m: check the export's units and scale, or remove "
        "stray vertices")
