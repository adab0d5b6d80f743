"""The material panel of `glint view`: the picked object's material (section 3.3), edited live.

It shows the picked object's name and material and the scene's materials (picking one edits
every object that shares it): `kd` (the base-colour texture, where there is one, still
multiplies it), emission, each lobe (kind, ks, one m while mx = my or mx and my, r0, alpha),
the anisotropy direction, and glTF-style controls (base colour, metallic, roughness,
transmission) mapped to kd and lobes by the bake's own rule, which the command layer hands in as
`pbr_mapping` (the viewer does not import the bake: docs/ARCHITECTURE.md). A material loaded from
glTF shows its author's factors (the manifest's `gltf`), and moving one keeps the others (ior,
specular, clearcoat) as they were; the lobes above show what the rule fitted to them. Other
materials show values guessed from kd and the lobes (`gltf_guess`). Buttons: Undo, Redo,
Revert (to the bake's materials), Save (the window's `on_save(materials)`).

Every widget calls one of the panel's methods (`set_kd`, `set_lobe`, `set_gltf`, ...), which
the tests call directly too; the methods build the new material (a `dataclasses.replace` of the
typed core/manifest.py Material and its core.scene.Lobe's) and hand it to viewer/material_edits.py
`MaterialEdits.edit` (checked there by the material schema, core/material_schema.py, the sidecar's
rules and messages: a refused value leaves the material as it was and its message shows in red in
the panel). A slider dragged over many
frames is one undo step (`group`).

    panel = MaterialPanel(edits, objects, pbr_mapping=mapping, on_save=save)
    panel.select_object(7)
    panel.set_lobe(0, m=0.2)
    imgui.new_frame(); panel.draw(); imgui.render()   # the widgets, once per frame
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable

from glint.core.bsdf import M_MIN
from glint.core.errors import GlintError
from glint.core.gltf_brdf import GltfMaterialParams
from glint.core.manifest import Material, lobe_from_json
from glint.core.material_schema import LOBE_KINDS, lobe_value
from glint.core.scene import Lobe
from glint.viewer.material_edits import MaterialEdits

GLTF_KEYS = ("base_color", "metallic", "roughness", "transmission")
NEW_LOBE = Lobe(ks=(0.5, 0.5, 0.5))  # the other fields Lobe's defaults
ERROR_COLOUR = (1.0, 0.35, 0.3, 1.0)
PANEL_WIDTH = 340  # pixels
MARGIN = 8  # pixels between the panel and the window's edges
MIN_HEIGHT = 120  # pixels: the panel's smallest height (a scroll bar below it)


def gltf_guess(entry: Material) -> dict:
    """glTF-style values that map (bake/material_mapping.py's rule) to this entry as closely as a
    metallic-roughness material can: the rule gives kd = b (1 - M)(1 - t), a metal lobe (r0 = 1)
    ks = b M and a transmit lobe ks = b (1 - M) t, so b = kd + metal ks + transmit ks, M and t
    follow, and the roughness is sqrt(m) of the first lobe (1 without lobes)."""
    kd = [float(c) for c in entry.kd[:3]]
    lobes = entry.lobes
    metal = next((lobe for lobe in lobes if lobe.kind == "reflect" and lobe.r0 >= 1.0), None)
    transmit = next((lobe for lobe in lobes if lobe.kind == "transmit"), None)
    mks = [float(c) for c in metal.ks[:3]] if metal else [0.0] * 3
    tks = [float(c) for c in transmit.ks[:3]] if transmit else [0.0] * 3
    base = [min(k + m + t, 1.0) for k, m, t in zip(kd, mks, tks)]
    mean = lambda v: sum(v) / 3.0  # noqa: E731
    metallic = mean(mks) / mean(base) if mean(base) > 0 else 0.0
    dielectric = mean(base) * (1.0 - metallic)
    transmission = mean(tks) / dielectric if dielectric > 0 else 0.0
    roughness = math.sqrt(max(float(lobes[0].my), 0.0)) if lobes else 1.0
    return {"base_color": base, "metallic": min(max(metallic, 0.0), 1.0), "roughness": min(roughness, 1.0),
            "transmission": min(max(transmission, 0.0), 1.0)}


def _differs(a, b) -> bool:
    """Whether two numbers or colours differ beyond float32 rounding (what the sliders hold)."""
    a, b = (list(v) if isinstance(v, (list, tuple)) else [v] for v in (a, b))
    return len(a) != len(b) or any(abs(float(x) - float(y)) > 1e-6 * max(1.0, abs(float(x))) for x, y in zip(a, b))


def _fmt(value) -> str:
    """A number (or colour) as the panel's notes show it: 3 significant digits."""
    if isinstance(value, str):
        return value
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(f"{float(v):.3g}" for v in value) + "]"
    return f"{float(value):.3g}"


class MaterialPanel:
    def __init__(self, edits: MaterialEdits, objects: list, *,
                 pbr_mapping: Callable[..., tuple[list, list]] | None = None,
                 on_save: Callable[[list[dict]], None] | None = None):
        """edits: the scene's MaterialEdits; objects: (name, material index) per object (the bake's
        order, the G-buffer's object ids); pbr_mapping(GltfMaterialParams) -> (kd, lobes as manifest
        dicts), or None (no glTF controls); on_save: the
        window's callback (None: Save is disabled)."""
        self.edits = edits
        self.objects = [(str(name), int(material)) for name, material in objects]
        self.pbr_mapping = pbr_mapping
        self.on_save = on_save
        self.visible = False
        self.picked: int | None = None  # object index
        self.material: int | None = None  # material index being edited
        self.message = ""  # the last refusal, shown in red until the next successful edit
        self.status = ""   # the last Save's outcome
        self._gltf: dict[int, dict] = {}
        self.widgets: dict[str, tuple[float, float, float, float]] = {}  # (x0, y0, x1, y1) per widget, as last drawn
        self.scroll = (0.0, 0.0)  # the panel's scroll position and its largest, as last drawn (pixels)
        self.rect: tuple[float, float, float, float] | None = None  # the panel's (x0, y0, x1, y1), as last drawn

    def contains(self, x: float, y: float) -> bool:
        """Whether window position (x, y) lies on the panel as last drawn (a click there is not a pick)."""
        r = self.rect
        return self.visible and r is not None and r[0] <= x < r[2] and r[1] <= y < r[3]

    # -- selection -------------------------------------------------------------------------------
    def select_object(self, index: int | None) -> None:
        """The picked object (None: nothing under the cursor) and its material; shows the panel."""
        if index is None or not 0 <= index < len(self.objects):
            self.picked = None
            return
        self.picked = int(index)
        self.status = ""  # the last Save's outcome belongs to what was picked before
        self.select_material(self.objects[index][1])

    def select_material(self, index: int) -> None:
        if 0 <= index < len(self.edits.materials):
            self.material = int(index)
            self.visible = True

    def sharing(self, material: int) -> list[str]:
        """Names of the objects that use `material` (all change with one edit)."""
        return [name for name, m in self.objects if m == material]

    @property
    def entry(self) -> Material | None:
        return None if self.material is None else self.edits.materials[self.material]

    # -- edits (what the widgets call) -------------------------------------------------------------
    def _edit(self, changes: dict, group=None) -> bool:
        """The material being edited with `changes` (Material fields) replaced, as an edit. An edit
        other than the glTF controls' leaves a material that no longer is its glTF factors' mapping:
        its `gltf` goes."""
        if self.material is None:
            return False
        changes = {"gltf": None, **changes}
        try:
            self.edits.edit(self.material, replace(self.entry, **changes), group=group)
        except GlintError as e:
            self.message = str(e)
            return False
        self.message = ""
        return True

    def set_kd(self, rgb, group=None) -> bool:
        return self._edit({"kd": list(rgb)}, group)

    def set_emission(self, rgb, group=None) -> bool:
        return self._edit({"emission": list(rgb)}, group)

    def set_lobe(self, k: int, group=None, **fields) -> bool:
        """Change lobe k's fields (kind, ks, mx, my, r0, alpha; `m` sets mx = my, checked as the
        sidecar's `m` is)."""
        lobes = list(self.entry.lobes)
        if not 0 <= k < len(lobes):
            self.message = f"no lobe {k}"
            return False
        if "m" in fields:
            try:
                fields["mx"] = fields["my"] = lobe_value("m", fields.pop("m"), f"material '{self.entry.name}' lobes[{k}]")
            except GlintError as e:
                self.message = str(e)
                return False
        lobes[k] = replace(lobes[k], **fields)
        return self._edit({"lobes": lobes}, group)

    def add_lobe(self) -> bool:
        return self._edit({"lobes": [*self.entry.lobes, replace(NEW_LOBE)]})

    def remove_lobe(self, k: int) -> bool:
        lobes = list(self.entry.lobes)
        return 0 <= k < len(lobes) and self._edit({"lobes": lobes[:k] + lobes[k + 1:]})

    def set_anisotropy_rotation(self, radians: float, group=None) -> bool:
        return self._edit({"anisotropy_rotation": radians}, group)

    def gltf(self) -> dict:
        """The glTF-style values shown for the material: its glTF factors, else the last set, else
        `gltf_guess`."""
        params = self.entry.gltf if self.entry is not None else None
        if params is not None:
            return {"base_color": list(params.base_color), **{k: getattr(params, k) for k in GLTF_KEYS[1:]}}
        if self.material not in self._gltf:
            self._gltf[self.material] = gltf_guess(self.entry)
        return self._gltf[self.material]

    def gltf_changes(self) -> list[str]:
        """What moving a glTF-style control would replace besides the value moved: kd and the lobes
        become the mapping's of the glTF values shown, which need not be the material's (a lobe's r0
        or alpha that no glTF value holds). One line per changed value, e.g. "lobe 0 r0: 0.05 -> 0.04";
        empty when the mapping gives the material as it is."""
        if self.pbr_mapping is None or self.entry is None:
            return []
        try:
            kd, lobes = self.pbr_mapping(self._gltf_params())
        except GlintError:
            return []
        new = [lobe_from_json(lobe) for lobe in lobes]
        old = list(self.entry.lobes)
        out = []
        if _differs(self.entry.kd[:3], kd[:3]):
            out.append(f"kd: {_fmt(self.entry.kd[:3])} -> {_fmt(kd[:3])}")
        if len(new) != len(old):
            out.append(f"lobes: {len(old)} -> {len(new)} ({', '.join(lb.kind for lb in new) or 'none'})")
        for k, (a, b) in enumerate(zip(old, new)):
            for field in ("kind", "ks", "mx", "my", "r0", "alpha"):
                x, y = getattr(a, field), getattr(b, field)
                if (x != y) if field == "kind" else _differs(x, y):
                    out.append(f"lobe {k} {field}: {_fmt(x)} -> {_fmt(y)}")
        return out

    def set_gltf(self, group=None, **values) -> bool:
        """Change glTF-style values (GLTF_KEYS) and replace kd and the lobes by the bake's mapping of them
        (its lobes handed over as manifest dicts, read by the model's `lobe_from_json`)."""
        if self.pbr_mapping is None:
            self.message = "no glTF mapping in this viewer"
            return False
        unknown = set(values) - set(GLTF_KEYS)
        if unknown:
            raise TypeError(f"unknown glTF values {sorted(unknown)}")
        state = {**self.gltf(), **values}
        try:
            params = self._gltf_params(values)
            kd, lobes = self.pbr_mapping(params)
        except GlintError as e:
            self.message = str(e)
            return False
        # a material with glTF factors keeps the new ones; another one its shown values (`_gltf`)
        keep = params if self.entry.gltf is not None else None
        if self._edit({"kd": list(kd), "lobes": [lobe_from_json(lobe) for lobe in lobes], "gltf": keep}, group):
            self._gltf[self.material] = state
            return True
        return False

    def _gltf_params(self, values: dict | None = None) -> GltfMaterialParams:
        """The glTF factors shown, with `values` (GLTF_KEYS) changed: the material's own factors
        (ior, specular, clearcoat ... kept) where it has them, else the specification's defaults
        under the shown values. Raises GlintError for a value the specification refuses."""
        shown = {**self.gltf(), **(values or {})}
        shown["base_color"] = tuple(float(c) for c in shown["base_color"][:3])
        base = self.entry.gltf if self.entry.gltf is not None else GltfMaterialParams()
        return replace(base, **shown)

    def undo(self) -> bool:
        self._gltf.clear()  # the glTF values are guessed again from what is shown
        return self.edits.undo()

    def redo(self) -> bool:
        self._gltf.clear()
        return self.edits.redo()

    def revert(self) -> bool:
        self._gltf.clear()
        return self.edits.revert()

    def save(self) -> bool:
        if self.on_save is None:
            self.status = "nothing to save to"
            return False
        try:
            self.on_save([m.to_json() for m in self.edits.materials])  # the save's one conversion
        except GlintError as e:
            self.status = f"not saved: {e}"
            return False
        self.status = f"saved ({len(self.edits.edited)} materials edited)"
        return True

    # -- the widgets --------------------------------------------------------------------------------
    def draw(self) -> None:
        """The panel's ImGui window (between imgui.new_frame() and imgui.render())."""
        if not self.visible:
            return
        from imgui_bundle import imgui  # only the window with a panel needs it

        # at the window's right edge (the overlay's text is at the left), where it fits
        display = imgui.get_io().display_size
        right = display.x - PANEL_WIDTH - MARGIN
        imgui.set_next_window_pos(imgui.ImVec2(max(MARGIN, right), MARGIN), imgui.Cond_.first_use_ever)
        # Never taller (or wider) than the window, whatever its size now: what does not fit scrolls
        # (wheel or scroll bar). A panel of fixed height ran off the bottom of a small window with
        # no scroll bar, since its contents fitted the (partly invisible) panel.
        tallest = max(display.y - 2 * MARGIN, MIN_HEIGHT)
        imgui.set_next_window_size_constraints(imgui.ImVec2(min(PANEL_WIDTH, max(display.x - 2 * MARGIN, 100)), MIN_HEIGHT),
                                               imgui.ImVec2(max(display.x - 2 * MARGIN, 100), tallest))
        imgui.set_next_window_size(imgui.ImVec2(PANEL_WIDTH, tallest), imgui.Cond_.first_use_ever)
        _, self.visible = imgui.begin("Material", self.visible)
        pos, size = imgui.get_window_pos(), imgui.get_window_size()
        self.rect = (pos.x, pos.y, pos.x + size.x, pos.y + size.y)
        self.widgets = {}
        self._draw_actions(imgui)
        self._draw_selection(imgui)
        if self.entry is not None:
            if self.message:
                imgui.text_colored(imgui.ImVec4(*ERROR_COLOUR), self.message)
            self._draw_material(imgui)
        self.scroll = (imgui.get_scroll_y(), imgui.get_scroll_max_y())
        imgui.end()

    def _where(self, imgui, key: str) -> None:
        """Record where the last widget was drawn (window coordinates), as `widgets[key]`."""
        lo, hi = imgui.get_item_rect_min(), imgui.get_item_rect_max()
        self.widgets[key] = (lo.x, lo.y, hi.x, hi.y)

    @property
    def button_centres(self) -> dict[str, tuple[float, float]]:
        """Undo, Redo, Revert, Save: the centre of each button as last drawn (window coordinates)."""
        return {k: ((r[0] + r[2]) / 2, (r[1] + r[3]) / 2) for k, r in self.widgets.items()
                if k in ("Undo", "Redo", "Revert", "Save")}

    def _draw_actions(self, imgui) -> None:
        """Undo, Redo, Revert, Save in one row at the top, and the last Save's outcome."""
        for label, action, enabled in (("Undo", self.undo, bool(self.edits.undo_stack)),
                                       ("Redo", self.redo, bool(self.edits.redo_stack)),
                                       ("Revert", self.revert, bool(self.edits.edited)),
                                       ("Save", self.save, self.on_save is not None)):
            imgui.begin_disabled(not enabled)
            if imgui.button(label):
                action()
            self._where(imgui, label)
            imgui.end_disabled()
            imgui.same_line()
        imgui.new_line()
        if self.status:
            imgui.text_wrapped(self.status)  # whole, on as many lines as it takes

    def _draw_selection(self, imgui) -> None:
        picked = self.objects[self.picked][0] if self.picked is not None else "none (click an object, or M over it)"
        imgui.text(f"object: {picked}")
        names = [m.name or f"material {i}" for i, m in enumerate(self.edits.materials)]
        current = self.material if self.material is not None else 0
        changed, index = imgui.combo("material", current, names)
        if changed:
            self.select_material(index)
        if self.material is not None:
            users = self.sharing(self.material)
            imgui.text_wrapped(f"used by {len(users)} object{'s' * (len(users) != 1)}: {', '.join(users[:6])}"
                               + (" ..." if len(users) > 6 else ""))

    def _widget(self, imgui, changed: bool, apply, key) -> None:
        """After one widget: apply its change as part of the undo group `key`; a released slider
        closes the group. Its place is recorded as `widgets[name]` ("kd", "m 0" for lobe 0's m, ...)."""
        self._where(imgui, key if isinstance(key, str) else f"{key[0]} {key[1]}")
        if changed:
            apply(group=(self.material, key))
        if imgui.is_item_deactivated():
            self.edits.end_group()

    def _draw_material(self, imgui) -> None:
        m = self.entry
        changed, kd = imgui.color_edit3("kd", list(m.kd)[:3], imgui.ColorEditFlags_.float)
        self._widget(imgui, changed, lambda group: self.set_kd(kd, group), "kd")
        if m.kd_texture:
            imgui.text_disabled("(times the base-colour texture)")
        changed, emission = imgui.drag_float3("emission", list(m.emission)[:3], 0.05, 0.0, 1e4)
        self._widget(imgui, changed, lambda group: self.set_emission(emission, group), "emission")
        lobes = m.lobes
        for k, lobe in enumerate(lobes):
            imgui.push_id(f"lobe{k}")
            if imgui.tree_node_ex(f"lobe {k}: {lobe.kind}", imgui.TreeNodeFlags_.default_open):
                self._draw_lobe(imgui, k, lobe)
                imgui.tree_pop()
            imgui.pop_id()
        if imgui.button("add lobe"):
            self.add_lobe()
        if m.anisotropy_rotation or any(lb.mx != lb.my for lb in lobes):
            changed, angle = imgui.slider_angle("anisotropy direction", float(m.anisotropy_rotation),
                                                -180.0, 180.0)
            self._widget(imgui, changed, lambda group: self.set_anisotropy_rotation(angle, group), "rotation")
        if self.pbr_mapping is not None and self._header(imgui, "glTF-style"):
            changes = self.gltf_changes()
            if changes:  # said before the first move replaces them, not after
                imgui.text_wrapped("Moving these sets kd and the lobes by the glTF rule, replacing "
                                   + "; ".join(changes))
            else:
                imgui.text_wrapped("These set kd and the lobes by the glTF rule.")
            g = self.gltf()
            changed, base = imgui.color_edit3("base colour", list(g["base_color"]), imgui.ColorEditFlags_.float)
            self._widget(imgui, changed, lambda group: self.set_gltf(group, base_color=base), "base_color")
            for key in ("metallic", "roughness", "transmission"):
                changed, value = imgui.slider_float(key, float(g[key]), 0.0, 1.0)
                self._widget(imgui, changed, lambda group, key=key, value=value: self.set_gltf(group, **{key: value}),
                             key)

    def _header(self, imgui, label: str) -> bool:
        """A collapsing header, its place recorded (`widgets[label]`); True while open."""
        is_open = imgui.collapsing_header(label)
        self._where(imgui, label)
        return is_open

    def _draw_lobe(self, imgui, k: int, lobe: Lobe) -> None:
        kind = lobe.kind
        changed, choice = imgui.combo("kind", LOBE_KINDS.index(kind) if kind in LOBE_KINDS else 0, list(LOBE_KINDS))
        if changed:
            self.set_lobe(k, kind=LOBE_KINDS[choice])
        changed, ks = imgui.color_edit3("ks", list(lobe.ks)[:3], imgui.ColorEditFlags_.float)
        self._widget(imgui, changed, lambda group: self.set_lobe(k, group, ks=ks), ("ks", k))
        mx, my = float(lobe.mx), float(lobe.my)
        flags = imgui.SliderFlags_.logarithmic
        if mx == my:
            changed, m = imgui.slider_float("m", mx, M_MIN, 1.0, "%.4f", flags)
            self._widget(imgui, changed, lambda group: self.set_lobe(k, group, m=m), ("m", k))
        else:
            changed, mx = imgui.slider_float("mx", mx, M_MIN, 1.0, "%.4f", flags)
            self._widget(imgui, changed, lambda group: self.set_lobe(k, group, mx=mx), ("mx", k))
            changed, my = imgui.slider_float("my", my, M_MIN, 1.0, "%.4f", flags)
            self._widget(imgui, changed, lambda group: self.set_lobe(k, group, my=my), ("my", k))
        changed, anisotropic = imgui.checkbox("anisotropic", mx != my)
        if changed:
            self.set_lobe(k, mx=mx, my=min(2.0 * mx, 1.0) if anisotropic else mx)
        changed, r0 = imgui.slider_float("r0", float(lobe.r0), 0.0, 1.0)
        self._widget(imgui, changed, lambda group: self.set_lobe(k, group, r0=r0), ("r0", k))
        changed, alpha = imgui.slider_float("alpha", float(lobe.alpha), 0.0, 1.0)
        self._widget(imgui, changed, lambda group: self.set_lobe(k, group, alpha=alpha), ("alpha", k))
        if imgui.small_button("remove lobe"):
            self.remove_lobe(k)
