"""A bake is up to date when the scene's content, the settings and glint's stage versions are the
same (bake/pipeline.py same_inputs), wherever the files lie; a stale bake's line names what changed
(core/skipped.py stale_reason).

Found on main before: a sidecar holding only a comment made a bake "stale (made by an older
glint)" (the scene hash took the sidecar's bytes; nothing in the manifest's comparison named the
change); a bake moved to another folder or install was stale the same way (the manifest's
absolute `scene.source` was compared); on another machine derived floats (camera and light
directions through trig and BLAS) differing in the last bit made it "stale (changed: lights,
cameras)" and re-baked the light maps (the up-to-date check compared them exactly).

Deliberate bugs tried (each fails the test named): the sidecar's bytes hashed instead of its TOML
content (test_a_sidecar_with_only_a_comment_is_no_change); `scene.source` compared in same_inputs
(test_a_bake_moved_with_its_scene_is_up_to_date, both cases); same_inputs back to comparing the
whole manifest (test_last_bit_differences_of_derived_floats_are_no_change, and the naming test); VERSION_NAMES'
stale_reason back to its fixed "made by an older glint" without the version
(test_a_new_integrator_version_says_which); cameras compared exactly in changed_inputs
(test_a_camera_a_last_bit_apart_is_not_named).
"""
from __future__ import annotations

import json
import shutil

import numpy as np
from conftest import write_room

from glint.bake import gltf_loader, gltf_scene, hashing, pipeline
from glint.cli import main

DRAFT = ["-q", "draft", "--samples", "8", "--texels-per-metre", "6", "--no-denoise", "-j", "1"]
CAMERA = '[cameras.Door]\neye = [0, 1, 0.5]\ntarget = [0, 1, -1]\nyfov = 50\n'


def files(bake_dir):
    """{relative path: (mtime_ns, bytes)} of every file of a bake dir: what "no file touched" compares."""
    return {str(p.relative_to(bake_dir)): (p.stat().st_mtime_ns, p.read_bytes())
            for p in sorted(bake_dir.rglob("*")) if p.is_file()}


def bake(scene, bake_dir, capsys, *extra):
    assert main(["bake", str(scene), *DRAFT, "-o", str(bake_dir), *extra]) == 0
    captured = capsys.readouterr()
    return captured.out + captured.err


def stale_line(output):
    lines = [line for line in output.splitlines() if " is stale (" in line]
    assert len(lines) == 1, output
    return lines[0]


def test_a_sidecar_with_only_a_comment_is_no_change(tmp_path, capsys):
    """A sidecar that appears with nothing but a comment changes nothing the bake reads: up to date,
    no file touched. Catches the scene hash taking the sidecar's bytes (was: "stale (made by an
    older glint)" and a rewritten manifest)."""
    scene = write_room(tmp_path / "room.glb")
    out = tmp_path / "room.bake"
    bake(scene, out, capsys)
    before = files(out)
    (tmp_path / "room.glint.toml").write_text("# note\n")
    output = bake(scene, out, capsys)
    assert "up to date, nothing to do" in output and "stale" not in output
    assert files(out) == before


def test_a_bake_moved_with_its_scene_is_up_to_date(tmp_path, capsys):
    """Scene, sidecar and bake dir copied to another folder: `glint bake` and `glint capture` there
    find the bake up to date and touch no file; and a built-in's case, the same bake dir found from
    a scene file at another path (another install). Catches the absolute `scene.source` in the
    up-to-date comparison."""
    a, b = tmp_path / "a", tmp_path / "elsewhere" / "b"
    a.mkdir()
    scene = write_room(a / "room.glb", sidecar=CAMERA)
    bake(scene, a / "room.bake", capsys)
    shutil.copytree(a, b)
    before = files(b / "room.bake")
    output = bake(b / "room.glb", b / "room.bake", capsys)
    assert "up to date, nothing to do" in output and "stale" not in output
    assert main(["capture", str(b / "room.glb"), "-o", str(tmp_path / "c.png"), "--bake-dir", str(b / "room.bake"),
                 "--size", "16x12", "--supersample", "1"]) == 0
    assert "stale" not in capsys.readouterr().err
    assert files(b / "room.bake") == before
    assert json.loads((b / "room.bake" / "manifest.json").read_text())["scene"]["source"] == str(scene)  # for information

    # another install: the package's scene file at another path, the cache's bake dir the same
    install = tmp_path / "site-packages" / "glint" / "scenes"
    install.mkdir(parents=True)
    shutil.copy(scene, install / "room.glb")
    shutil.copy(a / "room.glint.toml", install / "room.glint.toml")
    before = files(a / "room.bake")
    output = bake(install / "room.glb", a / "room.bake", capsys)
    assert "up to date, nothing to do" in output and "stale" not in output
    assert files(a / "room.bake") == before


