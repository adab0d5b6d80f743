"""Warnings a person can read: repeated ones summarised, the end of a bake says what looks wrong.

glint.core.errors collects the warnings that repeat per object or material (a `WarningKind`)
and prints one line per kind with a count and the first names; `--verbose` prints each.
`glint bake` ends with one line of what the scene will look like wrong: the share of
light-map texels inside geometry and the glTF features the loader ignored (manifest
`statistics.lightmaps.invalid_texels` and `statistics.ignored_features`).

The scenes are made here: a closed room lit by a ceiling lamp (conftest's write_room without
its box) plus what each test needs. Expected counts come from how the scene was built.
"""
from __future__ import annotations

import argparse
import json

import numpy as np
import pytest
from conftest import write_room

from glint.cli import main
from glint.core.errors import WarningKind, summarised, warn
from glint.scenes.gltf_writer import GltfWriter, quad, room_faces
from glint.options import add_bake_options
from glint.services import run_bake

FAST = ["-q", "draft", "--samples", "4", "--texels-per-metre", "4", "--no-denoise", "-j", "1"]
SLIVERS = 12  # objects with 2 good triangles and 1 of zero area
FLAT = 4  # objects with only a zero-area triangle


def room_writer(light: float = 8.0) -> tuple[GltfWriter, int]:
    """(writer with a closed 2 x 2 x 2 m room and its lamp, the walls' material)."""
    w = GltfWriter()
    wall = w.add_material("Wall", base_color=(0.7, 0.7, 0.7), roughness=1.0)
    floor = w.add_material("Floor", base_color=(0.7, 0.7, 0.7), roughness=1.0)
    faces = room_faces(1.0, 2.0, wall, floor)
    if light:
        lamp = w.add_material("Lamp", emissive=(1, 1, 1), emissive_strength=light)
        faces["Lamp"] = ((0, 1.99, 0), (0.25, 0, 0), (0, 0, 0.25), lamp)
    w.add_quads(faces, normals=True)
    return w, wall


def add_degenerate_objects(w: GltfWriter, material: int) -> None:
    """SLIVERS small quads with one extra zero-area triangle each, and FLAT objects of only
    a zero-area triangle (a corner on the opposite edge: collinear)."""
    for k in range(SLIVERS + FLAT):
        p, i = quad((-0.8 + 0.1 * k, 1.0, 0.0), (0.03, 0, 0), (0, 0.03, 0))
        p = np.vstack([p, (p[0] + p[1]) / 2])
        i = np.vstack([i, [[0, 1, 4]]]) if k < SLIVERS else np.array([[0, 1, 4]])
        name = f"Sliver{k}" if k < SLIVERS else f"Flat{k - SLIVERS}"
        w.add_node(name, mesh=w.add_mesh(name, p, i, material, normals=np.tile([0, 0, 1.0], (5, 1))))


def warning_lines(err: str, word: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("glint: warning:") and word in line]


def test_many_objects_with_zero_area_triangles_give_one_line_and_verbose_each(tmp_path, capsys):
    """Deliberate bugs this catches (tried): `warn` printing kinded warnings at once as before
    (16 lines instead of 2); the summary counting warnings in its sum but the objects wrongly
    (`n=len(names[:3])`: "3 objects"); `main` not passing `--verbose` on to `summarised`
    (the second bake shows the summary instead of 12 lines); an object whose triangles all
    have zero area reported as having dropped them too ("16 objects")."""
    w, wall = room_writer()
    add_degenerate_objects(w, wall)
    scene = w.write(tmp_path / "slivers.glb")
    assert main(["bake", str(scene), "-o", str(tmp_path / "s.bake"), *FAST]) == 0
    err = capsys.readouterr().err
    assert warning_lines(err, "zero-area") == [
        f"glint: warning: {SLIVERS} objects have zero-area triangles (dropped {SLIVERS} of their "
        f"{3 * SLIVERS} triangles): 'Sliver0' (1), 'Sliver1' (1), 'Sliver2' (1), "
        f"... and {SLIVERS - 3} more"]
    assert warning_lines(err, "no triangles with area") == [
        f"glint: warning: {FLAT} objects have no triangles with area and were skipped: "
        f"'Flat0', 'Flat1', 'Flat2', ... and {FLAT - 3} more"]

    # Up to date now, but loading warns again: one line per object with --verbose.
    assert main(["bake", str(scene), "-o", str(tmp_path / "s.bake"), *FAST, "--verbose"]) == 0
    err = capsys.readouterr().err
    assert warning_lines(err, "zero-area") == [
        f"glint: warning: slivers.glb: object 'Sliver{k}': dropped 1 zero-area triangle(s) of 3"
        for k in range(SLIVERS)]
    assert warning_lines(err, "no triangles with area") == [
        f"glint: warning: slivers.glb: object 'Flat{k}' has no triangles with area; skipped"
        for k in range(FLAT)]


