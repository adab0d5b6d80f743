"""The layers of docs/ARCHITECTURE.md, checked on the import graph of the installed package.

Every module of the `glint` package is a node; an edge is

- every `import` and `from ... import` (at module level or inside a function: both are
  dependencies), `import glint` and `from glint import X` included: `glint` itself is
  glint/__init__.py, which holds the version only and counts as core (anyone may import it;
  it imports nothing of glint);
- an import by string: `importlib.import_module("glint.x")` or `__import__("glint.x")` with a
  literal, and any other string literal that is a glint module's path ("glint.cubemap_stage", or
  "glint.viewer.renderer.Renderer": its longest prefix that is a module), as data handed to code
  that imports it later (a worker's modules to pre-import, a `mock.patch` target). An import whose
  name is not a literal is allowed only in DYNAMIC_IMPORTS, which says where its names come from.

The test fails on

- an import cycle between modules (catches e.g. `glint.cli` importing `glint.capture` which
  imports `glint.cli` back, as the commands once did);
- an edge against the layering: core imports nothing of glint above it; the bake and the
  viewer import only core (and the viewer the shaders' package), never each other; the services
  import neither commands nor bench/; commands (glint/: cli, capture, view, entry, bench_command)
  and tools (bench/'s scripts: a module with an `if __name__ == "__main__":` block) never import
  each other; both may import the measurements (the rest of bench/: what `glint bench` and the
  scripts share), which import neither;
- an import of the folders' bare names (`import bake`, `from viewer.camera import ...`),
  which works in a checkout and breaks in an installed package.

Deliberate bugs it catches (tried): adding `from glint.viewer.camera import ViewCamera` to
bake/cubemap.py fails `test_layers`; `from glint.cli import main` in glint/services.py fails
`test_no_cycles`; `importlib.import_module("glint.viewer.renderer")` in bake/lightmap.py fails
`test_layers` ("glint.bake.lightmap -> glint.viewer.renderer (string, line ...)") and
`test_the_bake_never_reaches_the_viewer`; `import glint.cli` in bench/measure_fill_rate.py (a tool)
fails `test_layers` and `test_commands_and_tools_never_import_each_other`, and so does
`from glint.bench.measure_fill_rate import main` in glint/capture.py (command -> tool);
`from glint.capture import main` in bench/bench.py (a measurement) fails both too;
`__import__(name)` with a computed name in bake/texels.py fails `test_dynamic_imports_are_listed`;
`from glint.core.errors import GlintError` in glint/__init__.py fails `test_the_package_itself_is_core`;
deleting a module's row from docs/ARCHITECTURE.md's "Modules, layer by layer" (or adding a module
without one) fails `test_every_module_is_named_once_in_architecture_md`.
"""
from __future__ import annotations

import ast
import re
from collections import Counter
from functools import cache
from pathlib import Path

import networkx as nx
import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = {"glint": "glint", "core": "glint.core", "parallel": "glint.parallel", "bake": "glint.bake",
           "viewer": "glint.viewer",
           "shaders": "glint.shaders", "scenes": "glint.scenes", "bench": "glint.bench"}
BARE = {"core", "parallel", "bake", "viewer", "shaders", "scenes", "bench"}

# layer of a module -> the layers it may import (its own included)
ALLOWED = {
    "core": {"core"},
    "parallel": {"core", "parallel"},
    "bake": {"core", "parallel", "bake"},
    "viewer": {"core", "viewer", "shaders"},
    "scenes": {"core", "scenes"},
    "shaders": {"shaders"},
    "services": {"core", "parallel", "bake", "viewer", "scenes", "services"},
    "measurements": {"core", "parallel", "bake", "viewer", "scenes", "shaders", "services", "measurements"},
    "commands": {"core", "parallel", "bake", "viewer", "scenes", "services", "measurements", "commands"},
    "tools": {"core", "parallel", "bake", "viewer", "scenes", "shaders", "services", "measurements", "tools"},
}
SERVICES = {"glint.services", "glint.options", "glint.cubemap_stage"}
# Modules that import a module whose name is not a literal, and where those names come from.
DYNAMIC_IMPORTS = {
    # the worker server pre-imports TASK_MODULES (literals, edges here) and the modules its caller
    # names: bake/pipeline.py's `worker_modules`, which glint/services.py passes (a string edge there)
    "glint.parallel.local_cluster",
}
MODULE_PATH = re.compile(r"glint(\.[A-Za-z_][A-Za-z0-9_]*)+")


def modules() -> dict[str, Path]:
    found = {}
    for folder, package in FOLDERS.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            rel = path.relative_to(ROOT / folder).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            found[".".join([package, *parts])] = path
    return found


