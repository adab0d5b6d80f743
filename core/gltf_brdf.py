"""The glTF 2.0 metallic-roughness BRDF, written from the specification alone: the reference.

Everything here comes from the Khronos texts, never from glint's own material model (this
module imports neither bake/material_mapping.py nor core/bsdf.py: it is what those are
checked against, issue 24). Sections cited:

- [B.2] glTF 2.0 Specification, Appendix B "BRDF Implementation", B.2 "Material Structure":
  material = mix(dielectric_brdf, metal_brdf, metallic); metal_brdf =
  conductor_fresnel(f0 = baseColor, specular_brdf(alpha = roughness^2)); dielectric_brdf =
  fresnel_mix(ior = 1.5, base = diffuse_brdf(baseColor), layer = specular_brdf(roughness^2)).
- [B.3.2] "Specular BRDF": MicrofacetBRDF = G D / (4 |N.L| |N.V|) = Vis D with the
  Trowbridge-Reitz/GGX D = alpha^2 chi+(N.H) / (pi ((N.H)^2 (alpha^2 - 1) + 1)^2) and the
  height-correlated Smith G: Vis = chi+(H.L) chi+(H.V) / (2 (|N.V| sqrt(alpha^2 + (1 - alpha^2)
  (N.L)^2) + |N.L| sqrt(alpha^2 + (1 - alpha^2) (N.V)^2))).
- [B.3.3] "Diffuse BRDF": diffuse_brdf(color) = color / pi.
- [B.3.4] "Fresnel": F = f0 + (1 - f0) (1 - |V.H|)^5; conductor_fresnel(f0, bsdf) = bsdf F;
  fresnel_mix(ior, base, layer) = mix(base, layer, F) with f0 = ((1 - ior) / (1 + ior))^2.
- [IOR] KHR_materials_ior: the 1.5 of fresnel_mix becomes `ior` (>= 1, or 0: f0 = 1).
- [SPEC] KHR_materials_specular, "Implementation": dielectric_f0 = min(f0_ior * specularColor, 1)
  * specular, dielectric_f90 = specular, dielectric_fresnel = mix(dielectric_f0, dielectric_f90,
  (1 - |V.H|)^5) (RGB), dielectric_brdf = dielectric_fresnel * specular_brdf + (1 -
  max_value(dielectric_fresnel)) * base, max_value = the largest of r, g, b.
- [TRANS] KHR_materials_transmission, "Transmission BTDF" and its implementation notes (thin
  walled): base = mix(diffuse_brdf(baseColor), specular_btdf(roughness^2) * baseColor,
  transmission); specular_btdf = Vis_T D_T with H_T = normalize(V - 2 (N.L) N + L) (L mirrored
  through the surface plane), D_T the GGX D at H_T and the *separable* Smith form
  Vis_T = chi+((H_T.L) / (N.L)) / (|N.L| + sqrt(alpha^2 + (1 - alpha^2) (N.L)^2))
        * chi+((H_T.V) / (N.V)) / (|N.V| + sqrt(alpha^2 + (1 - alpha^2) (N.V)^2)).
  The extension does not say which half vector fresnel_mix's |V.H| uses for a transmitted L;
  here it is H_T, the microfacet the light passes through (for L above the surface, H).
- [COAT] KHR_materials_clearcoat, "Implementation": coated_material = mix(material,
  clearcoat_brdf, clearcoat * clearcoat_fresnel), clearcoat_fresnel = 0.04 + (1 - 0.04)
  (1 - |V.Nc|)^5 (N.V, not V.H: the extension's "Discussion"), clearcoat_brdf = the specular
  BRDF of B.3.2 with alpha = clearcoatRoughness^2. Nc = N (no clearcoat normal texture here).
  Emission under the coat: coated_emission = emission (1 - clearcoat clearcoat_fresnel).
- [EMIT] KHR_materials_emissive_strength: emission = emissiveFactor * emissiveStrength.
- [HEITZ18] Heitz (2018), "Sampling the GGX Distribution of Visible Normals", JCGT 7(4): the
  visible-normal sampling of `sample` (listing 1) and its pdf D_V(H) = G1(V) max(0, V.H) D(H) / N.V
  (Eq. 3), with the Smith G1(V) = 2 N.V / (N.V + sqrt(alpha^2 + (1 - alpha^2) (N.V)^2)).

Conventions
- Local shading frame, z = the normal N. Directions are unit vectors shaped (..., 3): `wo`
  towards the viewer (the spec's V), `wi` towards the light (the spec's L). Parameters are one
  material (scalars); directions broadcast.
- `evaluate` returns the BRDF (reflection, wi.z > 0) or the thin-walled BTDF (wi.z < 0) as RGB,
  *without* the cosine. It is 0 for a viewer at or below the horizon (wo.z <= 0): the back of a
  double-sided surface is the caller's (flip z), as in the spec (3.9.6, the normal is reversed).
  The reflection parts need wi.z > 0 (a BRDF is defined on the upper hemisphere; the spec's
  formulas use |N.L| and would otherwise mirror it below), transmission wi.z < 0.
- Roughness 0 is a perfect mirror, which no function of directions can be. alpha = roughness^2
  is floored at ALPHA_MIN = 1e-4 (roughness 0.01): D's peak 1 / (pi alpha^2) = 3.2e7 is then
  finite in float32 too (the Mitsuba twin, bench/mitsuba_gltf_bsdf.py, uses the same floor),
  float32 rounding of a half vector (sin^2 ~ 1e-14) stays far below alpha^2 = 1e-8, and the lobe
  is narrower than anything a renderer resolves (its directional albedo equals the mirror's:
  Smith's Lambda ~ (alpha tan theta)^2 / 4 < 1e-5 up to 85 degrees).
- D's denominator (N.H)^2 (alpha^2 - 1) + 1 is computed as alpha^2 hz^2 + (hx^2 + hy^2), the same
  value for a unit H, without the cancellation of 1 - (N.H)^2 near the peak.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from glint.core.errors import GlintError

ALPHA_MIN = 1e-4          # floor of alpha = roughness^2 (module docstring)
COAT_F0 = 0.04            # [COAT]: fresnel_coat with ior = 1.5
VIS_DEN_MIN = 1e-300      # Vis denominators: only 0 when both cosines are 0, where Vis is not used
ALBEDO_N = 1 << 14        # directional_albedo's default samples: within 0.03 % of 2^19 (docs/BENCHMARKS.md)
ALBEDO_SEED = 24          # its fixed Sobol scramble: deterministic results
COMPONENTS = ("diffuse", "specular", "transmission", "clearcoat")


@dataclass(frozen=True)
class GltfMaterialParams:
    """One glTF metallic-roughness material, factors only (no textures); defaults are the
    specification's (glTF 2.0 5.19-5.20 and each extension's property table)."""

    base_color: tuple[float, float, float] = (1.0, 1.0, 1.0)   # baseColorFactor (rgb, linear)
    metallic: float = 1.0                                      # metallicFactor
    roughness: float = 1.0                                     # roughnessFactor
    ior: float = 1.5                                           # KHR_materials_ior
    specular: float = 1.0                                      # KHR_materials_specular specularFactor
    specular_color: tuple[float, float, float] = (1.0, 1.0, 1.0)  # specularColorFactor (may be > 1)
    transmission: float = 0.0                                  # KHR_materials_transmission
    clearcoat: float = 0.0                                     # KHR_materials_clearcoat clearcoatFactor
    clearcoat_roughness: float = 0.0                           # clearcoatRoughnessFactor
    emissive: tuple[float, float, float] = (0.0, 0.0, 0.0)     # emissiveFactor
    emissive_strength: float = 1.0                             # KHR_materials_emissive_strength

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            values = tuple(value) if isinstance(value, (tuple, list, np.ndarray)) else (value,)
            if f.name in ("base_color", "specular_color", "emissive"):
                if len(values) != 3:
                    raise GlintError(f"glTF material: {f.name} must have 3 components, not {len(values)}")
                object.__setattr__(self, f.name, tuple(float(v) for v in values))
            elif len(values) != 1:
                raise GlintError(f"glTF material: {f.name} must be a number")
            else:
                object.__setattr__(self, f.name, float(value))
            for v in getattr(self, f.name) if len(values) == 3 else (getattr(self, f.name),):
                if not math.isfinite(v):
                    raise GlintError(f"glTF material: {f.name} must be finite, not {v}")
        unit = ("metallic", "roughness", "specular", "transmission", "clearcoat", "clearcoat_roughness")
        for name in unit:
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise GlintError(f"glTF material: {name} must be in [0, 1], not {getattr(self, name)}")
        for name in ("base_color", "emissive"):
            if not all(0.0 <= v <= 1.0 for v in getattr(self, name)):
                raise GlintError(f"glTF material: {name} components must be in [0, 1], not {getattr(self, name)}")
        if any(v < 0.0 for v in self.specular_color):
            raise GlintError(f"glTF material: specular_color must be >= 0, not {self.specular_color}")
        if not (self.ior == 0.0 or self.ior >= 1.0):
            raise GlintError(f"glTF material: ior must be >= 1 (or 0, KHR_materials_ior), not {self.ior}")
        if self.emissive_strength < 0.0:
            raise GlintError(f"glTF material: emissive_strength must be >= 0, not {self.emissive_strength}")


# ----------------------------------------------------------------------------------- building blocks

def alpha_of(roughness: float) -> float:
    """[B.2] alpha = roughness^2, floored at ALPHA_MIN (module docstring)."""
    return max(float(roughness) ** 2, ALPHA_MIN)


def _dot(a, b):
    return np.sum(a * b, axis=-1)


def _normalize(v):
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(length, 1e-300), length[..., 0] > 0.0


def _mirror(w):
    """Reflection through the surface plane: V - 2 (N.L) N + L of [TRANS] is V + mirror(L)."""
    return w * np.array([1.0, 1.0, -1.0])


def d_ggx(h, alpha):
    """[B.3.2] D = alpha^2 chi+(N.H) / (pi ((N.H)^2 (alpha^2 - 1) + 1)^2), h a unit vector."""
    a2 = alpha * alpha
    den = a2 * h[..., 2] ** 2 + h[..., 0] ** 2 + h[..., 1] ** 2  # = (N.H)^2 (a2 - 1) + 1 (docstring)
    return np.where(h[..., 2] > 0.0, a2 / (np.pi * np.maximum(den, 1e-300) ** 2), 0.0)


def _lambda_root(cos, alpha):
    """sqrt(alpha^2 + (1 - alpha^2) cos^2), the root both Smith forms share ([B.3.2], [TRANS])."""
    a2 = alpha * alpha
    return np.sqrt(a2 + (1.0 - a2) * cos * cos)


def vis_height_correlated(nl, nv, hl, hv, alpha):
    """[B.3.2] Vis = G / (4 |N.L| |N.V|), the height-correlated Smith G."""
    nl, nv = np.abs(nl), np.abs(nv)
    den = 2.0 * (nv * _lambda_root(nl, alpha) + nl * _lambda_root(nv, alpha))
    return np.where((hl > 0.0) & (hv > 0.0), 1.0 / np.maximum(den, VIS_DEN_MIN), 0.0)


def vis_separable(nl, nv, hl, hv, alpha):
    """[TRANS] Vis_T: the separable Smith form, steps chi+((H.L)/(N.L)) and chi+((H.V)/(N.V))."""
    visible = (hl * nl > 0.0) & (hv * nv > 0.0)
    nl, nv = np.abs(nl), np.abs(nv)
    den = (nl + _lambda_root(nl, alpha)) * (nv + _lambda_root(nv, alpha))
    return np.where(visible, 1.0 / np.maximum(den, VIS_DEN_MIN), 0.0)


def smith_g1(nv, alpha):
    """[HEITZ18] G1(V) = 2 N.V / (N.V + sqrt(alpha^2 + (1 - alpha^2) (N.V)^2)) for N.V > 0."""
    nv = np.maximum(nv, 0.0)
    return 2.0 * nv / np.maximum(nv + _lambda_root(nv, alpha), VIS_DEN_MIN)


def fresnel_weight(cos):
    """[B.3.4] fresnel_w = (1 - |V.H|)^5."""
    return (1.0 - np.minimum(np.abs(cos), 1.0)) ** 5


def ior_f0(ior: float) -> float:
    """[B.3.4] f0 = ((1 - ior) / (1 + ior))^2 (ior = 0: f0 = 1, [IOR])."""
    return ((1.0 - ior) / (1.0 + ior)) ** 2


def dielectric_f0_f90(p: GltfMaterialParams):
    """[SPEC] dielectric_f0 = min(f0_ior * specularColor, 1) * specular (RGB), dielectric_f90 = specular."""
    f0 = np.minimum(ior_f0(p.ior) * np.asarray(p.specular_color), 1.0) * p.specular
    return f0, p.specular


def specular_brdf(wi, wo, alpha):
    """[B.3.2] the microfacet BRDF Vis D, on the upper hemisphere (wi.z, wo.z > 0)."""
    h, ok = _normalize(wi + wo)
    nl, nv = wi[..., 2], wo[..., 2]
    f = vis_height_correlated(nl, nv, _dot(h, wi), _dot(h, wo), alpha) * d_ggx(h, alpha)
    return np.where(ok & (nl > 0.0) & (nv > 0.0), f, 0.0), h


def specular_btdf(wi, wo, alpha):
    """[TRANS] the thin-walled microfacet BTDF Vis_T D_T for wi.z < 0 < wo.z, and H_T."""
    h, ok = _normalize(wo + _mirror(wi))  # H_T = normalize(V - 2 (N.L) N + L)
    nl, nv = wi[..., 2], wo[..., 2]
    f = vis_separable(nl, nv, _dot(h, wi), _dot(h, wo), alpha) * d_ggx(h, alpha)
    return np.where(ok & (nl < 0.0) & (nv > 0.0), f, 0.0), h


def coat_fresnel(nv):
    """[COAT] clearcoat_fresnel = 0.04 + (1 - 0.04) (1 - |V.Nc|)^5."""
    return COAT_F0 + (1.0 - COAT_F0) * fresnel_weight(nv)


# ----------------------------------------------------------------------------------- the BRDF

def evaluate(p: GltfMaterialParams, wi, wo):
    """The material's BSDF f(wi, wo) without the cosine, RGB, shape (..., 3) ([B.2], [B.3.5],
    [SPEC], [TRANS], [COAT]); reflection for wi.z > 0, thin-walled transmission for wi.z < 0."""
    wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
    base = np.asarray(p.base_color)
    alpha = alpha_of(p.roughness)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        spec, h = specular_brdf(wi, wo, alpha)
        btdf, h_t = specular_btdf(wi, wo, alpha)
        above = wi[..., 2] > 0.0
        # fresnel_mix's |V.H|: H for reflection, H_T for transmission (module docstring, [TRANS])
        vh = np.where(above, np.abs(_dot(wo, h)), np.abs(_dot(wo, h_t)))
        fw = fresnel_weight(vh)[..., None]
        f0, f90 = dielectric_f0_f90(p)
        dielectric_fresnel = f0 + (f90 - f0) * fw                         # [SPEC]
        diffuse = np.where(above[..., None], base / np.pi, 0.0)           # [B.3.3]
        transmitted = btdf[..., None] * base                              # [TRANS] specular_btdf * baseColor
        base_layer = (1.0 - p.transmission) * diffuse + p.transmission * transmitted
        dielectric = (dielectric_fresnel * spec[..., None]
                      + (1.0 - dielectric_fresnel.max(axis=-1, keepdims=True)) * base_layer)
        metal = (base + (1.0 - base) * fw) * spec[..., None]              # [B.3.4] conductor_fresnel
        material = (1.0 - p.metallic) * dielectric + p.metallic * metal   # [B.2] mix(..., metallic)
        if p.clearcoat > 0.0:                                              # [COAT] fresnel_coat
            coat, _ = specular_brdf(wi, wo, alpha_of(p.clearcoat_roughness))
            weight = (p.clearcoat * coat_fresnel(wo[..., 2]))[..., None]
            material = (1.0 - weight) * material + weight * coat[..., None]
        material = np.where((wo[..., 2] > 0.0)[..., None], material, 0.0)
    return np.nan_to_num(material, nan=0.0, posinf=0.0, neginf=0.0)


def emission(p: GltfMaterialParams, wo=(0.0, 0.0, 1.0)):
    """Emitted radiance towards wo, RGB ([EMIT]; under a clearcoat darkened by its Fresnel, [COAT])."""
    wo = np.asarray(wo, float)
    e = np.asarray(p.emissive) * p.emissive_strength
    if p.clearcoat > 0.0:
        e = e * (1.0 - p.clearcoat * coat_fresnel(wo[..., 2]))[..., None]
    return np.broadcast_to(e, wo.shape[:-1] + (3,)).copy()


# ----------------------------------------------------------------------------------- sampling

def _luminance(rgb):
    return float(np.dot(rgb, (0.2126, 0.7152, 0.0722)))  # Rec. 709 weights: only picks components


def component_probabilities(p: GltfMaterialParams, nv):
    """Probabilities of sampling diffuse, specular, transmission and clearcoat for a viewer at
    cos theta = nv (shape of nv + (4,)): each component's weight with Fresnel at N.V standing in
    for the one at V.H. Any positive choice gives an unbiased estimator (the pdf is the mixture's);
    this one follows where the energy goes so the weights f cos / pdf stay near 1."""
    nv = np.clip(np.asarray(nv, float), 0.0, 1.0)
    fw = fresnel_weight(nv)
    base = np.asarray(p.base_color)
    f0, f90 = dielectric_f0_f90(p)
    f_dielectric = float(np.max(f0)) + (f90 - float(np.max(f0))) * fw
    f_metal = _luminance(base) + (1.0 - _luminance(base)) * fw
    under_coat = 1.0 - p.clearcoat * coat_fresnel(nv)
    w = np.stack([
        (1 - p.metallic) * (1 - p.transmission) * _luminance(base) * (1 - f_dielectric),
        (1 - p.metallic) * f_dielectric + p.metallic * f_metal,
        (1 - p.metallic) * p.transmission * _luminance(base) * (1 - f_dielectric),
        np.zeros_like(nv)], axis=-1) * under_coat[..., None]
    w[..., 3] = p.clearcoat * coat_fresnel(nv)
    total = w.sum(axis=-1, keepdims=True)
    uniform = np.array([1.0, 0.0, 0.0, 0.0])  # nothing reflects: cosine sampling, still a valid pdf
    return np.where(total > 0.0, w / np.where(total > 0.0, total, 1.0), uniform)


def sample_visible_normal(wo, alpha, u1, u2):
    """[HEITZ18] listing 1: a microfacet normal distributed as D_V(H) for the view wo (wo.z > 0)."""
    vh, _ = _normalize(np.stack([alpha * wo[..., 0], alpha * wo[..., 1], wo[..., 2]], axis=-1))
    lensq = vh[..., 0] ** 2 + vh[..., 1] ** 2
    inv = 1.0 / np.sqrt(np.where(lensq > 0.0, lensq, 1.0))
    t1 = np.where((lensq > 0.0)[..., None],
                  np.stack([-vh[..., 1] * inv, vh[..., 0] * inv, np.zeros_like(lensq)], axis=-1),
                  np.array([1.0, 0.0, 0.0]))
    t2 = np.cross(vh, t1)
    r = np.sqrt(u1)
    phi = 2.0 * np.pi * u2
    p1, p2 = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1.0 + vh[..., 2])
    p2 = (1.0 - s) * np.sqrt(np.maximum(1.0 - p1 * p1, 0.0)) + s * p2
    nh = (p1[..., None] * t1 + p2[..., None] * t2
          + np.sqrt(np.maximum(1.0 - p1 * p1 - p2 * p2, 0.0))[..., None] * vh)
    ne = np.stack([alpha * nh[..., 0], alpha * nh[..., 1], np.maximum(nh[..., 2], 0.0)], axis=-1)
    return _normalize(ne)[0]


def _vndf_reflect_pdf(wi, wo, alpha):
    """[HEITZ18] Eq. 3 and the reflection Jacobian 1 / (4 V.H): pdf of wi = reflect(wo, H),
    H = normalize(wi + wo): G1(V) D(H) / (4 N.V), for wi, wo above the surface."""
    h, ok = _normalize(wi + wo)
    nv = wo[..., 2]
    pdf = smith_g1(nv, alpha) * d_ggx(h, alpha) / (4.0 * np.maximum(nv, 1e-300))
    return np.where(ok & (wi[..., 2] > 0.0) & (nv > 0.0) & (_dot(wo, h) > 0.0), pdf, 0.0)


def pdf(p: GltfMaterialParams, wi, wo):
    """The density (solid angle) of `sample`'s directions: the mixture sum_c P(c) pdf_c."""
    wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        prob = component_probabilities(p, wo[..., 2])
        alpha = alpha_of(p.roughness)
        out = prob[..., 0] * np.where((wi[..., 2] > 0.0) & (wo[..., 2] > 0.0), wi[..., 2] / np.pi, 0.0)
        out = out + prob[..., 1] * _vndf_reflect_pdf(wi, wo, alpha)
        if p.transmission > 0.0:
            out = out + prob[..., 2] * np.where(wi[..., 2] < 0.0, _vndf_reflect_pdf(_mirror(wi), wo, alpha), 0.0)
        if p.clearcoat > 0.0:
            out = out + prob[..., 3] * _vndf_reflect_pdf(wi, wo, alpha_of(p.clearcoat_roughness))
        out = np.where(wo[..., 2] > 0.0, out, 0.0)
    return np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0)


