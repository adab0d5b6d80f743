"""The fitted glTF table's rough metal rows (issue 24): three lobes fitted to Eq. 3.7's transfer error
(bake/brdf_fit.py `fit_transfer`, bench/fit_gltf_table.py), and how bake/gltf_fit_table.py reads rows
of one and of three lobes.

References: a BRDF written from three known lobes by core/bsdf.py (what the fit must give back), the
glTF specification's BRDF (core/gltf_brdf.py, Appendix B written without glint's model or mapping)
for the shipped table, and hand-made rows written here for the interpolation. Nothing expected is
taken from the code under test.
"""
from __future__ import annotations

import numpy as np
import pytest

from glint.bake import brdf_fit
from glint.bake.brdf_fit import BrdfData, fit_transfer, transfer_error
from glint.bake.gltf_fit_table import LOBES, FitTable, fit_table
from glint.core import bsdf
from glint.core.gltf_brdf import GltfMaterialParams, evaluate
from glint.core.scene import Lobe

VIEWS = (0, 30, 50, 60, 70, 80)  # fewer view angles than the fit's 18: a third of the time


def grey(ks, m, r0, alpha) -> Lobe:
    return Lobe(ks=(ks,) * 3, mx=m, my=m, r0=r0, alpha=alpha)


def test_transfer_fit_gives_back_three_known_lobes():
    """A BRDF written from three lobes (the shapes of a rough metal's fit, made up here) is fitted back
    by `fit_transfer` from its fixed starts: Eq. 3.7's error under 0.5 % at every view, each lobe's m
    within 5 % and ks within 5 %.

    Deliberate bugs this catches (tried): the lobes' ks taken as ks^2 in the objective (the fit then
    reports other ks); the lobes returned widest first. (A fit left at its first start still passes:
    on exact data the first start reaches the optimum.)"""
    known = [grey(0.3, 0.06, 0.9, 0.45), grey(0.4, 0.13, 0.95, 0.5), grey(0.2, 0.35, 0.9, 0.5)]
    data = BrdfData.from_function(lambda wi, wo: bsdf.bsdf(wi, wo, (0, 0, 0), known), views=VIEWS)
    result = fit_transfer(data, 3, width=0.06, r0_range=(0.8, 1.0), m_range=(0.02, 1.0))
    assert transfer_error(data, result.lobes).max() < 0.005, transfer_error(data, result.lobes)
    for got, want in zip(result.lobes, known):
        assert got.mx == pytest.approx(want.mx, rel=0.05), (result.lobes, known)
        assert got.ks[0] == pytest.approx(want.ks[0], rel=0.05), (result.lobes, known)


# Measured on the shipped table (bench/fit_gltf_table.py at this commit, roughness 0.2-0.7 by 0.025-0.05,
# f0 0.5, 0.9, 1): the worst share of a view's light sent the wrong way is 0.095 up to 60 degrees and
# 0.157 at 70, the worst albedo miss 3.3 % (f0 0.9, roughness 0.65, between two rows); the old table of
# two lobes fitted by least squares: 0.38 / 0.42. The dark metal (f0 0.2) follows less well: docs/SCENES.md.
ROUGH_METALS = [(r, f0) for r in (0.2, 0.25, 0.3, 0.325, 0.4, 0.45, 0.5, 0.6, 0.65, 0.7) for f0 in (0.5, 0.9, 1.0)]
THRESHOLDS = {60: 0.11, 70: 0.18, "albedo": 0.035}


@pytest.mark.parametrize("roughness, f0", ROUGH_METALS)
def test_rough_metals_send_little_light_the_wrong_way(roughness, f0):
    """A grey glTF metal of roughness 0.2-0.7 (between rows too) through the shipped table: the share of
    each view's light that glint's lobes send another way than the specification's BRDF (Eq. 3.7, per
    view over its directional albedo) is at most THRESHOLDS up to 60 and at 70 degrees, and the
    directional albedo within 3.5 % up to 80 degrees (3 % where one lobe could follow it: the rough
    rows trade that last half per cent for the shape, brdf_fit.py TRANSFER_RAISE_COST). What the floor of a room shows: the glTF metal floor
    of roughness 0.3 read 12 % bright, path traced, where this error was 0.26-0.29 (docs/BENCHMARKS.md).

    Deliberate bug this catches (tried): the table before, two lobes fitted by least squares (every
    case fails: 0.21 and more at every view)."""
    data = BrdfData.from_function(lambda wi, wo: evaluate(
        GltfMaterialParams(base_color=(f0, f0, f0), metallic=1.0, roughness=roughness), wi, wo), views=VIEWS + (85,))
    lobes = [grey(lb.ks, lb.m, lb.r0, lb.alpha) for lb in fit_table().specular_lobes(roughness, f0)]
    error = dict(zip(VIEWS, transfer_error(data, lobes)))
    assert max(error[d] for d in VIEWS if d <= 60) <= THRESHOLDS[60], error
    assert error[70] <= THRESHOLDS[70], error
    ours = brdf_fit.model_albedo(data, (0, 0, 0), lobes).mean(axis=-1)
    ref = data.albedo().mean(axis=-1)
    keep = np.degrees(data.theta_o) <= 80.5
    assert np.max(np.abs(ours[keep] / ref[keep] - 1)) < THRESHOLDS["albedo"], (ours / ref)


