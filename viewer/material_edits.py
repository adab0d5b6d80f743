"""Live material edits in the viewer: checking an edited material, and the history of edits.

An edit is a bake-manifest material entry (core/bake_dir.py `materials`: name, kd, emission,
lobes = [{kind, ks, mx, my, r0, alpha}], double_sided, textures ...) that replaces the entry
of one material index. No OpenGL here: `MaterialEdits` calls `apply(index, entry)` (the
window passes `Renderer.set_material`) and the optional `on_edit(materials)`, so the history
(undo, redo, revert to the bake's materials) is testable with plain dicts.

    edits = MaterialEdits(bake.manifest["materials"], renderer.set_material, on_edit=print)
    edits.edit(3, {**edits.materials[3], "kd": [0.8, 0.1, 0.1]})
    edits.undo(); edits.redo(); edits.revert()

`checked_material` is the one check of an edited entry (GpuScene.set_material calls it too):
NaN, infinite or negative colours and non-numbers are refused with a GlintError naming the
field (the panel shows it and keeps the previous material); roughness below the BSDF's floor
`M_MIN` (core/bsdf.py, the bake's minimum too: bake/material_mapping.py) is raised to it, r0 and
alpha are clamped to [0, 1] (Eq. 3.4), kd and ks to [0, 1] as the GPU upload clamps them.
"""
from __future__ import annotations

import copy
import math
from typing import Callable

from glint.core.bsdf import M_MIN
from glint.core.errors import GlintError

LOBE_KINDS = ("reflect", "transmit")
LOBE_FIELDS = ("kind", "ks", "mx", "my", "r0", "alpha")