def test_last_bit_differences_of_derived_floats_are_no_change(tmp_path, capsys, monkeypatch):
    """Another machine (libm, BLAS) may compute node transforms, camera and light directions a last
    bit differently from the same bytes: every node's translation nudged by one ulp here moves every
    vertex and the camera (the geometry hash and the manifest's cameras differ), yet the scene's
    bytes, settings and versions are the same: up to date, no file touched. Catches an up-to-date
    check on derived values (was: "stale (changed: lights, cameras)", light maps re-baked)."""
    scene = write_room(tmp_path / "room.glb", sidecar=CAMERA)
    out = tmp_path / "room.bake"
    bake(scene, out, capsys)
    before = files(out)
    old_geometry = json.loads((out / "manifest.json").read_text())["stages"]["geometry"]
    original = gltf_scene.local_matrix

    def nudged(node, where="node"):
        m = original(node, where)
        m[:3, 3] = np.nextafter(m[:3, 3], np.inf)
        return m

    monkeypatch.setattr(gltf_scene, "local_matrix", nudged)
    settings = pipeline.BakeSettings(samples=8, texels_per_metre=6.0, denoise=False, quality="draft")
    assert hashing.geometry_hash(gltf_loader.load_scene(scene), settings) != old_geometry  # the nudge is real
    output = bake(scene, out, capsys)
    assert "up to date, nothing to do" in output and "stale" not in output
    assert files(out) == before


def test_stale_lines_name_the_sidecar_and_the_object(tmp_path, capsys):
    """The sidecar's changed tables and the object whose content changed are named; a role change
    still redoes only the manifest (docs/ARCHITECTURE.md, "What invalidates what")."""
    scene = write_room(tmp_path / "room.glb", sidecar=CAMERA)
    out = tmp_path / "room.bake"
    bake(scene, out, capsys)
    lightmaps = {p.name: p.read_bytes() for p in (out / "lightmaps").iterdir()}
    (tmp_path / "room.glint.toml").write_text(CAMERA + '[objects.Box]\nrole = "diffuse"\n')
    output = bake(scene, out, capsys)
    assert "is stale (changed: sidecar room.glint.toml changed ([objects.Box])): re-baking" in stale_line(output)
    assert "light maps up to date; manifest updated" in output
    assert {p.name: p.read_bytes() for p in (out / "lightmaps").iterdir()} == lightmaps

    (tmp_path / "room.glint.toml").unlink()
    line = stale_line(bake(scene, out, capsys))
    assert "sidecar room.glint.toml disappeared ([cameras.Door], [objects.Box])" in line, line

    (tmp_path / "room.glint.toml").write_text('[objects.Box]\nrole = "curved"\n')
    line = stale_line(bake(scene, out, capsys))
    assert "changed: sidecar room.glint.toml appeared ([objects.Box])" in line, line
    (tmp_path / "room.glint.toml").write_text('[objects.Box]\nrole = "diffuse"\n')
    line = stale_line(bake(scene, out, capsys))
    assert "changed: sidecar room.glint.toml changed ([objects.Box] role)" in line, line

    write_room(scene, box_height=0.8)
    line = stale_line(bake(scene, out, capsys))
    assert "changed: positions of Box" in line and "older glint" not in line, line


def test_a_new_integrator_version_says_which(tmp_path, capsys, monkeypatch):
    """"made by an older glint" only where a stage version differs, and which: the light maps are
    re-baked, the unwrap kept."""
    scene = write_room(tmp_path / "room.glb")
    out = tmp_path / "room.bake"
    bake(scene, out, capsys)
    monkeypatch.setattr(hashing, "TRANSPORT_VERSION", hashing.TRANSPORT_VERSION + 1)
    output = bake(scene, out, capsys)
    version = hashing.TRANSPORT_VERSION
    assert f"is stale (made by an older glint (light-map integrator version {version - 1} -> {version}))" \
        in stale_line(output)
    assert "baked light maps" in output
    assert json.loads((out / "manifest.json").read_text())["inputs"]["versions"]["transport"] == version


