"""The material schema: one rule and one message per material field, for every source of a material.

A material's fields come from five places: the glTF mapping (bake/material_mapping.py `map_pbr`),
the sidecar's [materials."NAME"] and a glTF material's `extras.glint` (bake/material_mapping.py
`parse_material_override`), `--set` (bake/edits.py, through the sidecar reader) and the viewer's
material panel (viewer/material_edits.py, viewer/panel.py). Each checks a field with `material_value`
or `lobe_value`, which apply the field's `Key` (core/schema.py, the sidecar's own check) and say
"WHERE FIELD must be ALLOWED, not VALUE" in one line; the rule of each field is written once, here:

| field | rule |
|---|---|
| `kd`, `emission` | a number (grey) or 3 numbers, each finite and at least 0 (above 1 is kept; the bake and the viewer clamp kd to 1 with a warning) |
| lobe `kind` | `reflect` or `transmit` |
| lobe `ks` | as `kd` |
| lobe `m`, `mx`, `my` | a finite number of at least 0; below `M_MIN` (core/bsdf.py, 1e-4) raised to it: the lobe is a mirror there anyway, and Eq. 3.3 stays finite |
| lobe `r0`, `alpha` | a number from 0 to 1 (a reflectance, Kurt's exponent: Eq. 3.4); outside is refused, not clamped |
| `anisotropy_rotation` | a finite number (radians) |

`checked_lobe` and `checked_material` apply them to a typed `core.scene.Lobe` and a
`core.manifest.Material` (the panel's edits are `dataclasses.replace`s of those).
"""
from __future__ import annotations

from dataclasses import replace

from glint.core.bsdf import M_MIN
from glint.core.errors import GlintError
from glint.core.manifest import Material
from glint.core.scene import Lobe
from glint.core.schema import Key

LOBE_KINDS = ("reflect", "transmit")
MATERIAL_SCHEMA = {
    "kd": Key("rgb", lo=0),
    "emission": Key("rgb", lo=0),
    "anisotropy_rotation": Key("number"),  # radians, from the tangent towards the bitangent
}
LOBE_SCHEMA = {
    "kind": Key("choice", choices=LOBE_KINDS, default="reflect"),
    "ks": Key("rgb", lo=0),
    "mx": Key("number", lo=0),
    "my": Key("number", lo=0),
    "m": Key("number", lo=0),  # sets mx = my (sidecar, extras, --set, the panel's one slider)
    "r0": Key("number", lo=0, hi=1),
    "alpha": Key("number", lo=0, hi=1),
}
LOBE_FIELDS = ("kind", "ks", "mx", "my", "r0", "alpha")  # a Lobe's checked fields (`mr` is the bake's)


def _plain(value):
    """Numpy values and tuples as the plain numbers and lists a TOML or JSON reader gives."""
    if hasattr(value, "tolist"):
        return value.tolist()
    return list(value) if isinstance(value, tuple) else value


def material_value(key: str, value, where: str):
    """Material field `key` (MATERIAL_SCHEMA) checked by its one rule -> kd, emission: a list of 3
    floats; anisotropy_rotation: a float. GlintError "{where} {key} must be ..., not VALUE"."""
    checked = MATERIAL_SCHEMA[key].check(_plain(value), where, key)
    return [float(c) for c in checked] if MATERIAL_SCHEMA[key].kind == "rgb" else checked


def lobe_value(key: str, value, where: str):
    """Lobe field `key` (LOBE_SCHEMA) checked by its one rule -> ks: a tuple of 3 floats; m, mx, my:
    raised to M_MIN; the others as given. GlintError "{where} {key} must be ..., not VALUE"."""
    checked = LOBE_SCHEMA[key].check(_plain(value), where, key)
    if key == "ks":
        return tuple(float(c) for c in checked)
    return max(checked, M_MIN) if key in ("m", "mx", "my") else checked


def checked_lobe(lobe: Lobe, where: str) -> Lobe:
    """`lobe` with every field (LOBE_FIELDS) checked by its rule (`where`: 'material 'X' lobes[0]')."""
    if not isinstance(lobe, Lobe):
        raise GlintError(f"{where} must be a lobe {{ {', '.join(LOBE_FIELDS)} }}, not {lobe!r}")
    return replace(lobe, **{key: lobe_value(key, getattr(lobe, key), where) for key in LOBE_FIELDS})


def checked_material(material: Material) -> Material:
    """A manifest material (an edit: the panel's) with kd, emission, anisotropy_rotation and every
    lobe checked by their rules; GlintError naming the material and the field otherwise."""
    where = f"material '{material.name}'"
    if not isinstance(material.lobes, list):
        raise GlintError(f"{where} lobes must be a list of lobes, not {material.lobes!r}")
    return replace(material, **{key: material_value(key, getattr(material, key), where) for key in MATERIAL_SCHEMA},
                   lobes=[checked_lobe(lobe, f"{where} lobes[{k}]") for k, lobe in enumerate(material.lobes)])