def is_script(path: Path) -> bool:
    """An `if __name__ == "__main__":` block at the top level: a tool run as `python -m glint.bench.X`."""
    return any(isinstance(node, ast.If) and isinstance(node.test, ast.Compare)
               and isinstance(node.test.left, ast.Name) and node.test.left.id == "__name__"
               for node in ast.parse(path.read_text()).body)


@cache
def tools() -> frozenset[str]:
    return frozenset(m for m, path in modules().items() if m.startswith("glint.bench.") and is_script(path))


def layer(module: str) -> str:
    parts = module.split(".")
    if module == "glint":
        return "core"  # glint/__init__.py: the version only
    if parts[1] == "bench":
        return "tools" if module in tools() else "measurements"
    if parts[1] in ("core", "parallel", "bake", "viewer", "shaders", "scenes"):
        return parts[1]
    return "services" if module in SERVICES else "commands"


def _dynamic_import(node: ast.AST) -> ast.Call | None:
    """`__import__(...)`, `importlib.import_module(...)` or `import_module(...)`."""
    if isinstance(node, ast.Call) and node.args:
        func = node.func
        name = func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else None
        if name in ("__import__", "import_module"):
            return node
    return None


def imports(path: Path, module: str) -> list[tuple[str, int, str]]:
    """(imported module, line, kind) for every import in the file, relative ones resolved; kind is
    "import", "string" (a literal naming a module) or "dynamic" (an import of a computed name)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    docstrings = {id(node.value) for node in ast.walk(tree) if isinstance(node, ast.Expr)}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(alias.name, node.lineno, "import") for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1] + ([base] if base else []))
            out.append((base, node.lineno, "import"))
            out += [(f"{base}.{alias.name}", node.lineno, "import") for alias in node.names]  # `from pkg import module`
        elif (call := _dynamic_import(node)) and not (isinstance(call.args[0], ast.Constant)
                                                       and isinstance(call.args[0].value, str)):
            out.append(("?", node.lineno, "dynamic"))
        elif (isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings
              and MODULE_PATH.fullmatch(node.value)):
            out.append((node.value, node.lineno, "string"))
    return out


def _target(name: str, found: dict) -> str | None:
    """The module a name means: itself, or for a string its longest prefix that is a module
    (past `glint`: "glint.exr" is a file name)."""
    parts = name.split(".")
    for n in range(len(parts), 1, -1):
        if ".".join(parts[:n]) in found:
            return ".".join(parts[:n])
    return "glint" if name == "glint" else None


@pytest.fixture(scope="module")
def graph() -> nx.DiGraph:
    found = modules()
    g = nx.DiGraph()
    g.add_nodes_from(found)
    g.graph["dynamic"] = []
    for module, path in found.items():
        for name, line, kind in imports(path, module):
            if kind == "dynamic":
                g.graph["dynamic"].append(f"{module} (line {line})")
                continue
            top = name.split(".")[0]
            assert top not in BARE, f"{path.relative_to(ROOT)}:{line}: imports the bare name '{name}' (use glint.{name})"
            target = name if kind == "import" else _target(name, found)
            if target in found and target != module:
                g.add_edge(module, target, line=line, kind=kind)
    return g


def test_the_package_is_found_where_the_tests_run():
    """The folders are installed under one namespace: glint.bake is the checkout's bake/."""
    import glint.bake

    assert Path(glint.bake.__file__).resolve().parent == ROOT / "bake"
    assert Path(glint.__file__).resolve().parent == ROOT / "glint"


def test_every_module_is_in_the_graph(graph):
    assert {"glint", "glint.cli", "glint.services", "glint.core.scene", "glint.bake.pipeline",
            "glint.viewer.renderer", "glint.bench.bench", "glint.cubemap_stage"} <= set(graph)
    assert graph.number_of_edges() > 100
    # the edges this test once dropped: to the package `glint`, and by string
    assert graph.has_edge("glint.parallel.executor", "glint") and graph.has_edge("glint.cli", "glint")
    assert graph.edges["glint.viewer.shader_source", "glint.shaders"]["kind"] == "string"
    assert graph.edges["glint.services", "glint.cubemap_stage"]["kind"] in ("import", "string")
    assert {layer(m) for m in graph} == set(ALLOWED)


def test_the_package_itself_is_core():
    """glint/__init__.py, which every layer may import (its version), imports nothing of glint."""
    assert not [name for name, _, _ in imports(ROOT / "glint" / "__init__.py", "glint") if name.startswith("glint")]


def test_no_cycles(graph):
    """Over the imports; a string's module is imported later, by name and often in another process
    (a worker's pre-imports), which no import order can deadlock: string edges count for the layers."""
    imports_only = graph.edge_subgraph((a, b) for a, b, kind in graph.edges(data="kind") if kind == "import")
    cycles = list(nx.simple_cycles(imports_only))
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c + [c[0]]) for c in cycles[:5])


