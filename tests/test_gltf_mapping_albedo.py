"""glTF materials as their authors defined them: the directional albedo of glint's lobes for a glTF
material against the glTF specification's BRDF (issue 24).

glint's side: kd + each reflect lobe's ks x albedo, by core/bsdf.py (`lobe_albedo`), of the kd and
lobes the loader's rule makes (bake/material_mapping.py `map_pbr`, through the fitted table
bake/gltf_fit_table.py). The reference: core/gltf_brdf.py `directional_albedo`, Appendix B written
from the specification, with none of glint's model or mapping in it.

Metric: per channel, |glint - reference| / reference at view angles 0, 30, 60, 70 and 80 degrees.
Threshold 3 % where the model can follow the specification:
- dielectrics below `diffuse_roughness` (0.5), any base colour (their lobes are kept);
- grey metals (base colours 1, 0.9, 0.5; 0.2 up to roughness 0.2) up to roughness 0.7 (from 0.2 to 0.7 the table's rows have
  three lobes fitted to Eq. 3.7, their albedo held within 2.8 %; with one lobe 3.9 % at 0.5 and 5.6 %
  at 0.7);
- coloured metals (orange, gold, copper, blue) up to roughness 0.1: two lobes of one shape give each
  channel its own Schlick r0 (`metal_lobes`).
Where it cannot, the bound asserted is the measured one, and docs/SCENES.md ("glTF materials: how
close") says why:
- rougher metals, one lobe (lobe 1 is near m = 1, the widest Beckmann lobe): 3.6 % at roughness 0.8
  and 4.5 % at 1 (at 70-80 degrees);
- the dark grey metal (0.2) from roughness 0.3: 3.7 % at 0.3, 3.0 % at 0.6. Schlick's rise from 0.2
  to 1 at grazing is the most a lobe's Fresnel must follow, and raising the albedo's weight further
  cost its three lobes the shape (bake/brdf_fit.py TRANSFER_RAISE_COST; the transfer error doubled);
- rough coloured metals: each lobe's two parts take the fitted shape (m, alpha) of the brightest
  channel, and the dimmer channels' Fresnel rise towards grazing follows a Beckmann shape less well
  the rougher the lobe (orange (0.8, 0.5, 0.2): 1.2 % at roughness 0.2, 3.5 % at 0.3, 2.5 % at 0.5,
  6.5 % at 0.7, at 80 degrees in the blue channel; with only the narrowest lobe split, 9.3 % at 0.2
  and 15 % at 0.7; one lobe, before: 57 % at roughness 0.05);
- rough dielectrics (r >= 0.5): the lobe is dropped (a diffuse wall, no cube map) and its mean
  albedo joins kd, so the specification's rise towards grazing is lost (25 % at 80 degrees for
  a base colour of 0.2).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from glint.bake import material_mapping
from glint.bake.gltf_fit_table import fit_table
from glint.bake.material_mapping import GltfPbr
from glint.bench.measure_gltf_albedo import glint_albedo, reference_albedo
from glint.core.gltf_brdf import GltfMaterialParams

ANGLES = (0, 30, 60, 70, 80)
RTOL = 0.03
SAMPLES = 1 << 12  # the reference's albedo converges to 0.1 % (core/gltf_brdf.py docstring: 0.03 % at 2^14)
DIELECTRIC_ROUGHNESS = (0.0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.45)
METAL_ROUGHNESS = (0.0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7)
COLOURS = ((0.9, 0.9, 0.9), (0.8, 0.5, 0.2), (0.2, 0.2, 0.2))
GREYS = (1.0, 0.9, 0.5)
DARK_GREY, DARK_GREY_ROUGHNESS = 0.2, (0.0, 0.05, 0.1, 0.2)  # rougher: documented (module docstring)
COLOURED_METALS = ((0.8, 0.5, 0.2), (1.0, 0.78, 0.34), (0.95, 0.64, 0.54), (0.2, 0.2, 0.8))
COLOURED_ROUGHNESS = (0.0, 0.05, 0.1)


def relative_errors(factors: dict) -> np.ndarray:
    """(angles, 3): |glint - reference| / reference of one glTF material."""
    ours = glint_albedo(GltfPbr(**factors), ANGLES)
    ref = reference_albedo(GltfMaterialParams(**factors), ANGLES, n=SAMPLES)
    return np.abs(ours - ref) / np.maximum(ref, 1e-3)


def follows_the_specification() -> list[tuple[str, float]]:
    """(material, worst error) of every material of the 3 % set above that misses it."""
    misses = []
    cases = [dict(base_color=c, metallic=0.0, roughness=r) for c in COLOURS for r in DIELECTRIC_ROUGHNESS]
    cases += [dict(base_color=(g, g, g), metallic=1.0, roughness=r) for g in GREYS for r in METAL_ROUGHNESS]
    cases += [dict(base_color=(DARK_GREY,) * 3, metallic=1.0, roughness=r) for r in DARK_GREY_ROUGHNESS]
    cases += [dict(base_color=c, metallic=1.0, roughness=r) for c in COLOURED_METALS for r in COLOURED_ROUGHNESS]
    for factors in cases:
        worst = float(relative_errors(factors).max())
        if worst > RTOL:
            misses.append((str(factors), worst))
    return misses


def test_lobes_follow_the_specification_albedo():
    """Bugs it catches: Kurt's alpha = 0 for glTF lobes (the rule before issue 24: a smooth metal 66 %
    low at 70 degrees), a metal's r0 left at 1 (grey 0.2 metal: 0.2 at grazing instead of ~1), kd not
    multiplied by fresnel_mix's diffuse share (+4 % for a white dielectric), the one-lobe table of
    5d9521f (rough metals 3.9 % at roughness 0.5, 5.6 % at 0.7, grey 0.9: tried), a coloured metal as
    one lobe whose ks carries the colour (the rule before `metal_lobes`: orange 57 % low at 80
    degrees)."""
    misses = follows_the_specification()
    assert not misses, "\n".join(f"{m}: {100 * e:.1f} %" for m, e in misses)


@pytest.mark.parametrize("factors, bound", [
    (dict(base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=0.8), 0.04),
    (dict(base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=1.0), 0.05),
    (dict(base_color=(0.2, 0.2, 0.2), metallic=1.0, roughness=0.3), 0.04),
    (dict(base_color=(0.2, 0.2, 0.2), metallic=1.0, roughness=0.6), 0.035),
    (dict(base_color=(0.8, 0.5, 0.2), metallic=1.0, roughness=0.2), 0.02),
    (dict(base_color=(0.8, 0.5, 0.2), metallic=1.0, roughness=0.3), 0.04),
    (dict(base_color=(0.8, 0.5, 0.2), metallic=1.0, roughness=0.5), 0.03),
    (dict(base_color=(0.8, 0.5, 0.2), metallic=1.0, roughness=0.7), 0.07),
    (dict(base_color=(0.2, 0.2, 0.2), metallic=0.0, roughness=0.5), 0.27),
    (dict(base_color=(0.8, 0.5, 0.2), metallic=0.0, roughness=0.8), 0.13),
])
def test_where_the_model_cannot_follow_the_error_is_the_documented_one(factors, bound):
    """The model limits of the module docstring stay at their measured size."""
    assert relative_errors(factors).max() <= bound


def test_the_check_fails_with_alpha_zero(monkeypatch):
    """The table with Kurt's alpha set to 0 everywhere (the old rule's lobes, with the fitted m and
    ks) must fail the check: a test that passed it could not see the bug issue 24 reports."""
    table = fit_table()
    specular = table.specular.copy()
    specular[..., 3] = 0.0
    monkeypatch.setattr(material_mapping, "fit_table", lambda: replace(table, specular=specular))
    misses = follows_the_specification()
    assert len(misses) > 20 and max(e for _, e in misses) > 0.5
