"""Sidecar edits (bake/edits.py): `--set KEY=VALUE`, save_sidecar, and what an edit re-bakes."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from conftest import error_of, write_room

from glint.bake.edits import (
    apply_assignments,
    edited_bake_dir,
    format_assignment,
    material_assignments,
    parse_assignment,
    save_sidecar,
)
from glint.bake.gltf_loader import load_scene
from glint.bake.pipeline import describe
from glint.bake.sidecar import parse_sidecar, read_sidecar, sidecar_path
from glint.cli import main
from glint.core.bake_dir import Bake, default_bake_dir, read_manifest
from glint.core.errors import GlintError
from glint.core.image_io import read_image

# Draft bakes (conftest FAST) and small images: each capture takes a few seconds on llvmpipe.
BAKE_ARGS = ["-q", "draft", "--samples", "8", "--texels-per-metre", "6", "--no-denoise"]
# Looking down at the floor's (-x, -z) quarter, away from the box: the central pixels see floor only.
FLOOR_VIEW = ["--size", "48x48", "--eye", "-0.4,1.5,-0.4", "--target", "-0.5,0,-0.5", "--fov", "30",
              "--supersample", "1"]
FLOOR_EDIT = 'materials."Floor".kd=[0.35, 0.7, 0.14]'  # the room's kd 0.7 times (0.5, 1, 0.2)


def capture(scene: Path, out: Path, *extra: str) -> np.ndarray:
    assert main(["capture", str(scene), "-o", str(out), *FLOOR_VIEW, *BAKE_ARGS, *extra]) == 0
    return read_image(out)[..., :3] if out.suffix == ".exr" else out.read_bytes()


# -- (a) parsing, applying, one-line errors --------------------------------------------------------
def test_parse_assignment_reads_toml_keys_and_values():
    """Keys and values are TOML's (tomllib): quoted keys may hold '=' and dots, values any TOML
    value; format_assignment writes text that reads back the same. Splitting at the first '='
    (the obvious hand-written parser) refused the second case ("expected KEY=VALUE")."""
    assert parse_assignment('materials."Floor".kd=[0.3,0.2,0.1]') == (("materials", "Floor", "kd"), [0.3, 0.2, 0.1])
    assert parse_assignment('materials."a=b.c".emission = 2') == (("materials", "a=b.c", "emission"), 2)
    assert parse_assignment('bake = { samples = 4 }') == (("bake",), {"samples": 4})
    for keys, value in [(("materials", "Floor Tiles", "lobes"), [{"kind": "reflect", "m": 0.05}]),
                        (("bake", "quality"), "draft"), (("objects", 'Te"a', "role"), "curved")]:
        assert parse_assignment(format_assignment(keys, value)) == (keys, value)


@pytest.mark.parametrize("text, says", [
    ('materials."Floor".kd=nan', "kd must be a number or a list of 3 numbers (RGB) of at least 0, not nan"),
    ('materials."Floor".kd=[0.3, -0.2, 0.1]', "kd must be a number or a list of 3 numbers (RGB) of at least 0, not [0.3, -0.2, 0.1]"),
    ('materials."Floor".lobes=[{ m = -1 }]', "lobes[0] m must be a number of at least 0, not -1"),
    ('materials."Floor".lobes=[{ r0 = 1.5 }]', "r0 must be a number from 0 to 1, not 1.5"),
    ('objects."Box".role="shiny"', "role must be one of diffuse, curved, planar, transmissive, not 'shiny'"),
    ('bake.quality=draft', "strings need quotes"),
    ('bake.quality="fast"', "quality must be one of draft, preview, final"),
    ('materials."Floor".kdd=0.3', "unknown key 'kdd' (known: kd, emission, lobes)"),
    ('materials."Floor"=0.3', "must be a table"),
    ('materials."Floor".kd', "expected KEY=VALUE"),
])
def test_apply_refuses_what_the_sidecar_refuses_naming_the_set(text, says):
    """The edited sidecar goes through parse_sidecar: each bad value is one GlintError that names
    the --set text and says what is wrong. A sidecar typo only warns; a --set typo is refused
    (with apply_assignments' check for new warnings removed, the 'kdd' case raised nothing)."""
    with pytest.raises(GlintError) as err:
        apply_assignments({"bake": {"samples": 8}}, ['materials."Floor".kd=0.5', text])
    message = str(err.value)
    assert message.startswith(f"--set '{text}': ") and says in message and "\n" not in message, message


def test_apply_sets_keys_clamps_as_the_sidecar_and_keeps_the_rest():
    """The result is the sidecar dict with the keys set (the input untouched), and what
    parse_sidecar makes of it is what it makes of a file with those keys: m = 1e-6 is clamped
    to 1e-4, as the sidecar clamps it."""
    data = {"bake": {"samples": 8}, "materials": {"Floor": {"kd": 0.5, "emission": 0}}}
    out = apply_assignments(data, ['materials."Floor".kd=[0.3, 0.2, 0.1]', (("materials", "Wall", "lobes"),
                                                                             [{"m": 1e-6}]), "bake.seed=3"])
    assert out == {"bake": {"samples": 8, "seed": 3},
                   "materials": {"Floor": {"kd": [0.3, 0.2, 0.1], "emission": 0}, "Wall": {"lobes": [{"m": 1e-6}]}}}
    assert data["materials"]["Floor"]["kd"] == 0.5
    lobe = parse_sidecar(out, Path("x.glint.toml")).materials["Wall"]["lobes"][0]
    assert (lobe.mx, lobe.my) == (1e-4, 1e-4)


def test_set_on_the_command_line_one_line_errors(tmp_path, capsys):
    """`glint capture --set` with a bad value, or a material or object name the scene does not
    have, stops before any work with one line naming the --set (no bake directory appears)."""
    scene = write_room(tmp_path / "room.glb")
    for text, says in [('materials."Flor".kd=0.3', "no material is called 'Flor' (the scene has 'Floor', 'Lamp', 'Wall')"),
                       ('objects."Bx".role="curved"', "no object, node or mesh is called 'Bx'"),
                       ('materials."Floor".emission=[1, inf, 1]', "emission must be a number or a list of 3 numbers (RGB) of at least 0, not [1, inf, 1]")]:
        code = main(["capture", str(scene), "-o", str(tmp_path / "x.png"), "--set", text, *BAKE_ARGS])
        line = error_of(capsys, code)
        assert line.startswith(f"glint: --set '{text}': ") and says in line, line
    assert not list(tmp_path.glob("*.bake"))


# -- (b) save_sidecar ------------------------------------------------------------------------------
SIDECAR = '''# The room's sidecar: kept by hand.
[bake]
samples = 8  # enough for tests

# Floor: a warm grey
[materials."Floor"]
kd = 0.5  # measured

[objects."Box"]
role = "diffuse"
'''


def test_save_sidecar_keeps_comments_and_other_keys(tmp_path):
    """save_sidecar edits the file in place: every comment line, the other keys and their order
    stay; read_sidecar of the result equals parse_sidecar of apply_assignments (what --set gives).
    Written from the edited dict (tomlkit.dumps of apply_assignments' result) instead of the
    parsed document, every comment was lost and the test failed on the first one."""
    scene = write_room(tmp_path / "room.glb", sidecar=SIDECAR)
    edits = ['materials."Floor".kd=[0.3, 0.2, 0.1]', 'materials."Wall".lobes=[{ kind = "reflect", m = 0.05 }]',
             'bake.seed=7', 'objects."Box".role="curved"', 'sky.radiance=0.5']
    path = save_sidecar(scene, edits)
    text = path.read_text()
    assert path == sidecar_path(scene)
    for line in ("# The room's sidecar: kept by hand.", "samples = 8  # enough for tests", "# Floor: a warm grey",
                 "kd = [0.3, 0.2, 0.1]  # measured"):
        assert line in text, text
    assert text.index("samples = 8") < text.index("seed = 7") < text.index("# Floor") < text.index("[objects")
    import tomllib
    expected = parse_sidecar(apply_assignments(tomllib.loads(SIDECAR), edits, path=path), path)
    got = read_sidecar(scene)
    for field in ("bake", "objects", "units"):
        assert getattr(got, field) == getattr(expected, field)
    assert got.sky.radiance.tolist() == expected.sky.radiance.tolist() == [0.5] * 3
    assert got.materials.keys() == expected.materials.keys() == {"Floor", "Wall"}
    assert got.materials["Floor"]["kd"].tolist() == expected.materials["Floor"]["kd"].tolist()
    assert got.materials["Wall"]["lobes"] == expected.materials["Wall"]["lobes"]


def test_save_sidecar_creates_validates_and_never_half_writes(tmp_path):
    """Without a sidecar, save_sidecar creates one; a bad assignment writes nothing."""
    scene = write_room(tmp_path / "room.glb")
    assert save_sidecar(scene, ['materials."Floor".kd=0.25']).read_text() == '[materials.Floor]\nkd = 0.25\n'
    with pytest.raises(GlintError, match=r"kd must be a number or a list of 3 numbers \(RGB\) of at least 0, not -1"):
        save_sidecar(scene, ['materials."Wall".kd=0.5', 'materials."Floor".kd=-1'])
    assert sidecar_path(scene).read_text() == '[materials.Floor]\nkd = 0.25\n'
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


# -- material entries (the viewer's panel edits them) ---------------------------------------------
def test_material_assignments_round_trip_through_the_loader(tmp_path):
    """A bake-manifest material entry -> material_assignments -> load_scene(edits) -> describe
    gives the entry back exactly (kd, emission and lobes, float32 colours written as 0.7, not
    0.699999988079071); an edited entry (another kd, a lobe with another mx: (d), the lobe edit
    through the manifest entry it produces) comes back as edited, the other materials unchanged.
    With the edits dropped in bake/edits.py edited_sidecar (the unedited sidecar parsed) the
    edited lobe came back with mx 0.05, not 0.3."""
    lobes = [{"kind": "reflect", "ks": [0.5, 0.4, 0.3], "mx": 0.05, "my": 0.2, "r0": 0.04, "alpha": 0.5}]
    scene = write_room(tmp_path / "room.glb", floor_lobes=lobes)

    def entries_of(assignments=None):  # without the glTF factors, which an assignment drops by design
        return [{k: v for k, v in m.to_json().items() if k != "gltf"}
                for m in describe(load_scene(scene, assignments or ()))["materials"]]

    entries = entries_of()
    for entry in entries:
        assert entries_of(material_assignments(entry["name"], entry)) == entries
    floor = next(e for e in entries if e["name"] == "Floor")
    key, kd = material_assignments("Floor", floor)[0]
    assert key == ("materials", "Floor", "kd") and (np.float32(kd) == np.float32(floor["kd"])).all()
    assert all(len(repr(v)) <= 10 for v in kd), kd  # float32's shortest digits, not 0.699999988079071
    edited = {**floor, "kd": [0.2, 0.3, 0.4], "lobes": [{**lobes[0], "mx": 0.3}]}
    again = entries_of(material_assignments("Floor", edited))
    got = next(e for e in again if e["name"] == "Floor")
    f32 = [float(np.float32(v)) for v in (0.2, 0.3, 0.4)]  # colours are float32 in the bake
    assert got["lobes"] == [{**lobes[0], "ks": [float(np.float32(v)) for v in (0.5, 0.4, 0.3)], "mx": 0.3}]
    assert got["kd"] == f32
    assert [e for e in again if e["name"] != "Floor"] == [e for e in entries if e["name"] != "Floor"]


# -- (c) an edited capture: pixels as L = kd/pi E predicts, bakes kept apart ------------------------
@pytest.mark.slow
def test_set_kd_scales_the_floor_as_kd_over_pi_times_e(tmp_path):
    """`glint capture --set 'materials."Floor".kd=...'` against the unedited capture, floor only.

    The floor's radiance is kd/pi * E (Eq. 4.1; its lobe is dropped: roughness 1). E itself
    depends on the floor's kd through the bounce light (floor -> walls -> floor), so the sidecar
    caps paths at one bounce ([bake] max_depth = 1: the light map is the direct irradiance, which
    no kd changes) and the test checks that: the edited bake's light-map pages equal the
    unedited bake's exactly. Then every floor pixel's ratio edited / unedited is the kd ratio
    (0.35, 0.7, 0.14) / the loaded kd (0.7 mapped: x the diffuse share, + the dropped lobe): measured
    within 1.8e-8 (float32 rounding), tolerance 1e-4; with all bounces
    (max_depth 64) the floor's own kd changes E and the deviation was 0.118. The edited scene
    bakes beside the unedited one (room.edit-<hash>.bake), starting from it: the unwrap is
    reused, the light maps re-baked (a kd edit changes the transport hash), room.bake untouched.
    With the edits dropped in bake/edits.py edited_sidecar (the unedited sidecar parsed) the
    deviation was 0.8 (blue ratio 1, not 0.2); with glint.services.run_bake passing no `seed`,
    the edited bake redid the unwrap ("redone", not "reused")."""
    scene = write_room(tmp_path / "room.glb", sidecar="[bake]\nmax_depth = 1\n")
    plain = capture(scene, tmp_path / "plain.exr")
    base = default_bake_dir(scene)
    before = {p.name: p.stat().st_mtime_ns for p in base.rglob("*")}
    edited = capture(scene, tmp_path / "edited.exr", "--set", FLOOR_EDIT)
    assert {p.name: p.stat().st_mtime_ns for p in base.rglob("*")} == before  # the unedited bake untouched

    centre = (slice(12, 36), slice(12, 36))
    ratio = edited[centre] / plain[centre]
    assert plain[centre].min() > 1e-3  # lit floor, no black
    floor_kd = next(m.kd for m in load_scene(scene).materials if m.name == "Floor")  # the glTF mapping's
    expected = np.array([0.35, 0.7, 0.14]) / floor_kd
    assert np.abs(ratio - expected).max() < 1e-4, ratio.reshape(-1, 3)[:3]

    edit_dir = edited_bake_dir(base, load_scene(scene, [FLOOR_EDIT]).edits)
    record = read_manifest(edit_dir)["statistics"]["last_bake"]
    assert (record["unwrap"], record["light_maps"]) == ("reused", "re-baked"), record
    a, b = Bake(base), Bake(edit_dir)
    for page in range(len(a.manifest["lightmaps"])):
        assert np.array_equal(a.lightmap(page), b.lightmap(page))


# -- (e) --set, saved, then a plain capture: the same bytes ---------------------------------------
@pytest.mark.slow
def test_saved_edits_capture_as_the_set_capture(tmp_path):
    """--set, then save_sidecar of the same assignments, then a plain `glint capture` (which
    re-bakes room.bake from the saved sidecar): the PNG is byte-identical to the --set capture's.
    The edits include a lobe on the floor (glossy: cube maps, patterns), an emission and a role;
    the --set bake starts from the unedited room.bake. With the edits dropped in bake/edits.py
    edited_sidecar, the --set PNG equalled the unedited one and differed from the saved one."""
    scene = write_room(tmp_path / "room.glb", sidecar="# mine\n[bake]\nseed = 2\n")
    edits = ['materials."Floor".kd=[0.35, 0.5, 0.1234]',
             'materials."Floor".lobes=[{ kind = "reflect", ks = [0.9, 0.9, 0.9], mx = 0.08, my = 0.2 }]',
             'materials."Lamp".emission=[6, 5, 4]', 'objects."Box".role="curved"']
    set_edits = [arg for text in edits for arg in ("--set", text)]
    unedited = capture(scene, tmp_path / "plain.png")  # so the --set bake starts from room.bake
    with_set = capture(scene, tmp_path / "set.png", *set_edits)
    assert with_set != unedited
    save_sidecar(scene, edits)
    assert sidecar_path(scene).read_text().startswith("# mine\n")
    assert capture(scene, tmp_path / "saved.png") == with_set
    assert read_manifest(default_bake_dir(scene))["materials"] == \
        read_manifest(edited_bake_dir(default_bake_dir(scene), load_scene(scene, edits).edits))["materials"]


@pytest.mark.slow
def test_role_edit_reuses_the_light_maps_by_hard_link(tmp_path):
    """A role edit (`objects."Box".role`) is outside the transport hash (bake/hashing.py): the
    edited bake reuses the unedited bake's light maps and meshes by hard link (same inode) and
    re-bakes nothing. With glint.services.run_bake passing no `seed`, the edited bake re-baked
    the light maps ("re-baked", not "reused")."""
    scene = write_room(tmp_path / "room.glb")
    assert main(["bake", str(scene), *BAKE_ARGS]) == 0
    edit = 'objects."Box".role="planar"'
    assert main(["bake", str(scene), *BAKE_ARGS, "--set", edit]) == 0
    base = default_bake_dir(scene)
    edit_dir = edited_bake_dir(base, load_scene(scene, [edit]).edits)
    manifest = read_manifest(edit_dir)
    assert manifest["statistics"]["last_bake"]["light_maps"] == "reused", manifest["statistics"]["last_bake"]
    box = next(o for o in manifest["objects"] if o["name"] == "Box")
    assert box["role"] == "planar"
    for name in ["meshes.npz", *manifest["lightmaps"]]:
        assert os.stat(base / name).st_ino == os.stat(edit_dir / name).st_ino
    assert main(["bake", str(scene), *BAKE_ARGS, "--set", edit]) == 0  # the edited bake is now up to date
    assert read_manifest(edit_dir)["statistics"] == manifest["statistics"]


def test_saved_and_printed_edits_name_only_what_changed_rounded(capsys):
    """The panel's Save: a built-in scene's printed `--set` options (and a user scene's sidecar
    assignments) name only the keys the panel changed, each number in float32's shortest form
    that reads back to the same float32: a slider's m of float32(0.008836) is written 0.008836,
    not 0.008835999394893657; r0 = 0.04000000000000001 is 0.04. Deliberate bugs this catches
    (tried): every key written (the printed options held `emission` and `lobes = []` for a kd
    edit); lobe numbers written as float() (0.008835999394893657 printed)."""
    from glint.view import sidecar_saver

    baked = [{"name": "Sofa", "kd": [0.5, 0.5, 0.5], "emission": [0.0, 0.0, 0.0], "lobes": []},
             {"name": "Floor", "kd": [0.3, 0.3, 0.3], "emission": [0.0, 0.0, 0.0],
              "lobes": [{"kind": "reflect", "ks": [1.0, 1.0, 1.0], "mx": 0.1, "my": 0.1, "r0": 0.05, "alpha": 0.2}]}]
    m = float(np.float32(0.008836))
    edited = [{**baked[0], "kd": [float(np.float32(0.6)), 0.12, 0.08]},
              {**baked[1], "lobes": [{**baked[1]["lobes"][0], "mx": m, "my": m, "r0": 0.04000000000000001}]}]
    assert [k for k, _ in material_assignments("Sofa", edited[0], baked[0])] == [("materials", "Sofa", "kd")]
    (keys, lobes), = material_assignments("Floor", edited[1], baked[1])
    assert keys == ("materials", "Floor", "lobes")
    assert lobes[0]["mx"] == 0.008836 and lobes[0]["r0"] == 0.04 and np.float32(lobes[0]["mx"]) == np.float32(m)
    with pytest.raises(GlintError, match="built in and not saved"):
        sidecar_saver("living-room", Path("unused.glb"), baked)(edited)
    printed = capsys.readouterr().out
    assert "--set 'materials.Sofa.kd = [0.6, 0.12, 0.08]'" in printed
    assert "--set 'materials.Floor.lobes = [{kind = \"reflect\", ks = [1.0, 1.0, 1.0], mx = 0.008836, " \
        "my = 0.008836, r0 = 0.04, alpha = 0.2}]'" in printed
    assert "emission" not in printed and printed.count("--set") == 2