def test_shipped_rows_are_ordered_and_only_rough_metals_have_three():
    """Every value finite; rows with more than one lobe have LOBES of them, narrowest first (so that rows
    interpolate lobe by lobe), only at roughness 0.2-0.7 and f0 of at least 0.2; the white and the
    0.5 metal at roughness 0.3 have three, the dielectric layer (f0 0.04) one.

    Deliberate bug this catches (tried, on the table in memory): a row's lobes stored widest first."""
    check_rows(fit_table())


def check_rows(table: FitTable) -> None:
    spec = table.specular
    assert np.all(np.isfinite(spec)) and spec.shape[2] == LOBES
    count = (spec[..., 0] > 0).sum(axis=-1)
    assert set(np.unique(count)) <= {1, LOBES}
    many = count == LOBES
    assert np.all(np.diff(spec[..., 1], axis=-1)[many] >= 0)
    rough = (table.roughness >= 0.2 - 1e-9) & (table.roughness <= 0.7 + 1e-9)
    assert not np.any(many[:, ~rough]) and not np.any(many[table.f0 < 0.2 - 1e-9])
    assert len(table.specular_lobes(0.3, 1.0)) == LOBES and len(table.specular_lobes(0.3, 0.5)) == LOBES
    assert len(table.specular_lobes(0.3, 0.04)) == 1


def test_check_rows_fails_on_widest_first():
    """The row check itself can fail (the deliberate bug of the test above, kept as a test)."""
    table = fit_table()
    flipped = FitTable(table.roughness, table.f0, table.specular[:, :, ::-1].copy(), table.specular_albedo,
                       table.diffuse)
    with pytest.raises(AssertionError):
        check_rows(flipped)


def hand_table() -> FitTable:
    """Roughness rows 0.2 (one lobe), 0.3 and 0.4 (three), f0 rows 0.5 and 1 alike; made up here."""
    one = [[0.9, 0.04, 1.0, 0.5], [0.0, 0.04, 1.0, 0.5], [0.0, 0.04, 1.0, 0.5]]
    three = [[0.3, 0.06, 1.0, 0.5], [0.4, 0.12, 1.0, 0.5], [0.2, 0.32, 1.0, 0.5]]
    wider = [[0.3, 0.1, 1.0, 0.4], [0.4, 0.2, 1.0, 0.4], [0.3, 1.0, 1.0, 0.2]]
    specular = np.array([[one, three, wider]] * 2, float)
    return FitTable(roughness=np.array([0.2, 0.3, 0.4]), f0=np.array([0.5, 1.0]), specular=specular,
                    specular_albedo=np.array([[0.9, 0.88, 0.86]] * 2), diffuse=np.zeros(2))


def albedo_of(lobes, degrees: float) -> float:
    t = np.radians(degrees)
    wo = np.array([np.sin(t), 0.0, np.cos(t)])
    return sum(lb.ks * float(bsdf.lobe_albedo(wo, lb.m, lb.m, lb.r0, lb.alpha, "reflect")) for lb in lobes)


def test_rows_of_one_and_three_lobes_mix_continuously():
    """Between a one-lobe and a three-lobe row the two rows' lobes are mixed, ks times 1 - t and t (four
    lobes at roughness 0.25, each ks half its row's); between two three-lobe rows lobe by lobe (m
    through sqrt(m)). The directional albedo at 0, 60 and 80 degrees over a fine roughness scan has no
    step between neighbours above 0.5 %.

    Deliberate bug this catches (tried): the nearer row's lobes taken whole between a one-lobe and a
    three-lobe row (at roughness 0.25 the three-lobe row's ks 0.2, 0.3, 0.4 instead of the mix)."""
    table = hand_table()
    mixed = table.specular_lobes(0.25, 1.0)
    assert sorted(round(lb.ks, 6) for lb in mixed) == [0.1, 0.15, 0.2, 0.45]
    lobes = table.specular_lobes(0.35, 1.0)
    assert len(lobes) == 3 and lobes[2].m == pytest.approx(((np.sqrt(0.32) + 1.0) / 2) ** 2)
    assert lobes[0].ks == pytest.approx(0.3) and lobes[2].alpha == pytest.approx(0.35)
    rough = np.linspace(0.2, 0.4, 201)
    for degrees in (0.0, 60.0, 80.0):
        albedo = np.array([albedo_of(table.specular_lobes(float(r), 1.0), degrees) for r in rough])
        steps = np.abs(np.diff(albedo)) / albedo[1:]
        assert steps.max() < 0.005, (degrees, steps.max(), rough[1 + int(np.argmax(steps))])


def test_lobes_of_one_shape_are_returned_as_one():
    """A row whose fit put two lobes at one shape (m = 1, the widest) gives one lobe with their ks summed:
    each lobe costs the viewer samples per pixel.

    Deliberate bug this catches (tried): no merge (three lobes returned)."""
    row = [[0.5, 0.4, 1.0, 0.3], [0.2, 1.0, 1.0, 0.2], [0.3, 1.0, 1.0, 0.2]]
    table = FitTable(roughness=np.array([0.6, 0.7]), f0=np.array([0.5, 1.0]), specular=np.array([[row, row]] * 2, float),
                     specular_albedo=np.ones((2, 2)), diffuse=np.zeros(2))
    lobes = table.specular_lobes(0.65, 1.0)
    assert len(lobes) == 2 and lobes[1].ks == pytest.approx(0.5) and lobes[1].m == pytest.approx(1.0)