def _number(value, where: str, *, lo: float | None = None) -> float:
    """A finite number (not below `lo`), else GlintError naming `where`."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise GlintError(f"{where} must be a number (got {value!r})") from None
    if not math.isfinite(x):
        raise GlintError(f"{where} must be finite (got {value!r})")
    if lo is not None and x < lo:
        raise GlintError(f"{where} must be at least {lo:g} (got {x:g})")
    return x


def _rgb(value, where: str, hi: float | None = None) -> list[float]:
    """Three finite non-negative numbers (a grey number is repeated), clamped to `hi` when given."""
    if isinstance(value, (int, float)):
        value = [value] * 3
    if not isinstance(value, (list, tuple)) or len(value) < 3:
        raise GlintError(f"{where} must be an RGB triple (got {value!r})")
    rgb = [_number(v, f"{where}[{k}]", lo=0.0) for k, v in enumerate(value[:3])]
    return [min(v, hi) for v in rgb] if hi is not None else rgb


def checked_lobe(lobe: dict, where: str) -> dict:
    """One lobe {kind, ks, mx, my, r0, alpha} (`m` sets mx = my), checked and clamped (module docstring)."""
    if not isinstance(lobe, dict):
        raise GlintError(f"{where} must be a table of {', '.join(LOBE_FIELDS)} (got {lobe!r})")
    kind = lobe.get("kind", "reflect")
    if kind not in LOBE_KINDS:
        raise GlintError(f"{where}.kind must be one of {', '.join(LOBE_KINDS)} (got {kind!r})")
    m = lobe.get("m")
    mx = _number(lobe.get("mx", 0.1) if m is None else m, f"{where}.mx", lo=0.0)
    my = _number(lobe.get("my", 0.1) if m is None else m, f"{where}.my", lo=0.0)
    out = {k: v for k, v in lobe.items() if k != "m"}
    out.update(kind=kind, ks=_rgb(lobe.get("ks", (1.0, 1.0, 1.0)), f"{where}.ks", hi=1.0),
               mx=max(mx, M_MIN), my=max(my, M_MIN),
               r0=min(_number(lobe.get("r0", 0.04), f"{where}.r0", lo=0.0), 1.0),
               alpha=min(_number(lobe.get("alpha", 0.0), f"{where}.alpha", lo=0.0), 1.0))
    return out


def checked_material(entry: dict) -> dict:
    """A copy of the manifest material entry with kd, emission and lobes checked and clamped;
    GlintError naming the material and field for a value that cannot be shown."""
    if not isinstance(entry, dict):
        raise GlintError(f"a material must be a table (got {entry!r})")
    where = f"material '{entry.get('name', '?')}'"
    out = copy.deepcopy(entry)
    out["kd"] = _rgb(entry.get("kd", (0.8, 0.8, 0.8)), f"{where} kd", hi=1.0)
    out["emission"] = _rgb(entry.get("emission", (0.0, 0.0, 0.0)), f"{where} emission")
    lobes = entry.get("lobes") or []
    if not isinstance(lobes, list):
        raise GlintError(f"{where} lobes must be a list (got {lobes!r})")
    out["lobes"] = [checked_lobe(lobe, f"{where} lobes[{k}]") for k, lobe in enumerate(lobes)]
    return out


class MaterialEdits:
    """The materials as edited, and the undo / redo history of edits (module docstring).

    `baked`: the bake manifest's materials (what Revert returns to); `apply(index, entry)`
    shows an edit (raises GlintError to refuse it); `on_edit(materials)`, optional, hears of
    every change the viewer shows (edit, undo, redo, revert) with the whole list."""

    def __init__(self, baked: list[dict], apply: Callable[[int, dict], None],
                 on_edit: Callable[[list[dict]], None] | None = None):
        self.baked = copy.deepcopy(list(baked))
        self.materials = copy.deepcopy(self.baked)
        self.apply = apply
        self.on_edit = on_edit
        self.undo_stack: list[tuple[int, dict, dict, object]] = []  # (index, before, after, group)
        self.redo_stack: list[tuple[int, dict, dict, object]] = []

    def edit(self, index: int, entry: dict, group=None) -> dict:
        """Show `entry` as material `index` and record it (checked_material; GlintError refuses it and
        changes nothing). Consecutive edits with the same `group` (not None; a slider being dragged)
        form one undo step. -> the entry as applied."""
        if not 0 <= index < len(self.materials):
            raise GlintError(f"no material {index} (the scene has {len(self.materials)})")
        entry = checked_material(entry)
        before = self.materials[index]
        self._show(index, entry)
        last = self.undo_stack[-1] if self.undo_stack else None
        if group is not None and last is not None and last[3] == group and last[0] == index:
            self.undo_stack[-1] = (index, last[1], entry, group)
        else:
            self.undo_stack.append((index, before, entry, group))
        self.redo_stack.clear()
        self._notify()
        return entry

    def end_group(self) -> None:
        """The next edit starts a new undo step even with the same group (the slider was released)."""
        if self.undo_stack:
            index, before, after, _ = self.undo_stack[-1]
            self.undo_stack[-1] = (index, before, after, None)

    def undo(self) -> bool:
        return self._step(self.undo_stack, self.redo_stack, 1)  # show the step's `before`

    def redo(self) -> bool:
        return self._step(self.redo_stack, self.undo_stack, 2)  # show the step's `after`

    def _step(self, source: list, target: list, side: int) -> bool:
        """Move the last step of `source` to `target`, showing its entry number `side`."""
        if not source:
            return False
        step = source.pop()
        self._show(step[0], step[side])
        target.append(step)
        self._notify()
        return True

    def revert(self) -> bool:
        """Every material back to the bake's, as one undo step per changed material."""
        changed = [i for i, (m, b) in enumerate(zip(self.materials, self.baked)) if m != b]
        for i in changed:
            self.undo_stack.append((i, self.materials[i], copy.deepcopy(self.baked[i]), None))
            self._show(i, copy.deepcopy(self.baked[i]))
        if changed:
            self.redo_stack.clear()
            self._notify()
        return bool(changed)

    @property
    def edited(self) -> list[int]:
        """Indices of the materials that differ from the bake's."""
        return [i for i, (m, b) in enumerate(zip(self.materials, self.baked)) if m != b]

    def _show(self, index: int, entry: dict) -> None:
        self.apply(index, entry)
        self.materials[index] = entry

    def _notify(self) -> None:
        if self.on_edit is not None:
            self.on_edit(copy.deepcopy(self.materials))
