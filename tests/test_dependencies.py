"""Every third-party import is declared in pyproject.toml, where the code that imports it runs.

Read from the source (AST), not from this environment, which has every extra installed and so
cannot see a missing declaration (scipy, imported by bake/cubemap.py at module level and declared
only in the `test` extra, made `pip install . && glint ...` fail with ModuleNotFoundError on every
command while the whole suite passed):

- an import at a module's top level (what `import glint.X` runs) must be in [project].dependencies:
  a plain `pip install .` has nothing else;
- an import inside a function (an optional feature: Mitsuba, Dask, matplotlib, FLIP) must be in
  the dependencies or an extra, and the code says which extra to install in one line
  (`test_an_optional_import_missing_is_one_line_naming_its_extra`);
- an import of the tests must be in the dependencies or the `test` extra (what `.ci/run` installs).

An import name is matched to its distribution with importlib.metadata (PIL -> Pillow), else taken as
it is. Deliberate bugs tried: `import networkx` added at the top of bake/cubemap.py fails
`test_top_level_imports_are_dependencies` ("glint.bake.cubemap:... networkx"); scipy moved back to
the `test` extra fails it too; `import yaml` in a test fails `test_test_imports_are_declared`.
"""
from __future__ import annotations

import ast
import functools
import importlib.metadata
import re
import subprocess
import sys
from pathlib import Path

from test_architecture import ROOT, modules

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

# Distributions that come with a declared one, imported by name where that one is used: Dask's
# `distributed` (the extra dask[distributed]) and Mitsuba's Dr.Jit.
BROUGHT_BY = {"distributed": "dask", "drjit": "mitsuba"}


def normalise(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def requirement_names(requirements: list[str]) -> set[str]:
    return {normalise(re.match(r"\s*([A-Za-z0-9._-]+)", r).group(1)) for r in requirements}


def declared() -> tuple[set[str], dict[str, set[str]]]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = {k: requirement_names(v) for k, v in project.get("optional-dependencies", {}).items()}
    return requirement_names(project["dependencies"]), extras


@functools.cache
def distribution(top: str) -> str:
    """The distribution that provides the import name `top` (PIL -> pillow)."""
    if top in BROUGHT_BY:
        return BROUGHT_BY[top]
    found = importlib.metadata.packages_distributions().get(top)
    return normalise(found[0] if found else top)


def third_party_imports(path: Path, first_party: set[str]) -> list[tuple[str, int, bool]]:
    """(top-level import name, line, at module level) of every import of another project in the
    file; imports under `if TYPE_CHECKING:` never run and are left out."""
    tree = ast.parse(path.read_text(), filename=str(path))
    out = []

    def visit(node, top_level: bool):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                continue
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                names = ([a.name for a in child.names] if isinstance(child, ast.Import)
                         else [child.module] if child.level == 0 and child.module else [])
                for name in names:
                    top = name.split(".")[0]
                    if top not in sys.stdlib_module_names and top not in first_party and top != "__future__":
                        out.append((top, child.lineno, top_level))
            inner = top_level and not isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            visit(child, inner)

    visit(tree, True)
    return out


def package_imports():
    for module, path in modules().items():
        for top, line, top_level in third_party_imports(path, {"glint"}):
            yield module, path, top, line, top_level


def test_top_level_imports_are_dependencies():
    dependencies, _ = declared()
    missing = [f"{module}:{line} imports {top} ({distribution(top)})" for module, _, top, line, top_level
               in package_imports() if top_level and distribution(top) not in dependencies]
    assert not missing, ("imported when glint is imported, but not in pyproject.toml [project].dependencies "
                         "(a plain `pip install .` lacks them):\n" + "\n".join(missing))


def test_function_imports_are_declared_somewhere():
    dependencies, extras = declared()
    anywhere = dependencies.union(*extras.values())
    missing = [f"{module}:{line} imports {top} ({distribution(top)})" for module, _, top, line, _ in package_imports()
               if distribution(top) not in anywhere]
    assert not missing, "imported but declared nowhere in pyproject.toml:\n" + "\n".join(missing)


def test_test_imports_are_declared():
    dependencies, extras = declared()
    ours = {p.stem for p in (ROOT / "tests").rglob("*.py")} | {"glint"}
    missing = [f"{path.relative_to(ROOT)}:{line} imports {top} ({distribution(top)})"
               for path in sorted((ROOT / "tests").rglob("*.py"))
               for top, line, _ in third_party_imports(path, ours)
               if distribution(top) not in dependencies | extras["test"]]
    assert not missing, "the tests import what the `test` extra does not declare:\n" + "\n".join(missing)


def test_the_checker_sees_an_undeclared_import(tmp_path):
    """The checker itself: a module-level and a function-level import of an undeclared project are
    found, a standard-library one and one under TYPE_CHECKING are not."""
    source = tmp_path / "m.py"
    source.write_text("import os\nimport yaml\nfrom typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import rich\n"
                      "def f():\n    import toml\n    from glint.core import errors\n")
    assert third_party_imports(source, {"glint"}) == [("yaml", 2, True), ("toml", 7, False)]


def test_an_optional_import_missing_is_one_line_naming_its_extra(tmp_path):
    """With matplotlib, Mitsuba and Dask hidden (a `None` in sys.modules makes their import fail as
    when they are not installed), the code that needs each stops with one GlintError naming the
    extra to install, not a ModuleNotFoundError. Deliberate bug tried: bench/report.py's pyplot()
    without its try/except: "ModuleNotFoundError: import of matplotlib halted"."""
    code = """
import sys
for name in ("matplotlib", "mitsuba", "distributed", "dask"):
    sys.modules[name] = None
from glint.core.errors import GlintError
from glint.bench.report import pyplot
from glint.bench.mitsuba import choose_variant
from glint.parallel.executor import executor_for
from glint.bake.settings import BakeSettings
for call in (pyplot, lambda: choose_variant("auto"), lambda: executor_for(BakeSettings(scheduler="tcp://127.0.0.1:1")).start()):
    try:
        call()
        print("no error")
    except GlintError as e:
        print(str(e))
"""
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    lines = run.stdout.strip().splitlines()
    assert run.returncode == 0 and len(lines) == 3, run.stdout + run.stderr
    assert "pip install 'glint[bench]'" in lines[0] and "matplotlib" in lines[0]
    assert "pip install 'glint[bench]'" in lines[1] and "Mitsuba" in lines[1]
    assert "pip install 'glint[cluster]'" in lines[2] and "Dask" in lines[2]
