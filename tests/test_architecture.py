"""The layers of docs/ARCHITECTURE.md, checked on the import graph of the installed package.

Every `import` and `from ... import` in every module of the `glint` package (at module level
or inside a function: both are dependencies) is an edge. The test fails on

- an import cycle between modules (catches e.g. `glint.cli` importing `glint.capture` which
  imports `glint.cli` back, as the commands once did);
- an edge against the layering: core imports nothing of glint above it; the bake and the
  viewer import only core (and the viewer the shaders' package), never each other;
  nothing below the commands imports the commands or the measurement tools (catches a
  `from glint.viewer.renderer import Renderer` in the bake, as the cube-map stage once had);
- an import of the folders' bare names (`import bake`, `from viewer.camera import ...`),
  which works in a checkout and breaks in an installed package.

Deliberate bug it catches (tried): adding `from glint.viewer.camera import ViewCamera` to
bake/cubemap.py fails `test_layers`; `from glint.cli import main` in glint/services.py fails
`test_no_cycles`.
"""
from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx
import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = {"glint": "glint", "core": "glint.core", "bake": "glint.bake", "viewer": "glint.viewer",
           "shaders": "glint.shaders", "scenes": "glint.scenes", "bench": "glint.bench"}
BARE = {"core", "bake", "viewer", "shaders", "scenes", "bench"}

# layer of a module -> the layers it may import (its own included)
ALLOWED = {
    "core": {"core"},
    "bake": {"core", "bake"},
    "viewer": {"core", "viewer", "shaders"},
    "scenes": {"core", "scenes"},
    "shaders": {"shaders"},
    "services": {"core", "bake", "viewer", "scenes", "services"},
    "commands": {"core", "bake", "viewer", "scenes", "services", "commands", "bench"},
    "bench": {"core", "bake", "viewer", "scenes", "shaders", "services", "commands", "bench"},
}
SERVICES = {"glint.services", "glint.options", "glint.cubemap_stage"}


def layer(module: str) -> str:
    parts = module.split(".")
    if len(parts) > 1 and parts[1] in ("core", "bake", "viewer", "shaders", "scenes", "bench"):
        return parts[1]
    return "services" if module in SERVICES else "commands"


def modules() -> dict[str, Path]:
    found = {}
    for folder, package in FOLDERS.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            rel = path.relative_to(ROOT / folder).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            found[".".join([package, *parts])] = path
    return found


def imports(path: Path, module: str) -> list[tuple[str, int]]:
    """(imported module, line) for every import in the file, relative ones resolved."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1] + ([base] if base else []))
            out.append((base, node.lineno))
            out += [(f"{base}.{alias.name}", node.lineno) for alias in node.names]  # `from pkg import module`
    return out


@pytest.fixture(scope="module")
def graph() -> nx.DiGraph:
    found = modules()
    g = nx.DiGraph()
    g.add_nodes_from(found)
    for module, path in found.items():
        for target, line in imports(path, module):
            top = target.split(".")[0]
            assert top not in BARE, f"{path.relative_to(ROOT)}:{line}: imports the bare name '{target}' (use glint.{target})"
            # a module's own package __init__ is not an edge back to it
            if target in found and target != module and not module.startswith(target + "."):
                g.add_edge(module, target, line=line)
    return g


def test_the_package_is_found_where_the_tests_run():
    """The folders are installed under one namespace: glint.bake is the checkout's bake/."""
    import glint.bake

    assert Path(glint.bake.__file__).resolve().parent == ROOT / "bake"
    assert Path(glint.__file__).resolve().parent == ROOT / "glint"


def test_every_module_is_in_the_graph(graph):
    assert {"glint.cli", "glint.services", "glint.core.scene", "glint.bake.pipeline", "glint.viewer.renderer",
            "glint.bench.bench", "glint.cubemap_stage"} <= set(graph)
    assert graph.number_of_edges() > 100


def test_no_cycles(graph):
    cycles = list(nx.simple_cycles(graph))
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c + [c[0]]) for c in cycles[:5])


def test_layers(graph):
    wrong = [f"{a} -> {b} (line {d['line']})" for a, b, d in graph.edges(data=True)
             if layer(b) not in ALLOWED[layer(a)]]
    assert not wrong, "imports against the layers of docs/ARCHITECTURE.md:\n" + "\n".join(wrong)


def test_the_bake_never_reaches_the_viewer(graph):
    """Not even through core: nothing the bake imports, directly or not, is the viewer's."""
    for module in (m for m in graph if layer(m) == "bake"):
        reached = nx.descendants(graph, module)
        assert not {m for m in reached if layer(m) in ("viewer", "services", "commands", "bench")}, module


def test_the_layers_are_documented():
    """docs/ARCHITECTURE.md describes every folder this test knows (a new folder needs a rule here
    and a line there)."""
    text = (ROOT / "docs" / "ARCHITECTURE.md").read_text()
    for folder in FOLDERS:
        assert f"`{folder}/`" in text, f"docs/ARCHITECTURE.md does not describe {folder}/"
