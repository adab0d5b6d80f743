"""The typed bake-directory model (core/manifest.py) is the manifest's one schema.

- a real bake's manifest.json round-trips: `from_json(to_json(x)) == x`, and `to_json(from_json(j))`
  equals the file as JSON and as bytes (key order included);
- a manifest with every optional field removed (an older bake dir) loads, with the documented defaults;
- no production module reads the manifest's JSON outside the model (an AST scan, below);
- a lobe's `mx` has one default, core.scene.Lobe's, wherever a lobe dict is read.

The AST scan flags, in core/, bake/, viewer/, glint/ and bench/ (the model module and the PENDING
modules excepted): a subscript `X[...]` or a call `X.get(...)` where X is a name called `manifest`
or `old_manifest`, or an attribute `.manifest` (`bake.manifest`, `report.manifest`: the JSON views
kept for tests and pending modules). It cannot see manifest data under other names (a dict bound to
`entry`, `m`, `stats`, or passed into a function and read there under its parameter's name), nor
reads through `json.loads` of manifest.json; those the PENDING list and review cover.
Deliberate bug tried: `sky = bake.manifest.get("sky")` put back in viewer/gpu_sky.py makes
test_no_manifest_reads_outside_the_model fail, naming the file and line.
"""
import ast
import json
from pathlib import Path

import pytest

from glint.bake.pipeline import bake_scene
from glint.bake.settings import resolve_settings
from glint.bake.gltf_loader import load_scene
from glint.core.bake_dir import Bake, write_json
from glint.core.manifest import Manifest, Material, lobe_from_json
from glint.core.scene import Lobe

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "scenes"

# Modules that still read the manifest as JSON, with the reason (issue 23: to migrate next).
PENDING: dict[str, str] = {}  # every reader is migrated; a module added here says why
SCANNED = ("core", "bake", "viewer", "glint", "bench")
MODEL = "core/manifest.py"


def _bake(tmp_path, name="cornell-box"):
    scene = load_scene(SCENES / f"{name}.glb")
    out = tmp_path / f"{name}.bake"
    bake_scene(scene, resolve_settings(scene.bake_settings, quality="draft"), out, progress=False)
    return out


def test_a_real_bake_round_trips(tmp_path):
    out = _bake(tmp_path)
    text = (out / "manifest.json").read_text()
    model = Manifest.from_json(json.loads(text))
    assert Manifest.from_json(model.to_json()) == model
    assert model.to_json() == json.loads(text)
    write_json(tmp_path / "again.json", model.to_json())
    assert (tmp_path / "again.json").read_text() == text  # the same bytes, key order included
    assert Bake(out).model == model
    # the built-in scenes are glTF: each material keeps the factors it was mapped from (the panel's)
    assert all(m.gltf is not None for m in model.materials)
    assert model.materials[0].gltf == load_scene(SCENES / "cornell-box.glb").materials[0].gltf


def test_every_optional_material_entry_round_trips():
    entry = {"name": "m", "kd": [0.5, 0.5, 0.5], "emission": [0.0, 0.0, 0.0], "double_sided": True,
             "lobes": [{"kind": "transmit", "ks": [1.0, 1.0, 1.0], "mx": 0.2, "my": 0.3, "r0": 0.04, "alpha": 0.0,
                        "mr": "metal"}],
             "kd_texture": "textures/material_0.exr", "emission_texture": "textures/emission_0.exr",
             "metallic_roughness_texture": "textures/metallic_roughness_0.exr",
             "kd_sampler": {"wrap_s": "CLAMP_TO_EDGE", "wrap_t": "REPEAT", "mag_filter": "NEAREST"},
             "alpha_mode": "MASK", "alpha_cutoff": 0.25, "alpha": 0.75,
             "volume": {"ior": 1.4, "thickness": 0.1, "absorption": [0.1, 0.2, 0.3]},
             "normal_texture": "textures/normal_0.exr", "normal_scale": 0.5, "anisotropy_rotation": 0.3,
             "anisotropy_texture": "textures/anisotropy_0.exr",
             "gltf": {"base_color": [0.9, 0.6, 0.2], "metallic": 0.3, "roughness": 0.3, "ior": 1.33, "specular": 1.0,
                      "specular_color": [1.0, 1.0, 1.0], "transmission": 0.0, "clearcoat": 0.5,
                      "clearcoat_roughness": 0.0, "emissive": [0.0, 0.0, 0.0], "emissive_strength": 1.0}}
    assert Material.from_json(entry).to_json() == entry
    assert list(Material.from_json(entry).to_json()) == list(entry)