def test_layers(graph):
    wrong = [f"{a} -> {b} ({d['kind']}, line {d['line']}; {layer(a)} -> {layer(b)})"
             for a, b, d in graph.edges(data=True) if layer(b) not in ALLOWED[layer(a)]]
    assert not wrong, "imports against the layers of docs/ARCHITECTURE.md:\n" + "\n".join(wrong)


def test_commands_and_tools_never_import_each_other(graph):
    """Not even through the measurements or the services (which import neither)."""
    for module in graph:
        other = {"commands": "tools", "tools": "commands"}.get(layer(module))
        if other:
            reached = {m for m in nx.descendants(graph, module) if layer(m) == other}
            assert not reached, f"{module} ({layer(module)}) reaches {sorted(reached)}"


def test_the_bake_never_reaches_the_viewer(graph):
    """Not even through core: nothing the bake imports, directly or not, is the viewer's."""
    for module in (m for m in graph if layer(m) == "bake"):
        reached = nx.descendants(graph, module)
        assert not {m for m in reached if layer(m) in ("viewer", "services", "commands", "measurements", "tools")}, module


def test_dynamic_imports_are_listed(graph):
    """An import of a computed name is an edge nobody can check: only where DYNAMIC_IMPORTS says why."""
    unlisted = [where for where in graph.graph["dynamic"] if where.split(" ")[0] not in DYNAMIC_IMPORTS]
    assert not unlisted, "imports of computed names (import a literal, or pass the module):\n" + "\n".join(unlisted)
    assert {where.split(" ")[0] for where in graph.graph["dynamic"]} == DYNAMIC_IMPORTS  # no stale entry


def test_the_layers_are_documented():
    """docs/ARCHITECTURE.md describes every folder this test knows (a new folder needs a rule here
    and a line there)."""
    text = (ROOT / "docs" / "ARCHITECTURE.md").read_text()
    for folder in FOLDERS:
        assert f"`{folder}/`" in text, f"docs/ARCHITECTURE.md does not describe {folder}/"


MODULE_ROW = re.compile(r"^\|\s*`([^`]+)`\s*\|")


def documented_modules() -> list[tuple[str, str]]:
    """(path, layer) of every row of docs/ARCHITECTURE.md's "Modules, layer by layer": a table row
    whose first cell is one path in backticks, under the heading "### Layer `NAME`"."""
    text = (ROOT / "docs" / "ARCHITECTURE.md").read_text()
    section = text.split("\n## Modules, layer by layer\n", 1)[1].split("\n## ", 1)[0]
    rows, current = [], None
    for line in section.splitlines():
        if heading := re.match(r"^### Layer `(\w+)`", line):
            current = heading.group(1)
        elif (row := MODULE_ROW.match(line)) and current:
            rows.append((row.group(1), current))
    return rows


def test_every_module_is_named_once_in_architecture_md():
    """Every module of the package (every .py file of glint/, core/, bake/, viewer/ with passes/,
    bench/, scenes/; shaders/ as one folder) has exactly one row in docs/ARCHITECTURE.md's
    "Modules, layer by layer", under the layer this test gives it, and no row names a module that
    does not exist. The bug it catches: the document falling behind the code, as it had (a dozen
    modules unnamed, e.g. viewer/gl_bindings.py, where every texture unit and binding now lives),
    a module moved between layers (a bench/ measurement that gains a `__main__` block is a tool)
    with its row left under the old one, and a renamed or deleted module's row left behind.

    Deliberate bugs tried: deleting the row of `viewer/timing.py` fails ("has no row for:
    viewer/timing.py"), and so does a new file core/manifest.py without a row; moving the row of
    `bench/report.py` under "Layer `tools`" fails ("bench/report.py: documented under tools, is
    measurements"); a second row of `viewer/timing.py` fails ("more than one row"); a row of
    `viewer/old.py` fails ("rows of no module: viewer/old.py")."""
    expected = {"shaders/": "shaders"}
    for module, path in modules().items():
        if path.parent != ROOT / "shaders":
            expected[path.relative_to(ROOT).as_posix()] = layer(module)
    rows = documented_modules()
    counts = Counter(path for path, _ in rows)
    missing = sorted(set(expected) - set(counts))
    assert not missing, "docs/ARCHITECTURE.md has no row for: " + ", ".join(missing)
    twice = sorted(path for path, n in counts.items() if n > 1)
    assert not twice, "docs/ARCHITECTURE.md has more than one row for: " + ", ".join(twice)
    stale = sorted(set(counts) - set(expected))
    assert not stale, "docs/ARCHITECTURE.md has rows of no module: " + ", ".join(stale)
    wrong = [f"{path}: documented under {documented}, is {expected[path]}"
             for path, documented in rows if documented != expected[path]]
    assert not wrong, "docs/ARCHITECTURE.md puts modules under the wrong layer:\n" + "\n".join(wrong)
