"""Glass with a volume (KHR_materials_volume): the physics both the bake and the viewer use.

A volume material is a closed solid of index n in air. Light crossing it meets two interfaces,
each transmitting 1 - F (the exact unpolarised dielectric Fresnel reflectance, not Schlick's:
the ior is known), and is absorbed on the way by Beer-Lambert, exp(-sigma_a s) over the
length s inside, with sigma_a = -ln(attenuationColor) / attenuationDistance (the glTF
extension's definition: attenuationColor is what white light keeps after attenuationDistance).

The bake (bake/irradiance.py) and the viewer (shaders/specular.glsl, `volume_transmit`) both
use the slab model for one crossing: light arriving at cosine c to the entry face leaves with
its direction unchanged, having travelled inside at cos_t = sqrt(1 - (1 - c^2) / n^2) to the
face normal. So a straight ray that crosses the solid along s' (what a ray tracer measures
between the two hits) stands for a refracted path of length s' c / cos_t, and the pair of
interfaces transmits (1 - F(c))^2 (Stokes: the exit's F at the inside angle equals the
entry's at c). For a parallel slab (a window pane) all of this is exact except the light
reflected back and forth inside, (1 - F)^2 / (1 - F^2 a^2) against (1 - F)^2 (0.25 % at
normal incidence for n = 1.5).
"""
from __future__ import annotations

import numpy as np


def absorption_coefficient(color, distance: float) -> np.ndarray:
    """sigma_a (1/m, RGB) of glTF's attenuationColor and attenuationDistance; 0 for an infinite distance."""
    c = np.clip(np.nan_to_num(np.asarray(color, np.float64).reshape(3), nan=1.0), 1e-6, 1.0)
    if not np.isfinite(distance) or distance <= 0:
        return np.zeros(3)
    return -np.log(c) / float(distance)


def fresnel_dielectric(cos_i, eta):
    """Unpolarised Fresnel reflectance of light arriving at cosine cos_i from the medium of index 1
    onto one of index eta (the mean of the s and p reflectances; 1 under total internal reflection)."""
    c = np.clip(np.abs(np.asarray(cos_i, np.float64)), 0.0, 1.0)
    eta = np.asarray(eta, np.float64)
    sin2_t = (1.0 - c * c) / (eta * eta)
    cos_t = np.sqrt(np.clip(1.0 - sin2_t, 0.0, 1.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = (c - eta * cos_t) / (c + eta * cos_t)
        rp = (eta * c - cos_t) / (eta * c + cos_t)
    f = 0.5 * (rs * rs + rp * rp)
    return np.where(sin2_t >= 1.0, 1.0, np.nan_to_num(f, nan=1.0))


def refracted_cos(cos_i, ior):
    """cos of the refracted direction inside the glass (Snell) for light arriving at cos_i from air."""
    c = np.clip(np.abs(np.asarray(cos_i, np.float64)), 0.0, 1.0)
    return np.sqrt(np.clip(1.0 - (1.0 - c * c) / (np.asarray(ior, np.float64) ** 2), 0.0, 1.0))