def test_an_older_bake_dir_reads_with_the_defaults(tmp_path):
    out = _bake(tmp_path)
    data = json.loads((out / "manifest.json").read_text())
    for key in ("inputs", "lightmaps_back"):
        data.pop(key)
    data["statistics"] = {k: v for k, v in data["statistics"].items()
                          if k not in ("last_bake", "ignored_features", "cluster")}
    for o in data["objects"]:
        o.pop("lightmap_back")
    write_json(out / "manifest.json", data)
    model = Bake(out).model
    assert model.inputs is None and "inputs" not in model.to_json()
    assert model.lightmaps_back == [] and not any(model.has_back(i) for i in range(len(model.objects)))
    assert model.statistics.last_bake is None and model.statistics.ignored_features == {}
    assert all(o.lightmap_back is False for o in model.objects)
    m = Material.from_json({"name": "old", "kd": [0.5, 0.5, 0.5], "emission": [0, 0, 0], "double_sided": False,
                            "lobes": [{"kind": "reflect"}], "kd_texture": None})
    assert (m.alpha_mode, m.alpha_cutoff, m.alpha, m.volume, m.normal_scale, m.gltf) == ("OPAQUE", 0.5, 1.0, None, 1.0, None)
    assert m.lobes[0].mx == m.lobes[0].my == Lobe().mx
    assert "alpha_mode" not in m.to_json()  # written as the bake writes an opaque material


def test_another_version_is_refused_in_one_line(tmp_path):
    out = _bake(tmp_path)
    data = json.loads((out / "manifest.json").read_text())
    write_json(out / "manifest.json", {**data, "version": 2})
    from glint.core.errors import GlintError
    with pytest.raises(GlintError, match="made by another version") as e:
        Bake(out)
    assert "\n" not in str(e.value)


def _manifest_reads(tree: ast.AST) -> list[int]:
    def is_manifest(node) -> bool:
        return (isinstance(node, ast.Name) and node.id in ("manifest", "old_manifest")) or \
               (isinstance(node, ast.Attribute) and node.attr == "manifest")
    lines = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Subscript) and is_manifest(node.value):
            lines.append(node.lineno)
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "get"
              and is_manifest(node.func.value)):
            lines.append(node.lineno)
    return sorted(lines)


def test_no_manifest_reads_outside_the_model():
    found = []
    for folder in SCANNED:
        for path in sorted((ROOT / folder).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if rel == MODEL or rel in PENDING:
                continue
            found += [f"{rel}:{line}" for line in _manifest_reads(ast.parse(path.read_text()))]
    assert not found, "manifest JSON read outside core/manifest.py (read Bake.model instead): " + ", ".join(found)
    for rel in PENDING:
        assert (ROOT / rel).is_file(), f"PENDING names a missing module {rel}"


def test_the_lobe_mx_default_is_one_value():
    assert lobe_from_json({}).mx == lobe_from_json({}).my == Lobe().mx
    # every literal default a module gives a lobe's mx/my agrees with it
    for folder in SCANNED:
        for path in sorted((ROOT / folder).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "get"
                        and len(node.args) == 2 and isinstance(node.args[0], ast.Constant)
                        and node.args[0].value in ("mx", "my") and isinstance(node.args[1], ast.Constant)):
                    assert node.args[1].value == Lobe().mx, f"{path.relative_to(ROOT)}:{node.lineno}"