def test_ignored_features_named_at_the_end_of_a_bake(tmp_path, capsys):
    """A clearcoat texture on two materials and EXT_texture_webp on their texture are named in the last
    line of `glint bake` and of a bake that capture/view/bench start (glint.services.run_bake),
    and kept in the manifest. Deliberate bugs this catches (tried): the textures' warning in
    bake/material_mapping.py without `ignored=` (no clearcoatTexture in the line); the pipeline
    not writing `statistics.ignored_features` (no "ignored:" at all); `cmd_bake` not printing
    the line; `run_bake` not printing it; unsupported extensions of extensionsUsed not
    counted (no EXT_texture_webp)."""
    w, wall = room_writer()
    texture = w.add_texture(np.full((2, 2, 3), 128, np.uint8))
    for m in (wall, 1):  # a wall and the floor
        w.materials[m]["extensions"] = {"KHR_materials_clearcoat": {"clearcoatFactor": 0.0,
                                                                   "clearcoatTexture": {"index": texture}}}
    w.extensions_used.add("KHR_materials_clearcoat")
    w.materials[1]["pbrMetallicRoughness"]["baseColorTexture"] = {"index": texture}
    w.textures[texture]["extensions"] = {"EXT_texture_webp": {"source": 0}}
    w.extensions_used.add("EXT_texture_webp")
    scene = w.write(tmp_path / "maps.glb")
    bake_dir = tmp_path / "maps.bake"

    parser = argparse.ArgumentParser()
    parser.add_argument("scene")
    add_bake_options(parser)
    run_bake(parser.parse_args([str(scene), "-o", str(bake_dir), *FAST]), progress=False)
    manifest = json.loads((bake_dir / "manifest.json").read_text())
    assert manifest["statistics"]["ignored_features"] == {"EXT_texture_webp": 1, "clearcoatTexture": 2}
    last = capsys.readouterr().err.splitlines()[-1]
    assert last.startswith("glint: the scene will look wrong where: ")
    assert last.endswith("ignored: EXT_texture_webp (1), clearcoatTexture (2)")

    assert main(["bake", str(scene), "-o", str(bake_dir), *FAST]) == 0  # up to date: still said, last
    out, err = capsys.readouterr()
    assert "up to date" in out and err.splitlines()[-1] == last


def test_texels_inside_geometry_named_at_the_end_of_a_bake(tmp_path, capsys):
    """A lit room inside a bigger closed room: the outer room's walls see the inner room's backs
    (single-sided), so most texels are inside geometry, past the bake's warning share (30 %); the
    last line gives the share as the manifest counts it. A well-made room (conftest's) gets no such line: its
    share, chart borders and contacts, stays under the warning's. Deliberate bugs this catches
    (tried): the share given as a fraction, not a percentage ("0.0 %"); the line printed for any
    share (the good room's 17 %)."""
    w = GltfWriter()
    wall = w.add_material("Wall", base_color=(0.7, 0.7, 0.7), roughness=1.0)
    outer = {f"Outer {name}": ((c[0], c[1] - 0.5, c[2]), u, v, m)
             for name, (c, u, v, m) in room_faces(1.5, 3.0, wall, wall).items()}
    lamp = w.add_material("Lamp", emissive=(1, 1, 1), emissive_strength=8.0)
    w.add_quads({**room_faces(1.0, 2.0, wall, wall), **outer, "Lamp": ((0, 1.99, 0), (0.25, 0, 0), (0, 0, 0.25), lamp)},
                normals=True)
    scene = w.write(tmp_path / "nested.glb")
    assert main(["bake", str(scene), "-o", str(tmp_path / "io.bake"), *FAST]) == 0
    lightmaps = json.loads((tmp_path / "io.bake" / "manifest.json").read_text())["statistics"]["lightmaps"]
    share = 100 * lightmaps["invalid_texels"] / lightmaps["texels"]
    assert share > 30
    last = capsys.readouterr().err.splitlines()[-1]
    assert last.startswith(f"glint: the scene will look wrong where: {share:.1f} % of light-map texels "
                           "lie inside geometry (filled from their neighbours)"), last
    good = write_room(tmp_path / "room.glb")
    assert main(["bake", str(good), "-o", str(tmp_path / "room.bake"), *FAST]) == 0
    assert "look wrong" not in capsys.readouterr().err


