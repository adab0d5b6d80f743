"""The sidecar's schema (bake/sidecar_schema.py): every key range-checked in one place, with one message, from
the sidecar file, the command line and `--set` alike."""
import pytest

from glint.bake.settings import BakeSettings, resolve_settings
from glint.cli import main
from glint.core.errors import GlintError

from conftest import error_of, write_room


def _bake(tmp_path, sidecar: str, *args) -> int:
    scene = write_room(tmp_path / "room.glb", sidecar=sidecar)
    return main(["bake", str(scene), "-o", str(tmp_path / "room.bake"), *args])


@pytest.mark.parametrize("sidecar, expected", [
    # was "internal error: TypeError" from xatlas
    ("[bake]\npadding = -5\n", "room.glint.toml: [bake] padding must be a whole number from 0 to 64, not -5"),
    # was a ZeroDivisionError
    ("[bake]\nmax_page_size = 0\n",
     "room.glint.toml: [bake] max_page_size must be a whole number from 64 to 8192, not 0"),
    # was three xatlas segfaults over 25 s
    ("[bake]\nmax_page_size = 100000000\n",
     "room.glint.toml: [bake] max_page_size must be a whole number from 64 to 8192, not 100000000"),
    # were accepted (49 % of texels unlit)
    ("[bake]\nmax_depth = -1\n", "room.glint.toml: [bake] max_depth must be a whole number from 1 to 1024, not -1"),
    ("[bake]\nbackface_threshold = -3\n",
     "room.glint.toml: [bake] backface_threshold must be a number from 0 to 1, not -3"),
    ("[bake]\nseed = -1\n", "room.glint.toml: [bake] seed must be a whole number from 0 to 4294967295, not -1"),
    ("[bake]\ndenoise = 1\n", "room.glint.toml: [bake] denoise must be true or false, not 1"),
    ("[bake]\nquality = \"ultra\"\n",
     "room.glint.toml: [bake] quality must be one of draft, preview, final, not 'ultra'"),
    ("[bake]\ncubemap_budget_mib = 0\n", "room.glint.toml: [bake] cubemap_budget_mib must be a number above 0, not 0"),
    ("[bake]\nsamples = 0\n", "room.glint.toml: [bake] samples must be a whole number of at least 1, not 0"),
    ("[lights]\nunits = \"watts\"\n",
     "room.glint.toml: [lights] units must be one of photometric, radiometric, not 'watts'"),
    ("[sky]\nstrength = -1\n", "room.glint.toml: [sky] strength must be a number of at least 0, not -1"),
    ("[objects.\"Box\"]\ncubemap_size = 100\n",
     "room.glint.toml: [objects.\"Box\"] cubemap_size must be a power of two from 4 to 4096, not 100"),
    ("[cameras.c]\neye = [0, 1, 1]\ntarget = [0, 1, 0]\nyfov = 200\n",
     "room.glint.toml: [cameras.c] yfov must be a number above 0 and below 180, not 200"),
    ("[camera_paths.p]\nkeys = [ { time = 0, eye = [0, 1, 1], target = [0, 1, \"x\"] } ]\n",
     "room.glint.toml: [camera_paths.p] keys[0] target must be a list of 3 numbers, not [0, 1, 'x']"),
], ids=["padding", "page-0", "page-huge", "depth", "backface", "seed", "denoise", "quality", "budget", "samples",
        "units", "sky", "cubemap-size", "yfov", "path-key"])
def test_sidecar_value_out_of_range_is_one_line(tmp_path, capsys, sidecar, expected):
    """Each value outside its range is refused before any work, in one line naming the file, table, key,
    value and what is allowed. Catches: a [bake] key passed to the bake unchecked (removing BAKE's range
    of padding gave 'internal error: TypeError', of max_depth a bake that ran with -1)."""
    assert error_of(capsys, _bake(tmp_path, sidecar)) == f"glint: {expected}"


@pytest.mark.parametrize("args, expected", [
    (["--samples", "0"], "argument --samples: must be a whole number of at least 1, not 0"),
    (["--texels-per-metre", "inf"], "argument --texels-per-metre: must be a number above 0, not inf"),
    (["-j", "-1"], "argument -j/--jobs: must be a whole number of at least 0, not -1"),
])
def test_command_line_takes_the_same_rule(tmp_path, capsys, args, expected):
    """The options' values go through the [bake] keys' rules (one copy). Catches: a second, laxer
    check on the command line (texels-per-metre inf passed the old float check)."""
    assert error_of(capsys, _bake(tmp_path, "", *args)) == \
        f"glint: bake: {expected} (`glint bake --help` lists the options)"


def test_set_takes_the_same_rule(tmp_path, capsys):
    """`--set bake.padding=-5` is refused as the file's key is, naming the --set. Catches: --set bypassing
    the schema."""
    code = _bake(tmp_path, "", "--set", "bake.padding=-5")
    assert error_of(capsys, code) == \
        "glint: --set 'bake.padding=-5': [bake] padding must be a whole number from 0 to 64, not -5"


def test_resolve_settings_checks_every_source():
    """resolve_settings checks the sidecar's dict and the command line's values by the same rules (the
    bake's re-bake reads a manifest's settings through it too)."""
    with pytest.raises(GlintError, match=r"^\[bake\] max_page_size must be a whole number from 64 to 8192, not 0$"):
        resolve_settings({"max_page_size": 0})
    with pytest.raises(GlintError, match=r"^--jobs must be a whole number of at least 0, not -2$"):
        resolve_settings({}, jobs=-2)
    assert resolve_settings({"max_page_size": 64, "padding": 0, "backface_threshold": 1}).max_page_size == 64


def test_defaults_lie_in_their_ranges():
    """Every default is accepted by its own rule, and the defaults stay those documented in docs/SCENES.md."""
    s = resolve_settings({})
    assert (s.padding, s.max_page_size, s.max_depth, s.backface_threshold, s.samples) == (2, 2048, 64, 0.2, 128)
    assert s == BakeSettings()


def test_unknown_keys_still_warn(tmp_path, capsys):
    """An unknown key is a warning naming the known ones, never an error (unchanged behaviour)."""
    scene = write_room(tmp_path / "room.glb", sidecar="[bake]\nquality = \"draft\"\nsampels = 4\n")
    from glint.bake.gltf_loader import load_scene

    load_scene(scene)
    err = capsys.readouterr().err
    assert "room.glint.toml: unknown key [bake] 'sampels' ignored (known: quality, samples," in err
