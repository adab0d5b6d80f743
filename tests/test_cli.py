"""The `glint` command line: help, scene listing, and one-line errors with nothing written."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import NOT_ERRORS, quad, write_room

from glint.core.image_io import read_image
from glint.scenes.gltf_writer import GltfWriter


def glint(*args, cwd=None, env=None):
    return subprocess.run([sys.executable, "-m", "glint", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=300, env=None if env is None else {**os.environ, **env})


def assert_one_line_error(result, *words):
    assert result.returncode == 2, result.stderr
    lines = [l for l in result.stderr.strip().splitlines() if not l.startswith(NOT_ERRORS)]
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("glint: ") and "Traceback" not in result.stderr
    for word in words:
        assert word.lower() in lines[0].lower(), lines[0]


def test_help_explains_commands():
    result = glint("--help")
    assert result.returncode == 0
    assert "bake" in result.stdout and "scenes" in result.stdout
    bake_help = glint("bake", "--help").stdout
    for option in ("--quality", "--samples", "--texels-per-metre", "--jobs", "--out", "--force"):
        assert option in bake_help


def test_scenes_lists_builtins():
    result = glint("scenes")
    assert result.returncode == 0
    assert "cornell-box" in result.stdout and "living-room" in result.stdout


def test_unknown_scene_name(tmp_path):
    assert_one_line_error(glint("bake", "no-such-scene", cwd=tmp_path), "no-such-scene", "cornell-box")


def test_missing_file(tmp_path):
    assert_one_line_error(glint("bake", tmp_path / "missing.glb"), "missing.glb", "no such file")
    assert list(tmp_path.iterdir()) == []


def test_malformed_gltf(tmp_path):
    bad = tmp_path / "broken.glb"
    bad.write_bytes(b"glTF\x02\x00\x00\x00garbage")
    assert_one_line_error(glint("bake", bad), "broken.glb")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken.glb"]


def test_scene_without_light(tmp_path):
    w = GltfWriter()
    m = w.add_material("Grey")
    p, i = quad((0, 0, 0), (1, 0, 0), (0, 0, -1))
    w.add_node("Floor", mesh=w.add_mesh("Floor", p, i, m))
    path = w.write(tmp_path / "dark.glb")
    assert_one_line_error(glint("bake", path), "light")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dark.glb"]


def test_bad_option_values(tmp_path):
    """A mistake on the command line is one line naming the option and the value, exit 2, not
    argparse's usage block (glint/cli.py ArgumentParser.error). Deliberate bug tried: the plain
    argparse.ArgumentParser: the usage block fails `assert len(lines) == 1`."""
    for args, words in ((("--samples", "0"), ("--samples", "at least 1", "not 0")),
                        (("--quality", "ultra"), ("--quality", "invalid choice", "ultra")),
                        (("--texels-per-metre", "-1"), ("--texels-per-metre", "above 0", "not -1")),
                        (("--jobs", "x"), ("--jobs", "whole number", "'x'")),
                        (("-j", "-1"), ("--jobs", "at least 0", "not -1")),
                        (("--frobnicate",), ("unrecognized arguments", "--frobnicate"))):
        result = glint("bake", "cornell-box", *args, "-o", tmp_path / "x.bake")
        assert_one_line_error(result, "glint: bake: ", *words)
        assert "usage:" not in result.stderr
    assert_one_line_error(glint("bake"), "required", "SCENE")
    assert_one_line_error(glint("capture", "cornell-box"), "required", "-o/--output")
    assert_one_line_error(glint("frob"), "invalid choice", "frob", "glint --help")
    assert not (tmp_path / "x.bake").exists()


def test_debug_shows_traceback(tmp_path):
    result = glint("bake", tmp_path / "missing.glb", "--debug")
    assert result.returncode == 2 and "Traceback" in result.stderr


def test_bake_then_up_to_date(tmp_path):
    path = write_room(tmp_path / "room.glb")
    args = ("bake", path, "--samples", "4", "--texels-per-metre", "5", "--no-denoise")
    first = glint(*args)
    assert first.returncode == 0, first.stderr
    assert (tmp_path / "room.bake" / "manifest.json").exists()
    second = glint(*args)
    assert second.returncode == 0 and "up to date" in second.stdout


@pytest.mark.slow
def test_bake_living_room_preview(tmp_path):
    """`glint bake living-room --quality preview`, the README's first bake, end to end on the CI machine."""
    out = tmp_path / "lr.bake"
    result = glint("bake", "living-room", "--quality", "preview", "-o", out)
    assert result.returncode == 0, result.stderr
    manifest = json.loads((out / "manifest.json").read_text())
    assert len(manifest["objects"]) >= 20
    assert manifest["statistics"]["lightmaps"]["rays"] > 1e6
    roles = {o["role"] for o in manifest["objects"]}
    assert roles == {"diffuse", "curved", "planar", "transmissive"}
    for page in manifest["lightmaps"]:
        image = read_image(out / page)
        assert np.all(np.isfinite(image)) and image.min() >= 0
        assert image[..., :3].max() > 0.1
    again = glint("bake", "living-room", "--quality", "preview", "-o", out)
    assert again.returncode == 0 and "up to date" in again.stdout


@pytest.mark.parametrize("command", ["capture", "view"])
def test_unknown_camera_is_reported_before_the_bake(tmp_path, command):
    """`--camera nope` is one line naming the cameras there are, and nothing is baked. Catches
    the check made after the bake (it was: a typo cost a whole bake of a big scene first)."""
    scene = write_room(tmp_path / "room.glb")
    out = ["-o", str(tmp_path / "x.png")] if command == "capture" else []
    result = glint(command, scene, "--camera", "nope", *out, "--bake-dir", tmp_path / "room.bake",
                   env={"DISPLAY": ":0"} if command == "view" else None)
    assert_one_line_error(result, "unknown camera 'nope'", "Camera")
    assert not (tmp_path / "room.bake").exists()
