"""Each command imports only what it uses (glint/cli.py COMMANDS; glint.services.render_cubemaps).

What is imported is read from the interpreter itself (`-X importtime`, `sys.modules`), never timed:
start-up times are measured, not asserted (docs/VIEWER.md "Start-up times" has the figures).

Deliberate bugs tried: glint/cli.py importing glint.bench_command (then glint.bench.command) at the top (as it did) fails
`test_bake_help_imports_neither_the_renderer_nor_the_tools` ("glint.bench_command" in the list);
glint/services.py importing glint.cubemap_stage at the top fails
`test_a_bake_without_cube_maps_never_imports_the_renderer` (['glint.cubemap_stage', 'glint.viewer.renderer',
'moderngl', ...]).
"""
from __future__ import annotations

import subprocess
import sys

from conftest import FAST, write_room

HEAVY = ("moderngl", "glint.bench", "glint.viewer.renderer", "glint.cubemap_stage")


def imported_by(args: list[str], cwd) -> list[str]:
    """The modules `python -X importtime -m glint ARGS` imports, in order."""
    run = subprocess.run([sys.executable, "-X", "importtime", "-m", "glint", *args], capture_output=True,
                         text=True, cwd=cwd)
    assert run.returncode == 0, run.stderr[-3000:]
    return [line.rsplit("|", 1)[1].strip() for line in run.stderr.splitlines() if line.startswith("import time:")
            and "|" in line and not line.rstrip().endswith("imported package")]


def test_bake_help_imports_neither_the_renderer_nor_the_tools(tmp_path):
    modules = imported_by(["bake", "--help"], tmp_path)
    assert "glint.cli" in modules and "glint.options" in modules
    heavy = [m for m in modules if m.startswith(HEAVY)]
    assert not heavy, heavy


def test_version_and_help_import_no_third_party_module(tmp_path):
    """`glint --version` and `glint --help` need argparse and glint's version only (no numpy: it alone
    takes longer than the 0.3 s these may take)."""
    for args in (["--version"], ["--help"]):
        modules = imported_by(args, tmp_path)
        assert "glint.cli" in modules
        assert not [m for m in modules if m.split(".")[0] in ("numpy", "PIL", "OpenImageIO", "moderngl")], args


def test_a_bake_without_cube_maps_never_imports_the_renderer(tmp_path):
    """A bake of a scene with no curved or transmissive object renders no cube map: neither the
    cube-map stage nor moderngl is imported (glint.services.render_cubemaps imports them on demand)."""
    scene = write_room(tmp_path / "room.glb")
    options = ["-q", FAST["quality"], "--samples", str(FAST["samples"]), "--texels-per-metre",
               str(FAST["texels_per_metre"]), "--no-denoise", "-j", "1"]
    code = ("import sys; from glint.cli import main; code = main(sys.argv[1:]); "
            "print(sorted(m for m in sys.modules if m.startswith(('moderngl', 'glint.cubemap_stage', "
            "'glint.viewer.renderer')))); raise SystemExit(code)")
    run = subprocess.run([sys.executable, "-c", code, "bake", str(scene), *options], capture_output=True, text=True,
                         cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "8 of 8 objects need no cube map" in run.stdout, run.stdout
    assert run.stdout.strip().splitlines()[-1] == "[]", run.stdout
