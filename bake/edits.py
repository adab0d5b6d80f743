"""Sidecar edits: `KEY=VALUE` assignments on top of a scene's NAME.glint.toml.

An assignment sets one key of the sidecar (docs/SCENES.md): KEY is a dotted TOML key path, VALUE
a TOML value, e.g.

    materials."Floor".kd=[0.3, 0.2, 0.1]
    materials."Floor".lobes=[{ kind = "reflect", m = 0.05, r0 = 0.04 }]
    objects."Teapot".role="curved"
    bake.samples=64

Both halves are read by tomllib itself (`parse_assignment`), so the syntax is exactly TOML's
(strings need their quotes: `bake.quality="draft"`). They come from `--set` on `glint capture`,
`glint bake` and `glint view`, and from the viewer's material panel (`material_assignments` of a
bake-manifest material entry).

The edited sidecar is checked by bake/sidecar.py `parse_sidecar`, exactly as a file with those keys
would be (the material schema, core/material_schema.py: a lobe `m` below 1e-4 is raised to it, a NaN
or a negative colour, an r0 above 1 is refused), and the
assignment at fault is named: the first one whose addition makes the check fail or warn (an unknown
key, which in the file would only warn, is refused: a `--set` that does nothing is a mistake). A
material or object name that matches nothing in the scene is refused by the loader
(`Sidecar.set_names`).

`save_sidecar` writes assignments into the file with tomlkit, which edits TOML in place: the
user's comments, key order and other keys stay as they were.

Where an edited scene bakes (`edited_bake_dir`): beside the scene's own bake directory, named
by a hash of the assignments (`room.bake` -> `room.edit-<hash>.bake`), first filled from the
unedited bake (bake/pipeline.py `seed`), so the stage hashes (bake/hashing.py) redo only what the
edits touch, and the unedited bake is never overwritten or made stale by an edited capture.
"""
from __future__ import annotations

import copy
import hashlib
import json
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomlkit

from glint.bake.material_mapping import OVERRIDE_KEYS
from glint.bake.sidecar import Sidecar, parse_sidecar, parse_toml, read_sidecar_text, sidecar_path
from glint.core.atomic import atomic_write_text
from glint.core.errors import GlintError, quiet
from glint.core.manifest import Material

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

EXAMPLE = "materials.\"Floor\".kd=[0.3, 0.2, 0.1]"
NAMED_TABLES = ("materials", "objects")  # tables keyed by a scene's names: a --set naming nothing is refused
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")  # TOML bare keys


@dataclass(frozen=True)
class Assignment:
    keys: tuple[str, ...]
    value: object
    text: str  # as the user gave it (messages), or format_assignment's


def parse_assignment(text: str) -> tuple[tuple[str, ...], object]:
    """`KEY=VALUE` -> (key path, value), both read by tomllib: 'materials."Floor".kd=[0.3,0.2,0.1]'
    -> (("materials", "Floor", "kd"), [0.3, 0.2, 0.1]). A GlintError naming the text otherwise."""
    where = f"--set '{text}'"
    if "\n" in text or "\r" in text:
        raise GlintError(f"{where}: one KEY=VALUE per --set, on one line")
    # The first '=' after which the left part is a whole TOML key ('=' may sit in a quoted key).
    for i in (i for i, ch in enumerate(text) if ch == "="):
        try:
            tree = tomllib.loads(f"{text[:i]} = 0")
        except tomllib.TOMLDecodeError:
            continue
        keys = []
        while isinstance(tree, dict) and len(tree) == 1:
            (key, tree), = tree.items()
            keys.append(key)
        try:
            parsed = tomllib.loads(f"value = {text[i + 1:].strip()}")
        except tomllib.TOMLDecodeError as err:
            raise GlintError(f"{where}: the value is not a TOML value ({err}); strings need quotes, "
                             "e.g. --set 'bake.quality=\"draft\"'") from None
        if list(parsed) != ["value"]:  # e.g. a second "key = value" smuggled in
            raise GlintError(f"{where}: one KEY=VALUE per --set")
        return tuple(keys), parsed["value"]
    raise GlintError(f"{where}: expected KEY=VALUE (a TOML key path and value), e.g. --set '{EXAMPLE}'")


