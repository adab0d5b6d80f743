"""bake/merl.py: the MERL binary format and the CSV table, against expectations written by hand.

The index test builds its directions with scipy's Rotation (not bake/merl.py's own conversion) from
half/difference angles chosen inside bins, and expects the flat index computed by hand from MERL's
BRDFRead.cpp mapping: theta_h = 30 deg -> floor(sqrt(30/90) x 90) = 51, theta_d = 45.5 deg -> 45,
phi_d = 100.3 deg (and -79.7 deg, reciprocity) -> 100, i.e. (51 x 90 + 45) x 180 + 100.
Deliberate bugs tried: a linear theta_h index (floor(theta_h / 90 deg x 90)) fails
`test_lookup_finds_the_hand_computed_bin` (value 0 instead of 0.7: it reads bin 30); the blue scale
1.15/1500 instead of 1.66/1500 fails `test_channel_scales` (0.000767 against 0.001107).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from glint.bake import merl
from glint.core.errors import GlintError

N = 90 * 90 * 180
HAND_INDEX = (51 * 90 + 45) * 180 + 100


def directions(theta_h, phi_h, theta_d, phi_d):
    """wi, wo from Rusinkiewicz's angles (degrees), by scipy rotations: h = Rz(phi_h) Ry(theta_h) z,
    wi = the same rotation of the difference vector, wo = wi mirrored about h."""
    rot = Rotation.from_euler("ZY", [phi_h, theta_h], degrees=True)  # intrinsic: z first, then the new y
    td, pd = np.radians(theta_d), np.radians(phi_d)
    d = np.array([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)])
    h, wi = rot.apply([0.0, 0.0, 1.0]), rot.apply(d)
    return wi, 2.0 * np.dot(wi, h) * h - wi


def write_raw(path, values, dims=(90, 90, 180)):
    with open(path, "wb") as f:
        f.write(np.array(dims, "<i4").tobytes())
        f.write(np.asarray(values, "<f8").tobytes())
    return path


def test_lookup_finds_the_hand_computed_bin(tmp_path):
    raw = np.zeros((3, N))
    raw[:, HAND_INDEX] = [0.7 * 1500, 0.5 * 1500 / 1.15, 0.25 * 1500 / 1.66]
    table = merl.read_brdf_file(write_raw(tmp_path / "one.binary", raw))
    for phi_h, phi_d in ((0.0, 100.3), (37.0, 100.3), (0.0, -79.7)):  # phi_h ignored; phi_d + 180 the same
        wi, wo = directions(30.0, phi_h, 45.5, phi_d)
        assert wi[2] > 0 and wo[2] > 0
        np.testing.assert_allclose(table.evaluate(wi, wo), [0.7, 0.5, 0.25], rtol=1e-12)
    assert merl.merl_index(np.radians(30.0), np.radians(45.5), np.radians(100.3)) == HAND_INDEX


def test_channel_scales(tmp_path):
    raw = np.ones((3, N))
    table = merl.read_brdf_file(write_raw(tmp_path / "ones.binary", raw))
    wi, wo = directions(20.0, 0.0, 10.0, 50.0)
    np.testing.assert_allclose(table.evaluate(wi, wo), [1 / 1500, 1.15 / 1500, 1.66 / 1500], rtol=1e-12)


def test_written_file_reads_back_the_brdf(tmp_path):
    """write_merl at bin centres, read at a bin's centre: the same value; below the surface: missing."""
    f = lambda wi, wo: np.stack([wi[..., 2], wo[..., 2], wi[..., 0] ** 2], axis=-1)  # noqa: E731
    table = merl.read_brdf_file(merl.write_merl(tmp_path / "f.binary", f))
    th, td, pd = ((51.5 / 90) ** 2 * 90, 45.5, 100.5)
    wi, wo = directions(th, 0.0, td, pd)
    np.testing.assert_allclose(table.evaluate(wi, wo), f(wi, wo), rtol=1e-9, atol=1e-12)
    wi, wo = directions(60.0, 0.0, 80.0, 10.0)  # wi below the surface
    assert wi[2] < 0 and np.all(table.evaluate(wi, wo) < 0)
    assert (tmp_path / "f.binary").stat().st_size == 12 + 8 * 3 * N


