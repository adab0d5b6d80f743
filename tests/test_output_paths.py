"""glint never deletes, replaces or hides a file or directory it did not write.

A bake writes, replaces or removes only a directory that is absent, empty or a glint bake holding
nothing but its bake's files; anything else is refused before any work, in one line, with nothing
touched. A command's output files must be distinct and outside its bake directory."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import error_of

from glint.cli import main
from glint.core.atomic import atomic_write_text
from glint.core.bake_dir import BakeDirWriter
from glint.core.errors import GlintError

FAST = ["-q", "draft", "--samples", "4", "--texels-per-metre", "4", "--no-denoise", "-j", "1"]


def tree(root: Path) -> dict:
    """Every file under `root` (hidden ones too) with its bytes, and every directory."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames:
            out[os.path.relpath(os.path.join(dirpath, name), root)] = "<dir>"
        for name in filenames:
            path = os.path.join(dirpath, name)
            out[os.path.relpath(path, root)] = Path(path).read_bytes()
    return out


@pytest.fixture
def no_loading(monkeypatch):
    """A refusal must come before the scene is loaded: loading fails the test."""
    def fail(*a, **k):
        raise AssertionError("the scene was loaded before the refusal")
    monkeypatch.setattr("glint.services.open_scene", fail)


def dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_a_users_directory_is_refused_before_loading(tmp_path, room, capsys, no_loading):
    """Bug caught: `glint bake -o d` renamed d (the user's thesis.txt and all) away and deleted it."""
    d = tmp_path / "d"
    d.mkdir()
    (d / "thesis.txt").write_bytes(b"precious\n")
    (d / "data.csv").write_bytes(b"1,2\n")
    (d / "notes").mkdir()
    before = tree(tmp_path)
    line = error_of(capsys, main(["bake", str(room), "-o", str(d), *FAST]))
    assert line == (f"glint: {d} is not a glint bake directory (it holds data.csv, notes and 1 more); "
                    "give a new or empty directory with -o")
    assert (d / "thesis.txt").read_bytes() == b"precious\n"
    assert tree(tmp_path) == before  # no temporary directory, nothing renamed or hidden


def test_a_file_in_the_way_is_refused_not_hidden(tmp_path, room, capsys, no_loading):
    """Bug caught: an existing file given as -o was renamed to a hidden .NAME.old-PID."""
    f = tmp_path / "f"
    f.write_bytes(b"mine")
    before = tree(tmp_path)
    line = error_of(capsys, main(["bake", str(room), "-o", str(f), *FAST]))
    assert line == f"glint: {f} is a file, not a bake directory; give a new or empty directory with -o"
    assert tree(tmp_path) == before


@pytest.mark.parametrize("out", [".", ""])
def test_the_current_directory_is_refused(tmp_path, room, capsys, monkeypatch, no_loading, out):
    """Bug caught: `-o .` and `-o ""` baked first, then failed with `internal error: ValueError`."""
    monkeypatch.chdir(tmp_path)
    before = tree(tmp_path)
    line = error_of(capsys, main(["bake", str(room), "-o", out, *FAST]))
    assert line.startswith("glint: -o .: a bake replaces its directory as a whole")
    assert tree(tmp_path) == before


def test_capture_stats_over_its_image_is_refused(tmp_path, room, capsys, no_loading):
    """Bug caught: `capture -o s.png --stats s.png` wrote the JSON over the image and exited 0."""
    s = tmp_path / "s.png"
    line = error_of(capsys, main(["capture", str(room), "-o", str(s), "--stats", str(s),
                                  "--bake-dir", str(tmp_path / "b"), *FAST]))
    assert line == f"glint: -o {s} and --stats {s} are the same file; give them different names"
    assert sorted(os.listdir(tmp_path)) == ["room.glb"]


def test_capture_image_inside_its_bake_dir_is_refused(tmp_path, room, capsys, no_loading):
    """Bug caught: an image written into the bake directory, which the next bake replaces whole."""
    (tmp_path / "b").mkdir()
    line = error_of(capsys, main(["capture", str(room), "-o", str(tmp_path / "b" / "s.png"),
                                  "--bake-dir", str(tmp_path / "b"), *FAST]))
    assert line == (f"glint: -o {tmp_path / 'b' / 's.png'} is inside the bake directory {tmp_path / 'b'}, "
                    "which a bake replaces as a whole; write it elsewhere")
    assert sorted(os.listdir(tmp_path)) == ["b", "room.glb"] and not os.listdir(tmp_path / "b")


def test_bench_output_equal_to_its_bake_dir_is_refused(tmp_path, room, capsys, no_loading):
    """Bug caught: bench's -o DIR and --bake-dir DIR the same folder (bench files inside a bake)."""
    b = tmp_path / "b"
    line = error_of(capsys, main(["bench", str(room), "-o", str(b), "--bake-dir", str(b), *FAST]))
    assert line == f"glint: -o {b} is the bake directory {b}, which a bake replaces as a whole; write it elsewhere"
    assert not b.exists()


