"""Live material edits in the viewer: the history of edits of typed materials.

An edit is a `core.manifest.Material` (a `dataclasses.replace` of the one it changes; its lobes
`core.scene.Lobe`s) that replaces the material of one index. No OpenGL here: `MaterialEdits` calls
`apply(index, material)` (the window passes `Renderer.set_material`) and the optional
`on_edit(materials)` (manifest entries: the background re-bake's boundary), so the history (undo,
redo, revert to the bake's materials) is testable without a window.

    edits = MaterialEdits(bake.model.materials, renderer.set_material, on_edit=print)
    edits.edit(3, replace(edits.materials[3], kd=[0.8, 0.1, 0.1]))
    edits.undo(); edits.redo(); edits.revert()

Every edit is checked by the material schema (core/material_schema.py `checked_material`, which
GpuScene.set_material applies too), the rules the sidecar's [materials] follow: a NaN, infinite or
negative colour, a roughness below 0, an r0 or alpha outside 0..1 or an unknown lobe kind is refused
with a GlintError naming the material and field (the panel shows it and keeps the previous
material); a roughness below the BSDF's floor `M_MIN` (core/bsdf.py) is raised to it.
"""
from __future__ import annotations

from typing import Callable

from glint.core.errors import GlintError
from glint.core.manifest import Material
from glint.core.material_schema import checked_material


class MaterialEdits:
    """The materials as edited, and the undo / redo history of edits (module docstring).

    `baked`: the bake's materials (what Revert returns to; typed, or manifest entries read by
    `Material.from_json`); `apply(index, material)` shows an edit (raises GlintError to refuse it);
    `on_edit(materials)`, optional, hears of every change the viewer shows (edit, undo, redo,
    revert) with the whole list as manifest entries (`Material.to_json`)."""

    def __init__(self, baked: list, apply: Callable[[int, Material], None],
                 on_edit: Callable[[list[dict]], None] | None = None):
        self.baked = [m if isinstance(m, Material) else Material.from_json(m) for m in baked]
        self.materials = list(self.baked)
        self.apply = apply
        self.on_edit = on_edit
        self.undo_stack: list[tuple[int, Material, Material, object]] = []  # (index, before, after, group)
        self.redo_stack: list[tuple[int, Material, Material, object]] = []

    def edit(self, index: int, material: Material, group=None) -> Material:
        """Show `material` as material `index` and record it (checked_material; GlintError refuses it and
        changes nothing). Consecutive edits with the same `group` (not None; a slider being dragged)
        form one undo step. -> the material as applied."""
        if not 0 <= index < len(self.materials):
            raise GlintError(f"no material {index} (the scene has {len(self.materials)})")
        entry = checked_material(material)
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
            self.undo_stack.append((i, self.materials[i], self.baked[i], None))
            self._show(i, self.baked[i])
        if changed:
            self.redo_stack.clear()
            self._notify()
        return bool(changed)

    @property
    def edited(self) -> list[int]:
        """Indices of the materials that differ from the bake's."""
        return [i for i, (m, b) in enumerate(zip(self.materials, self.baked)) if m != b]

    def _show(self, index: int, entry: Material) -> None:
        self.apply(index, entry)
        self.materials[index] = entry

    def _notify(self) -> None:
        if self.on_edit is not None:
            self.on_edit([m.to_json() for m in self.materials])
