"""bench/measure_gltf_albedo.py: the mapping under measurement is an argument, and glint's albedo is
kd plus the reflect lobes' albedo (computed here independently for cases with known answers)."""
from __future__ import annotations

import numpy as np

from glint.bench import measure_gltf_albedo as T
from glint.core.scene import Lobe


def test_lambert_mapping_reads_kd_and_reference_is_the_spec():
    """A mapping that makes every material a Lambertian kd = 0.5 (no lobes) reads 0.5 at every angle;
    the reference column of a white metal mirror reads 1 (0.3 %). Caught: the mapping argument ignored
    (map_pbr's metal reads 0.34 at 70 deg)."""
    rows = T.measure(mapping=lambda pbr: (np.full(3, 0.5), [], np.zeros(3)), n=4096, roughness=(0.0,),
                     metallic=(1.0,), colours={"white": (1.0, 1.0, 1.0)}, theta_deg=(0, 70), progress=None)
    assert [r.theta_deg for r in rows] == [0.0, 70.0]
    for r in rows:
        np.testing.assert_allclose(r.glint, 0.5, rtol=1e-12)
        np.testing.assert_allclose(r.reference, 1.0, rtol=3e-3)
        np.testing.assert_allclose(r.relative_difference, -0.5, rtol=3e-3)
    assert "| 0 | 1.000 / 0.500 (-50 %)" in T.markdown(rows, "t", "cmd", "abc", 4096)


def test_transmit_lobes_are_not_reflection():
    """Only reflect lobes count: a transmit lobe adds nothing to the (reflection) albedo; a Kurt
    alpha = 1/2 mirror-like reflect lobe with r0 = 1 reflects its ks (thesis 3.3: energy-neutral mirror)."""
    mirror = Lobe("reflect", (0.3, 0.3, 0.3), 1e-3, 1e-3, 1.0, 0.5)
    glass = Lobe("transmit", (1.0, 1.0, 1.0), 0.1, 0.1, 0.04, 0.0)
    a = T.glint_albedo(None, (0, 45), mapping=lambda _: (np.zeros(3), [mirror, glass], np.zeros(3)))
    np.testing.assert_allclose(a, 0.3, rtol=1e-2)