def test_a_bake_with_a_users_file_in_it_is_not_rebaked(tmp_path, room, capsys):
    """Bug caught: a re-bake deleted a file the user had put into the bake directory."""
    b = tmp_path / "room.bake"
    assert main(["bake", str(room), "-o", str(b), *FAST]) == 0
    (b / "notes.txt").write_bytes(b"keep me")
    before = tree(tmp_path)
    capsys.readouterr()
    line = error_of(capsys, main(["bake", str(room), "-o", str(b), "--force", *FAST]))
    assert line == (f"glint: {b} is a glint bake directory but also holds notes.txt, which a new bake would "
                    "delete; move it out, or give a new or empty directory with -o")
    assert tree(tmp_path) == before


def test_an_empty_directory_and_an_old_version_bake_are_written(tmp_path, room):
    """Bug caught: the rule refusing too much (an empty folder, or a bake of another format version)."""
    empty, old = tmp_path / "empty", tmp_path / "old"
    empty.mkdir()
    old.mkdir()
    (old / "manifest.json").write_text(json.dumps({"format": "glint-bake", "version": 0}))
    (old / "lightmaps").mkdir()
    (old / "lightmaps" / "page_0.exr").write_bytes(b"old")
    for d in (empty, old):
        assert main(["bake", str(room), "-o", str(d), *FAST]) == 0
        assert json.loads((d / "manifest.json").read_text())["version"] == 1
    assert sorted(os.listdir(tmp_path)) == ["empty", "old", "room.glb"]  # nothing set aside left


def test_the_writer_itself_refuses(tmp_path):
    """Bug caught: BakeDirWriter (the library API) replacing a user's directory, on entering or when a
    file appeared in the target during the bake (the commit's last check)."""
    d = tmp_path / "d"
    d.mkdir()
    (d / "thesis.txt").write_bytes(b"precious")
    with pytest.raises(GlintError, match="is not a glint bake directory"):
        with BakeDirWriter(d):
            pass
    e = tmp_path / "e"
    with pytest.raises(GlintError, match=r"is not a glint bake directory \(it holds thesis.txt\)"):
        with BakeDirWriter(e) as out:
            (out.path / "manifest.json").write_text('{"format": "glint-bake", "version": 1}')
            e.mkdir()
            (e / "thesis.txt").write_bytes(b"precious")
            out.commit()
    assert tree(tmp_path) == {"d": "<dir>", "d/thesis.txt": b"precious", "e": "<dir>", "e/thesis.txt": b"precious"}


def test_a_killed_bakes_temporaries_are_removed(tmp_path):
    """Bug caught: a SIGKILLed bake's .NAME.<pid>.<random>.tmp (and atomic .STEM.<pid>.tmp.EXT files)
    left for good; and the sweep must spare a live process's ones and names glint does not make."""
    gone, alive = dead_pid(), os.getppid()
    dead_tmp = tmp_path / f".b.{gone}.abcd_123.tmp"
    live_tmp = tmp_path / f".b.{alive}.abcd_123.tmp"
    users = [tmp_path / ".b.x.tmp", tmp_path / f".b.{gone}.tmp", tmp_path / f".c.{gone}.abcd_123.tmp"]
    for d in (dead_tmp, live_tmp, *users):
        (d / "lightmaps").mkdir(parents=True)
    with BakeDirWriter(tmp_path / "b") as out:
        (out.path / "manifest.json").write_text('{"format": "glint-bake", "version": 1}')
        out.commit()
    assert not dead_tmp.exists()
    assert live_tmp.is_dir() and all(d.is_dir() for d in users)

    dead_file, live_file = tmp_path / f".s.{gone}.tmp.png", tmp_path / f".s.{alive}.tmp.png"
    other = tmp_path / f".t.{gone}.tmp.png"
    for f in (dead_file, live_file, other):
        f.write_bytes(b"half")
    atomic_write_text(tmp_path / "s.png", "x")
    assert not dead_file.exists() and live_file.exists() and other.exists()


def test_a_commit_cut_between_its_renames_is_put_back(tmp_path):
    """Bug caught: a bake killed after setting the previous bake aside (.NAME.old-PID) and before moving
    the new one in: the next bake must put the previous one back (or remove it once replaced), never
    leave it hidden."""
    aside = tmp_path / f".b.old-{dead_pid()}"
    aside.mkdir()
    (aside / "manifest.json").write_text('{"format": "glint-bake", "version": 1, "mark": 1}')
    with BakeDirWriter(tmp_path / "b"):
        assert json.loads((tmp_path / "b" / "manifest.json").read_text())["mark"] == 1
    assert not aside.exists()