@pytest.mark.parametrize("case, message", [
    ("short", "truncated or padded"), ("dims", "dimensions (90, 90, 90)"), ("nan", "NaN or infinite"),
    ("negative", "no measured value"), ("tiny", "only 5 bytes")])
def test_bad_merl_files_are_one_line(tmp_path, case, message):
    path = tmp_path / f"{case}.binary"
    if case == "short":
        write_raw(path, np.ones(3 * N - 1))
    elif case == "dims":
        write_raw(path, np.ones(3 * N), dims=(90, 90, 90))
    elif case == "nan":
        raw = np.ones(3 * N)
        raw[5] = np.nan
        write_raw(path, raw)
    elif case == "negative":
        write_raw(path, -np.ones(3 * N))
    else:
        path.write_bytes(b"hello")
    with pytest.raises(GlintError, match=message.replace("(", r"\(").replace(")", r"\)")) as err:
        merl.read_brdf_file(path)
    assert "\n" not in str(err.value)


def write_csv(path, f, rows=None):
    ti, to, pd = np.meshgrid(np.arange(0, 91, 10.0), np.arange(0, 91, 10.0), np.arange(0, 181, 30.0), indexing="ij")
    lines = ["theta_i,theta_o,phi_d,r,g,b"]
    for a, b, c in zip(ti.ravel(), to.ravel(), pd.ravel()):
        lines.append(",".join(f"{v:.17g}" for v in (a, b, c, *f(a, b, c))))
    path.write_text("\n".join(lines[:rows] if rows else lines) + "\n")
    return path


def test_csv_table_reads_its_grid_and_interpolates(tmp_path):
    f = lambda ti, to, pd: (0.1 + ti / 900, 0.2 + to / 900, 0.3 + pd / 1800)  # noqa: E731 (linear: exact)
    table = merl.read_brdf_file(write_csv(tmp_path / "lin.csv", f))
    # wo at theta_o = 35, phi_o = 0; wi at theta_i = 25 on the mirror side (phi_i = 180: phi_d = 180), and at phi_i = 45
    to, ti = np.radians(35.0), np.radians(25.0)
    wo = np.array([np.sin(to), 0, np.cos(to)])
    for phi_i, phi_d in ((180.0, 180.0), (45.0, 45.0), (-45.0, 45.0)):
        p = np.radians(phi_i)
        wi = np.array([np.sin(ti) * np.cos(p), np.sin(ti) * np.sin(p), np.cos(ti)])
        np.testing.assert_allclose(table.evaluate(wi, wo), f(25.0, 35.0, phi_d), rtol=1e-9)


@pytest.mark.parametrize("text, message", [
    ("a,b,c\n1,2,3\n", "header line"), ("theta_i,theta_o,phi_d,r,g,b\n0,0,0,1,1,x\n", "not a number"),
    ("theta_i,theta_o,phi_d,r,g,b\n0,0,0,1,1,1\n", "full grid"),
    ("theta_i,theta_o,phi_d,r,g,b\n0,0,0,1,1,nan\n", "NaN"),
    ("theta_i,theta_o,phi_d,r,g,b\n0,95,0,1,1,1\n", "within 0-90")])
def test_bad_tables_are_one_line(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(GlintError, match=message):
        merl.read_brdf_file(path)


def test_unknown_suffix_and_missing_file(tmp_path):
    (tmp_path / "x.brdf").write_text("")
    with pytest.raises(GlintError, match="unknown BRDF file type"):
        merl.read_brdf_file(tmp_path / "x.brdf")
    with pytest.raises(GlintError, match="no such file"):
        merl.read_brdf_file(tmp_path / "none.binary")