def sample(p: GltfMaterialParams, wo, u1, u2, u3):
    """Importance sampling: u1 picks a component (`component_probabilities`), (u2, u3) its
    direction: cosine-weighted for the diffuse part, GGX visible normals [HEITZ18] reflected for
    the specular and clearcoat lobes, and reflected then mirrored below the surface for the
    thin-walled transmission ([TRANS]: H_T of the mirrored wi). Returns (wi, weight, pdf):
    weight = f(wi, wo) |cos theta_i| / pdf (RGB), pdf the mixture's (`pdf`); both 0 where the
    sample is invalid (a reflected direction below the surface, a viewer at or below it)."""
    wo = np.asarray(wo, float)
    shape = np.broadcast_shapes(wo.shape[:-1], np.shape(u1), np.shape(u2), np.shape(u3))
    wo = np.broadcast_to(wo, shape + (3,))
    u1, u2, u3 = (np.broadcast_to(np.asarray(u, float), shape) for u in (u1, u2, u3))
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        prob = component_probabilities(p, wo[..., 2])
        cdf = np.cumsum(prob, axis=-1)
        component = np.minimum((u1[..., None] >= cdf[..., :-1]).sum(axis=-1), 3)
        # diffuse: cosine-weighted hemisphere (Malley's method)
        r, phi = np.sqrt(u2), 2.0 * np.pi * u3
        cosine = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(1.0 - u2, 0.0))], axis=-1)
        h = sample_visible_normal(wo, alpha_of(p.roughness), u2, u3)
        reflected = 2.0 * _dot(wo, h)[..., None] * h - wo
        h = sample_visible_normal(wo, alpha_of(p.clearcoat_roughness), u2, u3)
        coat = 2.0 * _dot(wo, h)[..., None] * h - wo
        wi = np.select([(component == c)[..., None] for c in (1, 2, 3)], [reflected, _mirror(reflected), coat], cosine)
        wi = _normalize(wi)[0]
        density = pdf(p, wi, wo)
        f = evaluate(p, wi, wo)
        weight = f * (np.abs(wi[..., 2]) / np.where(density > 0.0, density, 1.0))[..., None]
        # A component's direction on the wrong side (a visible normal reflecting below the surface)
        # is dropped: its density there is not in the mixture pdf, so evaluating it would bias.
        side = np.where(component == 2, wi[..., 2] < 0.0, wi[..., 2] > 0.0)
        valid = (density > 0.0) & (wo[..., 2] > 0.0) & side
        weight = np.where(valid[..., None], weight, 0.0)
    return wi, np.nan_to_num(weight, nan=0.0, posinf=0.0, neginf=0.0), np.where(valid, density, 0.0)


