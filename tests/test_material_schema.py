"""One material schema (core/material_schema.py): a bad value says the same thing from every source.

The same bad value (a negative m, r0 = 2, a NaN kd, an unknown lobe kind) given through the sidecar's
[materials."Floor"], a glTF material's `extras.glint`, `--set` (bake/edits.py) and the viewer's panel
(viewer/panel.py, as its message shows it) is refused with one line that names the material and ends
in the same words, "lobes[0] m must be a number of at least 0, not -1"; a value the rules take
(m = 0, raised to the BSDF's floor M_MIN) gives the same lobe from each source, and the glTF
mapping's roughness floor is that M_MIN too.

Deliberate bug tried: viewer/material_edits.py `MaterialEdits.edit` keeping the edit without
`checked_material` (the panel bypassing the schema) -> the panel accepted mx = -1, r0 = 2, alpha -0.5,
kind 'glow', the negative ks, the NaN kd and the infinite emission (set_* returned True, no message):
7 of the 8 cases of test_the_same_message_from_every_source failed (m = -1 stayed refused: the
panel's `set_lobe` checks `m` itself with the schema's `lobe_value`).
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from glint.bake.edits import apply_assignments
from glint.bake.material_mapping import beckmann_m, material_from_gltf
from glint.bake.sidecar import parse_sidecar
from glint.core.bsdf import M_MIN
from glint.core.errors import GlintError
from glint.core.manifest import Material
from glint.core.scene import Lobe
from glint.viewer.material_edits import MaterialEdits
from glint.viewer.panel import MaterialPanel

NAN = math.nan
# (the sidecar's [materials."Floor"] table, the panel's call, the message's common end)
CASES = [
    ({"lobes": [{"m": -1}]}, ("set_lobe", (0,), {"m": -1}), "lobes[0] m must be a number of at least 0, not -1"),
    ({"lobes": [{"mx": -1}]}, ("set_lobe", (0,), {"mx": -1}), "lobes[0] mx must be a number of at least 0, not -1"),
    ({"lobes": [{"r0": 2}]}, ("set_lobe", (0,), {"r0": 2}), "lobes[0] r0 must be a number from 0 to 1, not 2"),
    ({"lobes": [{"alpha": -0.5}]}, ("set_lobe", (0,), {"alpha": -0.5}),
     "lobes[0] alpha must be a number from 0 to 1, not -0.5"),
    ({"lobes": [{"kind": "glow"}]}, ("set_lobe", (0,), {"kind": "glow"}),
     "lobes[0] kind must be one of reflect, transmit, not 'glow'"),
    ({"lobes": [{"ks": [1, -1, 1]}]}, ("set_lobe", (0,), {"ks": [1, -1, 1]}),
     "lobes[0] ks must be a number or a list of 3 numbers (RGB) of at least 0, not [1, -1, 1]"),
    ({"kd": [NAN, 0, 0]}, ("set_kd", ([NAN, 0, 0],), {}),
     "kd must be a number or a list of 3 numbers (RGB) of at least 0, not [nan, 0, 0]"),
    ({"emission": [0, math.inf, 0]}, ("set_emission", ([0, math.inf, 0],), {}),
     "emission must be a number or a list of 3 numbers (RGB) of at least 0, not [0, inf, 0]"),
]


def _panel() -> MaterialPanel:
    edits = MaterialEdits([Material(name="Floor", lobes=[Lobe()])], lambda index, material: None)
    panel = MaterialPanel(edits, [("floor", 0)])
    panel.select_object(0)
    return panel


def _messages(table: dict, call) -> dict[str, str]:
    """The one-line message each source gives for `table` (the panel: `call`)."""
    out = {}
    with pytest.raises(GlintError) as e:
        parse_sidecar({"materials": {"Floor": table}}, Path("room.glint.toml"))
    out["sidecar"] = str(e.value)
    with pytest.raises(GlintError) as e:
        material_from_gltf({"extras": {"glint": table}}, "Floor", source="room.glb")
    out["extras.glint"] = str(e.value)
    (key, value), = table.items()
    with pytest.raises(GlintError) as e:
        apply_assignments({}, [(("materials", "Floor", key), value)])
    out["--set"] = str(e.value)
    panel = _panel()
    method, args, kwargs = call
    assert not getattr(panel, method)(*args, **kwargs), "the panel took a value the schema refuses"
    assert panel.entry == Material(name="Floor", lobes=[Lobe()]) and not panel.edits.undo_stack
    out["panel"] = panel.message
    return out


@pytest.mark.parametrize("table, call, says", CASES)
def test_the_same_message_from_every_source(table, call, says):
    for source, message in _messages(table, call).items():
        assert message.endswith(says) and "\n" not in message, (source, message)
        assert "Floor" in message, (source, message)


def test_a_roughness_below_the_floor_is_raised_alike():
    """m = 0 (a mirror) is taken by every source and raised to M_MIN, the glTF mapping's floor too."""
    lobes = {
        "sidecar": parse_sidecar({"materials": {"Floor": {"lobes": [{"m": 0}]}}}, Path("x.glint.toml"))
        .materials["Floor"]["lobes"][0],
        "extras.glint": material_from_gltf({"extras": {"glint": {"lobes": [{"m": 0}]}}}, "Floor").lobes[0],
    }
    panel = _panel()
    assert panel.set_lobe(0, m=0) and panel.message == ""
    lobes["panel"] = panel.entry.lobes[0]
    for source, lobe in lobes.items():
        assert (lobe.mx, lobe.my) == (M_MIN, M_MIN), source
    assert beckmann_m(0.0) == M_MIN
    smooth = material_from_gltf({"pbrMetallicRoughness": {"roughnessFactor": 0.0}}, "Metal")
    assert smooth.lobes[0].mx == smooth.lobes[0].my == M_MIN
