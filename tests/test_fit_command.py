"""`glint fit` (glint/fit.py): the sidecar it writes is one glint's own reader accepts, it edits in place,
never writes a file that is not a sidecar, and bad input is one line.

Deliberate bugs tried: writing the lobes under the key `lobe` fails
`test_fit_writes_a_sidecar_glint_reads` (the sidecar check refuses the unknown key: exit 2, not 0);
dropping check_output's table test fails `test_a_file_that_is_not_a_sidecar_is_refused` (exit 0: the file
is edited).
"""
from __future__ import annotations

import sys

import numpy as np
import pytest

from glint.bake import merl
from glint.bake.sidecar import parse_sidecar, parse_toml
from glint.cli import main
from glint.core import bsdf
from glint.core.scene import Lobe

KNOWN = Lobe(ks=(0.8, 0.8, 0.8), mx=0.1, my=0.1, r0=0.05, alpha=0.3)


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    path = tmp_path_factory.mktemp("merl") / "known.binary"
    return merl.write_merl(path, lambda wi, wo: bsdf.bsdf(wi, wo, (0.2, 0.2, 0.2), [KNOWN]))


def test_fit_writes_a_sidecar_glint_reads(tmp_path, measured, capsys):
    side = tmp_path / "room.glint.toml"
    side.write_text('# lighting\n[bake]\nquality = "draft"  # fast\n\n[materials."Floor"]\nemission = [0, 0, 0]\n'
                    'kd = 0.9\n\n[materials."Wall"]\nkd = 0.5\n')
    assert main(["fit", str(measured), "--name", "Floor", "-o", str(side)]) == 0
    out = capsys.readouterr().out
    assert "replaced kd and lobes of [materials.\"Floor\"]" in out and "80°" in out
    text = side.read_text()
    assert "# lighting" in text and "# fast" in text  # edited in place
    parsed = parse_sidecar(parse_toml(text, side), side)
    assert not parsed.warnings
    floor = parsed.materials["Floor"]
    np.testing.assert_allclose(floor["kd"], 0.2, atol=0.01)
    np.testing.assert_allclose(floor["emission"], 0.0)  # kept
    (lobe,) = floor["lobes"]
    assert lobe.kind == "reflect" and abs(lobe.mx - 0.1) < 0.003 and abs(lobe.ks[0] - 0.8) < 0.03
    np.testing.assert_allclose(parsed.materials["Wall"]["kd"], 0.5)  # the other material untouched
    assert parsed.bake == {"quality": "draft"}


def test_without_output_prints_the_table(measured, capsys):
    assert main(["fit", str(measured), "--name", "Floor tiles"]) == 0
    out = capsys.readouterr().out
    toml = out[out.index('[materials."Floor tiles"]'):]
    side = parse_sidecar(parse_toml(toml, "x.glint.toml"), "x.glint.toml")
    assert len(side.materials["Floor tiles"]["lobes"]) == 1


def test_a_file_that_is_not_a_sidecar_is_refused(tmp_path, measured, capsys):
    other = tmp_path / "pyproject.glint.toml"
    other.write_text('[tool.x]\nvalue = 1\n')
    for target, message in ((tmp_path / "notes.toml", "only into a sidecar"), (other, "not a glint sidecar")):
        before = target.read_text() if target.exists() else None
        assert main(["fit", str(measured), "--name", "Floor", "-o", str(target)]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1
        assert (target.read_text() if target.exists() else None) == before


def test_bad_input_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.binary"
    bad.write_bytes(b"\x00" * 100)
    assert main(["fit", str(bad), "--name", "Floor"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("glint: bad.binary:") and len(err.strip().splitlines()) == 1
    assert main(["fit", str(tmp_path / "none.csv"), "--name", "Floor"]) == 2
    assert "no such file" in capsys.readouterr().err


def test_plots(tmp_path, measured, capsys, monkeypatch):
    assert main(["fit", str(measured), "--name", "Floor", "--plots", str(tmp_path)]) == 0
    png = tmp_path / "fit-Floor.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # as if the bench extra were not installed
    assert main(["fit", str(measured), "--name", "Floor", "--plots", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "pip install 'glint[bench]'" in err and len(err.strip().splitlines()) == 1