# ----------------------------------------------------------------------------------- albedo

def sobol_points(n: int, seed: int = ALBEDO_SEED):
    """n scrambled Sobol points in [0, 1)^3 (scipy.stats.qmc), fixed seed: deterministic."""
    from scipy.stats import qmc

    m = max(int(math.ceil(math.log2(max(n, 2)))), 1)
    return qmc.Sobol(d=3, scramble=True, seed=seed).random_base2(m)[:n]


def directional_albedo(p: GltfMaterialParams, theta_o, n: int = ALBEDO_N, part: str = "reflect"):
    """Directional albedo: the integral of f(wi, wo) |cos theta_i| over wi, RGB, shape
    theta_o.shape + (3,), for a viewer at theta_o (radians from the normal; phi is irrelevant:
    the BRDF is isotropic). `part`: "reflect" (upper hemisphere), "transmit" (lower) or "total".
    Estimated with `sample` (one-sample MIS over the components) at n scrambled Sobol points: the
    tests hold it to quadrature of `evaluate` and to 2^18 random points within 0.3 %."""
    if part not in ("reflect", "transmit", "total"):
        raise GlintError(f"directional_albedo: part must be reflect, transmit or total, not {part!r}")
    theta = np.asarray(theta_o, float)
    wo = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], axis=-1)[..., None, :]
    u = sobol_points(n)
    wi, weight, _ = sample(p, wo, u[:, 0], u[:, 1], u[:, 2])
    keep = {"reflect": wi[..., 2] > 0.0, "transmit": wi[..., 2] < 0.0, "total": np.ones(wi.shape[:-1], bool)}[part]
    return np.where(keep[..., None], weight, 0.0).mean(axis=-2)