def test_a_new_gltf_fit_table_makes_the_bake_stale(tmp_path, capsys, monkeypatch):
    """A new glTF fit table (bake/gltf_fit_table.npz) maps the same glTF file to other lobes: the bake is
    stale and says why, though the scene's files are the same bytes. Deliberate bug this catches
    (tried): stage_versions without the table's version (the bake found up to date, its manifest
    keeping the old table's lobes)."""
    scene = write_room(tmp_path / "room.glb")
    out = tmp_path / "room.bake"
    bake(scene, out, capsys)
    old = hashing.gltf_table_version()
    monkeypatch.setattr(hashing, "gltf_table_version", lambda: "0123456789ab")
    output = bake(scene, out, capsys)
    assert f"glTF material fit table {old} -> 0123456789ab" in stale_line(output)
    assert json.loads((out / "manifest.json").read_text())["inputs"]["versions"]["gltf_table"] == "0123456789ab"


def test_a_manifest_without_inputs_stays_readable(tmp_path, capsys):
    """A bake dir written before `inputs` existed: up to date when nothing changed, and a changed
    setting is named as such, not as an older glint."""
    scene = write_room(tmp_path / "room.glb")
    out = tmp_path / "room.bake"
    bake(scene, out, capsys)
    path = out / "manifest.json"
    manifest = json.loads(path.read_text())
    del manifest["inputs"]
    manifest["scene"]["hash"] = "0" * 32  # the old hash of the files' bytes
    path.write_text(json.dumps(manifest))
    assert "up to date, nothing to do" in bake(scene, out, capsys)
    line = stale_line(bake(scene, out, capsys, "--samples", "4"))
    assert "changed: bake settings (samples 8 -> 4)" in line and "older glint" not in line, line


def test_a_camera_a_last_bit_apart_is_not_named(tmp_path, capsys):
    """When something did change (a setting), a camera direction computed a last bit differently on
    another machine is not named with it. Catches stale_reason comparing derived floats exactly
    (was: "changed: ..., cameras" for a camera nobody moved)."""
    from glint.core.manifest import Manifest
    from glint.core.skipped import stale_reason

    scene = write_room(tmp_path / "room.glb", sidecar=CAMERA)
    bake(scene, tmp_path / "room.bake", capsys)
    old = json.loads((tmp_path / "room.bake" / "manifest.json").read_text())
    new = json.loads(json.dumps(old))
    new["cameras"][0]["forward"] = [float(np.nextafter(x, 2.0)) for x in new["cameras"][0]["forward"]]
    new["settings"]["samples"] = 16
    assert new["cameras"] != old["cameras"]
    assert stale_reason(Manifest.from_json(old), Manifest.from_json(new)) == "changed: bake settings (samples 8 -> 16)"


def test_a_deleted_file_is_made_again_and_only_what_depends_on_it(tmp_path, capsys):
    """A bake with its inputs unchanged but a file gone (deleted by hand) is not "up to date": the
    stale line names the file, and the bake makes it again -- a cube map alone (the light maps and the
    other files untouched), a light map with the light maps. Catches the up-to-date check looking at
    the manifest only (was: "up to date, nothing to do", then `glint capture` stopping at "cube map: no
    such file")."""
    scene = write_room(tmp_path / "room.glb", sidecar='[objects."Box"]\nrole = "curved"\n')
    out = tmp_path / "room.bake"
    bake(scene, out, capsys)
    model = json.loads((out / "manifest.json").read_text())
    (cube,) = [o["cubemap"]["file"] for o in model["objects"] if o.get("cubemap")]
    light_map = model["lightmaps"][0]
    before = files(out)
    (out / cube).unlink()
    output = bake(scene, out, capsys)
    assert f"files missing: {cube}" in stale_line(output)
    record = json.loads((out / "manifest.json").read_text())["statistics"]["last_bake"]
    assert record["cube_maps_rendered"] == 1 and record["light_maps"] == "reused", record
    after = files(out)
    assert after[cube][1] == before[cube][1]  # the same bytes again
    assert {k: v for k, v in after.items() if k.startswith("lightmaps/")} == \
        {k: v for k, v in before.items() if k.startswith("lightmaps/")}  # not touched
    assert "up to date, nothing to do" in bake(scene, out, capsys)

    (out / light_map).unlink()
    output = bake(scene, out, capsys)
    assert f"files missing: {light_map}" in stale_line(output)
    assert (out / light_map).is_file()
    record = json.loads((out / "manifest.json").read_text())["statistics"]["last_bake"]
    assert record["light_maps"] == "re-baked" and record["why"] == f"files missing: {light_map}", record