def format_assignment(keys: tuple[str, ...], value) -> str:
    """The TOML text of an assignment, 'materials."Floor Tiles".kd = [0.3, 0.2, 0.1]' (what
    parse_assignment reads back to the same keys and value)."""
    path = ".".join(k if _BARE_KEY.fullmatch(k) else json.dumps(k) for k in keys)
    return f"{path} = {_toml_item(value).as_string()}"


def apply_assignments(data: dict, assignments: list, *, path: Path = Path("scene.glint.toml")) -> dict:
    """The sidecar `data` (as tomllib reads it; not changed) with `assignments` set: each a
    `KEY=VALUE` text or a (keys, value) pair of parse_assignment. The result is checked as the
    sidecar file `path` would be (bake/sidecar.py parse_sidecar, warnings held back): a GlintError
    names the first assignment that makes the check fail or warn."""
    items = _assignments(assignments)
    with quiet():  # the real read of the result (edited_sidecar, the loader) warns once, later
        base = parse_sidecar(data, path)  # the file's own errors stay the file's
        for n in range(1, len(items) + 1):
            try:
                side = parse_sidecar(_set(data, items[:n]), path)
            except GlintError as err:
                raise GlintError(f"--set '{items[n - 1].text}': {_unprefixed(err, path)}") from None
            new = [w for w in side.warnings if w not in base.warnings]
            if new:
                warning = _unprefixed(new[0], path).replace(" ignored (known", " (known")
                raise GlintError(f"--set '{items[n - 1].text}': {warning}")
    return _set(data, items)


def edited_sidecar(scene_path: Path, assignments: list) -> tuple[Sidecar, tuple[str, ...]]:
    """The sidecar of `scene_path` with `assignments` applied and checked, and the assignments'
    canonical texts (format_assignment: for Scene.edits, the bake's source hash and directory)."""
    path = sidecar_path(scene_path)
    text = read_sidecar_text(path)
    data = {} if text is None else parse_toml(text, path)
    items = _assignments(assignments)
    side = parse_sidecar(apply_assignments(data, items, path=path), path)
    for item in items:
        if len(item.keys) >= 2 and item.keys[0] in NAMED_TABLES:
            side.set_names.setdefault((item.keys[0], item.keys[1]), f"--set '{item.text}'")
    return side, tuple(format_assignment(item.keys, item.value) for item in items)


def material_assignments(name: str, entry: dict, original: dict | None = None) -> list[tuple[tuple[str, ...], object]]:
    """A bake-manifest material entry (bake/pipeline.py describe, the panel's Save), read by the model
    (core/manifest.py `Material.from_json`) -> the assignments of [materials."name"] kd, emission and
    lobes (their sidecar keys: not `mr`, which the texture decides) that make the loader give that
    material again; with `original` (the entry as baked) only the keys whose values differ from it.
    Numbers are written in float32's shortest form (0.7, not 0.699999988079071; 0.04, not
    0.04000000000000001), which reads back to the same float32: colours are float32 in the bake,
    and the panel's sliders give float32 values."""
    values = _sidecar_values(entry)
    before = _sidecar_values(original) if original is not None else {}
    return [(("materials", name, key), values[key]) for key in OVERRIDE_KEYS if values[key] != before.get(key)]


def _sidecar_values(entry: dict) -> dict:
    """kd, emission and lobes of a manifest material entry as the sidecar writes them."""
    material = Material.from_json(entry)
    lobes = [{"kind": str(lobe.kind), "ks": _colour(lobe.ks), "mx": _number(lobe.mx), "my": _number(lobe.my),
              "r0": _number(lobe.r0), "alpha": _number(lobe.alpha)} for lobe in material.lobes]
    return {"kd": _colour(material.kd), "emission": _colour(material.emission), "lobes": lobes}


def save_sidecar(scene_path: Path, assignments: list) -> Path:
    """Write `assignments` into the sidecar beside `scene_path` (created when absent) and return
    its path. The file is edited in place with tomlkit: comments, order and the other keys stay.
    Checked first (apply_assignments); written atomically (core/atomic.py)."""
    return save_sidecar_file(sidecar_path(scene_path), assignments)