def test_warnings_are_shown_when_the_command_then_fails(tmp_path, capsys):
    """A scene without light fails after loading: the summary of its flat objects still comes,
    before the error, which is the last line. Deliberate bug this catches (tried):
    `summarised` printing its summaries only when its block ends normally (no summary line)."""
    w, wall = room_writer(light=0.0)
    add_degenerate_objects(w, wall)
    scene = w.write(tmp_path / "dark.glb")
    assert main(["bake", str(scene), "-o", str(tmp_path / "d.bake"), *FAST]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(warning_lines("\n".join(lines), "zero-area")) == 1
    assert len(warning_lines("\n".join(lines), "no triangles with area")) == 1
    assert lines[-1].startswith("glint: dark.glb: the scene has no light")
    assert not (tmp_path / "d.bake").exists()


KIND = WarningKind("{n} things are odd ({odd:,} odd parts)")


def test_summary_line_counts_subjects_and_sums(capsys):
    """The collector itself: plain warnings print at once, kinded ones once per kind when the
    block ends (also on an error), each subject counted once; outside any block (a library
    caller) a kinded warning prints at once. Deliberate bugs this catches (tried): kinded
    warnings outside a block kept pending (never printed); a subject warned twice counted twice."""
    with pytest.raises(RuntimeError):
        with summarised():
            for k in range(5):
                warn(f"thing {k} is odd", KIND, f"t{k}", detail=str(k), counts={"odd": 1000 * k})
            warn("thing 4 is odd again", KIND, "t4", counts={"odd": 1})
            warn("plain")
            assert capsys.readouterr().err == "glint: warning: plain\n"
            raise RuntimeError
    assert capsys.readouterr().err == ("glint: warning: 5 things are odd (10,001 odd parts): "
                                       "'t0' (0), 't1' (1), 't2' (2), ... and 2 more\n")
    with summarised():
        warn("only one", KIND, "t0")
    assert capsys.readouterr().err == "glint: warning: only one\n"  # one subject: the message itself
    warn("outside", KIND, "t0")
    assert capsys.readouterr().err == "glint: warning: outside\n"


def test_every_ignored_feature_is_warned_about_and_counted(tmp_path, capsys):
    """What glint does not support, and used to ignore silently, warns and is counted in
    Scene.ignored_features (-> the end-of-bake line): skins, morph targets
    with weights, animations, light range, a volume's thickness texture, a textured
    material on an object without the texture coordinates it names. Deliberate bug this catches (tried): the
    morph targets' warning without `ignored=` (morph targets missing from the counts)."""
    from glint.bake.gltf_loader import load_scene

    w, wall = room_writer()
    texture = w.add_texture(np.full((2, 2, 3), 128, np.uint8))
    w.materials[wall]["pbrMetallicRoughness"]["baseColorTexture"] = {"index": texture}
    w.materials[wall]["extensions"] = {"KHR_materials_volume": {"thicknessFactor": 0.1,
                                                                "thicknessTexture": {"index": texture}}}
    w.extensions_used.add("KHR_materials_volume")
    node = {n["name"]: n for n in w.nodes}
    back = w.meshes[node["Back"]["mesh"]]
    attributes = back["primitives"][0]["attributes"]
    back["primitives"][0]["targets"] = [{"POSITION": attributes["NORMAL"]}]
    back["weights"] = [0.5]
    node["Left"]["skin"] = 0
    w.add_node("Bulb", light=w.add_light("Bulb", "point", intensity=10.0, range=5.0), translation=(0, 1, 0))
    path = w.write(tmp_path / "unsupported.gltf")
    doc = json.loads(path.read_text())  # the writer has no skins or animations
    doc["skins"] = [{"joints": [0]}]
    doc["animations"] = [{"channels": [], "samplers": []}]
    path.write_text(json.dumps(doc))

    scene = load_scene(path)
    assert scene.ignored_features == {
        "animations": 1, "thicknessTexture": 1, "skins": 1,
        "morph targets": 1, "light range": 1}
    err = capsys.readouterr().err
    for words in ("animation(s) not played", "thicknessTexture not supported",
                  "'Left' is skinned", "'Back' has morph target weights",
                  "light 'Bulb': range", "objects have a textured material but not the texture coordinates"):
        assert words in err, words


def test_nested_blocks_close_in_any_state():
    """An inner block that ends with the same (empty) record as the outer one, then a warning in
    the outer block: the outer block must still close. Catches records compared by value
    (dataclass equality), which removed the outer record at the inner block's end and failed
    `glint bake` of an external scene at its very end ("list.remove(x): x not in list")."""
    kind = WarningKind("{n} things are odd")
    with summarised() as outer:
        with summarised() as inner:
            pass
        warn("thing a is odd", kind, "a")
        warn("thing b is odd", kind, "b")
    assert len(outer.warnings) == 2 and not inner.warnings
