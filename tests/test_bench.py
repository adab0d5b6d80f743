"""`glint bench`: its files, the properties its numbers must have, and one-line errors.

Runs the built-in material-classes scene (one sphere per material class) at a tiny size and bake
quality, in-process through glint.cli.main, on llvmpipe in CI.
"""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from conftest import error_of

from glint.bench import bench, report
from glint.cli import main

BAKE = ["-q", "draft", "--samples", "8", "--texels-per-metre", "4", "--no-denoise"]
SMALL = ["--size", "128x72", "--frames", "2", "--warmup", "1"]
CLASSES = ("Glazed ceramic", "Chrome", "Brushed aluminium", "Frosted glass")


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """(output dir, bake options): one sweep of every method at n = 1 and 19."""
    d = tmp_path_factory.mktemp("bench")
    opts = [*BAKE, "--bake-dir", str(d / "mc.bake")]
    out = d / "out"
    assert main(["bench", "material-classes", "-o", str(out), *SMALL, "--reference-samples", "256",
                 "--lobe-samples", "1,19", *opts]) == 0
    return out, opts


def test_files_have_the_expected_rows_and_columns(run):
    out, _ = run
    rows = read_csv(out / "bench.csv")
    assert tuple(rows[0]) == bench.CSV_COLUMNS
    regions = {"image", "view-dependent", *(f"material:{c}" for c in CLASSES)}
    assert {r["region"] for r in rows} == regions
    keys = {(r["camera"], r["method"], r["n"], r["region"]) for r in rows}
    one_point = [k for k in bench.DEFAULT_METHODS if bench.METHODS[k].ignores_n]
    assert one_point == ["patterns-auto", "split-sum"]
    runs = 2 * len(bench.DEFAULT_METHODS) - len(one_point)  # these have no n: they run once, as n = 1
    assert len(keys) == len(rows) == 1 * runs * len(regions)
    assert {r["method"] for r in rows} == set(bench.DEFAULT_METHODS) and {r["n"] for r in rows} == {"1", "19"}
    assert {r["n"] for r in rows if r["method"] in one_point} == {"1"}
    data = json.loads((out / "bench.json").read_text())
    assert data["scene"] == "material-classes" and data["size"] == [128, 72]
    assert data["reference"]["samples_per_lobe_and_pixel"] == 256
    assert set(data["methods"]) == set(bench.DEFAULT_METHODS)
    assert len(data["results"]) == runs
    assert [r["prefilter_ms"] > 0 for r in data["results"] if "prefilter_ms" in r] == [True]  # split-sum's
    auto = [r for r in data["results"] if r["method"] == "patterns-auto"][0]  # n chosen per lobe, not the sweep's
    assert len(set(auto["samples_per_lobe"])) > 1 and all(1 <= n <= 19 for n in auto["samples_per_lobe"])
    for r in data["results"]:
        assert set(r["regions"]) == regions
        assert r["gpu_ms"]["specular"] > 0 and r["gpu_ms"]["frame"] >= r["gpu_ms"]["specular"]
    png = (out / "bench.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_errors_are_finite_and_masks_match_the_specular_pass(run):
    out, _ = run
    rows = read_csv(out / "bench.csv")
    flip = bench.flip_module() is not None
    for r in rows:
        assert math.isfinite(float(r["psnr_db"])) and float(r["psnr_db"]) > 0, r
        assert math.isfinite(float(r["rel_mse"])) and float(r["rel_mse"]) >= 0, r
        assert math.isfinite(float(r["ms_specular"])) and float(r["ms_specular"]) > 0, r
        if flip:
            assert 0 <= float(r["flip"]) <= 1, r
        else:
            assert r["flip"] == ""
    data = json.loads((out / "bench.json").read_text())
    for r in data["results"]:
        # The view-dependent mask (from the G-buffer) is exactly the pixels the specular pass shaded.
        assert r["regions"]["view-dependent"]["pixels"] == r["pixels_with_lobes"] > 0
        parts = sum(r["regions"][f"material:{c}"]["pixels"] for c in CLASSES)
        assert parts == r["regions"]["view-dependent"]["pixels"]


def psnr(rows, method, n, region):
    (row,) = [r for r in rows if r["method"] == method and r["n"] == str(n) and r["region"] == region]
    return float(row["psnr_db"]), float(row["rel_mse"])


def test_more_qmc_samples_give_less_error_on_glossy_objects(run):
    """The still-camera estimator is unbiased: 19 samples beat 1 on every glossy sphere."""
    rows = read_csv(run[0] / "bench.csv")
    for region in ("material:Chrome", "material:Glazed ceramic", "material:Brushed aluminium", "view-dependent"):
        p1, m1 = psnr(rows, "qmc", 1, region)
        p19, m19 = psnr(rows, "qmc", 19, region)
        assert p19 > p1 + 3.0, (region, p1, p19)
        assert m19 < m1, (region, m1, m19)


def test_errors_are_deterministic(run, tmp_path):
    out, opts = run
    again = tmp_path / "again"
    assert main(["bench", "material-classes", "-o", str(again), *SMALL, "--reference-samples", "256",
                 "--lobe-samples", "19", "--methods", "patterns,qmc", "--no-flip", *opts]) == 0
    first = {(r["method"], r["n"], r["region"]): (r["psnr_db"], r["rel_mse"]) for r in read_csv(out / "bench.csv")}
    for r in read_csv(again / "bench.csv"):
        assert (r["psnr_db"], r["rel_mse"]) == first[(r["method"], r["n"], r["region"])]
        assert r["flip"] == ""


def test_the_reference_against_itself_has_infinite_psnr(run, tmp_path):
    """QMC with as many samples in one frame as the reference is the reference, bit for bit."""
    _, opts = run
    out = tmp_path / "self"
    assert main(["bench", "material-classes", "-o", str(out), *SMALL, "--reference-samples", "32",
                 "--lobe-samples", "32", "--methods", "qmc", *opts]) == 0
    rows = read_csv(out / "bench.csv")
    assert rows and all(r["psnr_db"] == "inf" and float(r["rel_mse"]) == 0 for r in rows)
    if bench.flip_module() is not None:
        assert all(float(r["flip"]) == 0 for r in rows)
    data = json.loads((out / "bench.json").read_text())  # strict JSON: no Infinity
    assert all(e["psnr_db"] is None for r in data["results"] for e in r["regions"].values())
    assert (out / "bench.png").exists()


def test_error_functions():
    rng = np.random.default_rng(0)
    ref = {"srgb": rng.integers(0, 256, (8, 10, 3), dtype=np.uint8), "linear": rng.random((8, 10, 3), np.float32)}
    mask = np.zeros((8, 10), bool)
    mask[2:5, 3:7] = True
    same = bench.errors(ref, ref, {"m": mask})["m"]
    assert same["psnr_db"] == math.inf and same["rel_mse"] == 0 and same["pixels"] == 12
    test = {"srgb": ref["srgb"].copy(), "linear": ref["linear"] + 0.1}
    test["srgb"][mask] = np.clip(test["srgb"][mask].astype(int) + 16, 0, 255).astype(np.uint8)
    e = bench.errors(test, ref, {"m": mask, "all": np.ones((8, 10), bool)})
    mse = np.mean((test["srgb"][mask].astype(float) - ref["srgb"][mask]) ** 2)
    assert e["m"]["psnr_db"] == pytest.approx(10 * math.log10(255 ** 2 / mse))
    assert e["all"]["psnr_db"] > e["m"]["psnr_db"]  # the same error spread over more pixels
    r = ref["linear"][mask].astype(float)
    assert e["m"]["rel_mse"] == pytest.approx(np.mean(0.01 / (r * r + bench.REL_MSE_EPSILON)), rel=1e-5)
    assert report.num(math.inf) == "inf" and report.json_safe({"x": [math.inf, math.nan]}) == {"x": [None, None]}


@pytest.mark.parametrize("extra, message", [
    (["--lobe-samples", "0"], "--lobe-samples"),
    (["--lobe-samples", "3,x"], "not a whole number"),
    (["--lobe-samples", ""], "--lobe-samples"),
    (["--methods", "nope"], "unknown method 'nope'"),
    (["--size", "0x10"], "--size"),
    (["--reference-samples", "4", "--lobe-samples", "7"], "--reference-samples"),
    (["--frames", "0"], "--frames"),
    (["--supersample", "9"], "--supersample"),
])
def test_bad_options_give_one_line_errors(run, tmp_path, capsys, extra, message):
    _, opts = run
    code = main(["bench", "material-classes", "-o", str(tmp_path / "x"), *opts, *extra])
    assert message in error_of(capsys, code)
    assert not (tmp_path / "x").exists()


def test_unknown_camera_and_bad_output(run, tmp_path, capsys):
    _, opts = run
    code = main(["bench", "material-classes", "-o", str(tmp_path / "x"), "--camera", "nope", *SMALL, *opts])
    assert "unknown camera 'nope'; the scene has: front" in error_of(capsys, code)
    (tmp_path / "file").write_text("")
    code = main(["bench", "material-classes", "-o", str(tmp_path / "file"), *opts])
    assert "not a directory" in error_of(capsys, code)