def save_sidecar_file(path: Path, assignments: list) -> Path:
    """`save_sidecar` for the sidecar file `path` itself (`glint fit -o`)."""
    path = Path(path)
    text = read_sidecar_text(path) or ""
    items = _assignments(assignments)
    expected = apply_assignments(parse_toml(text, path), items, path=path)
    doc = tomlkit.parse(text)
    for item in items:
        _set_in_document(doc, item)
    out = tomlkit.dumps(doc)
    if parse_toml(out, path) != expected:  # tomlkit's edit must read back as the assignments say
        raise GlintError(f"{path.name}: cannot write the edits in place (its layout defeats the TOML "
                         "editor); add them by hand: " + "; ".join(i.text for i in items))
    atomic_write_text(path, out)
    return path


def edited_bake_dir(bake_dir: Path, edits: tuple[str, ...]) -> Path:
    """Where the scene with `edits` (Scene.edits) bakes when the user names no directory:
    `room.bake` -> `room.edit-<hash of the edits>.bake` beside it."""
    digest = hashlib.sha256(json.dumps(list(edits)).encode()).hexdigest()[:12]
    bake_dir = Path(bake_dir)
    stem = bake_dir.name[:-len(".bake")] if bake_dir.name.endswith(".bake") else bake_dir.name
    return bake_dir.with_name(f"{stem}.edit-{digest}.bake")


def edited_bake_keys(edits: tuple[str, ...]) -> set[str]:
    """The [bake] keys that `edits` (Scene.edits) set."""
    out = set()
    for keys, value in map(parse_assignment, edits):
        if keys[0] == "bake":
            out |= {keys[1]} if len(keys) > 1 else set(value) if isinstance(value, dict) else set()
    return out


# -- helpers -------------------------------------------------------------------------------------
def _assignments(assignments: list) -> list[Assignment]:
    out = []
    for a in assignments:
        if isinstance(a, Assignment):
            out.append(a)
        elif isinstance(a, str):
            keys, value = parse_assignment(a)
            out.append(Assignment(keys, value, a))
        else:
            keys, value = a
            out.append(Assignment(tuple(keys), value, format_assignment(tuple(keys), value)))
    return out


def _set(data: dict, items: list[Assignment]) -> dict:
    out = copy.deepcopy(data)
    for item in items:
        node = out
        for depth, key in enumerate(item.keys[:-1]):
            node = node.setdefault(key, {})
            if not isinstance(node, dict):
                raise GlintError(f"--set '{item.text}': {format_key(item.keys[:depth + 1])} is not a table "
                                 f"in the sidecar (it is {node!r})")
        node[item.keys[-1]] = copy.deepcopy(item.value)
    return out


def format_key(keys: tuple[str, ...]) -> str:
    return format_assignment(keys, 0).rsplit(" = ", 1)[0]


def _set_in_document(doc, item: Assignment) -> None:
    """Set one key in a tomlkit document: missing tables are added as [a."b"] sections (a table
    under a new one as a super table, so no empty [a] header appears); a new key goes after the
    table's last key, before the comments that introduce the next table."""
    node = doc
    for depth, key in enumerate(item.keys[:-1]):
        if key not in node:
            inner = depth + 1 < len(item.keys) - 1  # holds only tables: [materials] above [materials."X"]
            node[key] = tomlkit.table(is_super_table=inner)
        node = node[key]
    key, value = item.keys[-1], _toml_item(item.value)
    if key in node or not hasattr(node, "value") or not list(node.keys()):
        node[key] = value
    else:
        node.value._insert_after(list(node.keys())[-1], key, value)


def _toml_item(value):
    """A value as tomlkit writes it inline: tables as inline tables, lists as one-line arrays."""
    if isinstance(value, dict):
        table = tomlkit.inline_table()
        for k, v in value.items():
            table.append(k, _toml_item(v))
        return table
    if isinstance(value, list):
        array = tomlkit.array()
        for v in value:
            array.append(_toml_item(v))
        return array
    return tomlkit.item(value)


def _number(value) -> float:
    """float32's shortest decimal form of a number (reads back to the same float32)."""
    return float(np.format_float_positional(np.float32(value), unique=True, trim="0"))


def _colour(value) -> list[float]:
    """RGB as float32's shortest decimal form (reads back to the same float32)."""
    return [_number(v) for v in value]


def _unprefixed(message, path: Path) -> str:
    """parse_sidecar's message without its leading "NAME.glint.toml: " (the --set is named instead)."""
    message, prefix = str(message), f"{Path(path).name}: "
    return message[len(prefix):] if message.startswith(prefix) else message
