"""The README's first path: `pip install .` (not editable), then `glint ...` from anywhere.

The package is built and installed into a folder of its own (pip --target, no dependencies:
they are those of this environment), and `glint capture cornell-box` runs from a directory
outside the checkout with only that folder on the path. Catches: a module or data file that is
not in the wheel (shaders, built-in scenes: package-data), an import of a folder's bare name
(`import bake`) that works only inside a checkout, a path computed from the checkout's layout.
Deliberate bug tried: dropping `"glint.shaders"` from [tool.setuptools] packages fails it (the
installed tree has no glint/shaders).
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_installed_package_captures_from_another_directory(tmp_path):
    target, work, source = tmp_path / "site", tmp_path / "elsewhere", tmp_path / "source"
    work.mkdir()
    # a clean copy: setuptools would otherwise reuse a stale build/ of the checkout
    shutil.copytree(ROOT, source, ignore=shutil.ignore_patterns(".git", "build", "*.egg-info", "__pycache__",
                                                                "*.bake", ".pytest_cache", ".venv*"))
    build = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(target),
                            str(source)], capture_output=True, text=True, cwd=work)
    assert build.returncode == 0, build.stderr[-2000:]
    for folder in ("core", "bake", "viewer", "shaders", "scenes", "bench"):
        assert (target / "glint" / folder / "__init__.py").is_file(), folder
        assert not (target / folder).exists(), f"'{folder}' installed as a top-level package"
    assert (target / "glint" / "shaders" / "specular.glsl").is_file()
    assert (target / "glint" / "scenes" / "cornell-box.glb").is_file()

    env = {**os.environ, "PYTHONPATH": str(target), "GLINT_CACHE": str(tmp_path / "cache")}
    where = subprocess.run([sys.executable, "-c", "import glint.bake, glint.viewer; print(glint.bake.__file__)"],
                           capture_output=True, text=True, cwd=work, env=env)
    assert where.returncode == 0 and Path(where.stdout.strip()).is_relative_to(target), where
    run = subprocess.run([sys.executable, "-m", "glint", "capture", "cornell-box", "-o", "x.png", "-q", "draft",
                          "--size", "64x64", "--supersample", "1"],
                         capture_output=True, text=True, cwd=work, env=env)
    assert run.returncode == 0, run.stderr[-2000:]
    assert (work / "x.png").stat().st_size > 1000
    assert (target / "bin" / "glint").is_file()  # the console script
