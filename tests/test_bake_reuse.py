"""`capture`, `view` and `bench` use the bake the user made as it is (glint/services.py settings_for).

A draft bake captured without `-q draft` used to be re-baked at the default preset, silently.
Now an existing bake keeps its own settings; it is redone only for explicit bake options or a
changed scene, and then one line on stderr says why, before the work.

Deliberate bugs these catch (tried): `settings_for` returning the preset settings as before
(the first test sees the manifest's light maps rewritten at 16 texels/m instead of 6); an
`announce` that is never called (the stale tests find no line).
"""
from __future__ import annotations

import json

from conftest import write_room

from glint.cli import main

DRAFT = ["-q", "draft", "--samples", "8", "--texels-per-metre", "6", "--no-denoise"]
SIZE = ["--size", "32x24", "--supersample", "1"]


def manifest(bake_dir):
    return json.loads((bake_dir / "manifest.json").read_text())


def baked(tmp_path, capsys):
    scene = write_room(tmp_path / "room.glb")
    bake_dir = tmp_path / "room.bake"
    assert main(["bake", str(scene), *DRAFT, "-o", str(bake_dir), "-j", "1"]) == 0
    capsys.readouterr()
    return scene, bake_dir


def capture(scene, bake_dir, out, *extra):
    return main(["capture", str(scene), "-o", str(out), "--bake-dir", str(bake_dir), *SIZE, *map(str, extra)])


def test_a_draft_bake_is_captured_as_it_is(tmp_path, capsys):
    scene, bake_dir = baked(tmp_path, capsys)
    before = (bake_dir / "manifest.json").stat().st_mtime_ns, manifest(bake_dir)
    assert capture(scene, bake_dir, tmp_path / "a.png", "--stats", tmp_path / "s.json") == 0
    err = capsys.readouterr().err
    assert "stale" not in err
    assert (bake_dir / "manifest.json").stat().st_mtime_ns == before[0]
    assert manifest(bake_dir) == before[1]
    assert manifest(bake_dir)["settings"]["texels_per_metre"] == 6.0
    assert json.loads((tmp_path / "s.json").read_text())["bake"] == "up-to-date"


def test_an_explicit_option_re_bakes_and_says_why(tmp_path, capsys):
    scene, bake_dir = baked(tmp_path, capsys)
    assert capture(scene, bake_dir, tmp_path / "a.png", "--samples", "4") == 0
    stale = [line for line in capsys.readouterr().err.splitlines() if "stale" in line]
    assert len(stale) == 1, stale
    assert "samples 8 -> 4" in stale[0] and str(bake_dir) in stale[0]
    settings = manifest(bake_dir)["settings"]
    assert settings["samples"] == 4 and settings["texels_per_metre"] == 6.0  # the rest kept


def test_a_changed_scene_re_bakes_with_the_bake_s_own_settings(tmp_path, capsys):
    scene, bake_dir = baked(tmp_path, capsys)
    write_room(scene, kd=(0.5, 0.6, 0.7))
    assert capture(scene, bake_dir, tmp_path / "a.png") == 0
    stale = [line for line in capsys.readouterr().err.splitlines() if "stale" in line]
    assert len(stale) == 1 and "kd of Wall" in stale[0], stale
    m = manifest(bake_dir)
    assert m["settings"]["samples"] == 8 and m["settings"]["quality"] == "draft"
    assert m["statistics"]["last_bake"]["light_maps"] == "re-baked"
    assert m["statistics"]["last_bake"]["unwrap"] == "reused"  # only what changed


def test_glint_bake_itself_applies_its_presets(tmp_path, capsys):
    """`glint bake` without -q means the default preset, as it always did; it says why it re-bakes."""
    scene, bake_dir = baked(tmp_path, capsys)
    assert main(["bake", str(scene), "-o", str(bake_dir), "--samples", "8", "--no-denoise", "-j", "1"]) == 0
    err = capsys.readouterr().err
    assert "texels_per_metre 6.0 -> 16.0" in err
    assert manifest(bake_dir)["settings"]["quality"] == "preview"
