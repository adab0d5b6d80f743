"""glTF metallic-roughness materials -> the section 3.3 BSDF (kd + lobes, Eq. 3.2-3.6).

The rule
--------
Inputs are the glTF core factors (baseColor b, metallic M, roughness r, emissive e)
and, where present, KHR_materials_transmission (t), _ior (n), _specular (s, s_c),
_anisotropy (strength a), _clearcoat (c, r_c) and _emissive_strength (k).
glTF's BRDF is mix(dielectric, metal, M), with the dielectric a Fresnel-weighted
layer of specular reflection over mix(diffuse, specular transmission, t). So:

- Lobes are fitted, not written down (issue 24): glTF's specular BRDF (GGX with alpha = r^2,
  height-correlated Smith, Schlick) is not Eq. 3.4, and with Kurt's alpha = 0 a narrow lobe's
  directional albedo falls like F cos(theta_o), so floors lost most of their reflection at the
  angles a walkthrough sees them. Each lobe's (ks, m, r0, alpha) is read from the table of
  bake/gltf_fit_table.py: the section 3.3 lobes fitted (thesis 3.4.1) to glTF's specular BRDF with
  Schlick's Fresnel of normal-incidence reflectance f0, at roughness r (`FitTable.specular_lobes`):
  one lobe, or three where one Beckmann lobe cannot follow GGX's long tail (rough metals, narrowest
  first; up to five between rows). Every rule below that emits "one lobe" of the table emits each of that row's lobes,
  with the same weights (and, with a metallicRoughnessTexture, the same m scaling).
  How close the result is: docs/SCENES.md, "glTF materials: how close".
- Diffuse: kd = b * (1 - M) * (1 - t) * share(f0), where share is what glTF's fresnel_mix leaves
  to the diffuse term (0.953 for f0 = 0.04; with KHR_materials_specular's factor s, 1 - s (1 -
  share)). The base colour texture, when present, multiplies kd (`Material.kd_texture`), as in glTF.
- Dielectric reflection: one reflect lobe, the table's for f0 = ((n - 1) / (n + 1))^2 times the
  mean of s_c (0.04 for the default n = 1.5), its ks times (1 - M) * s. No lobe when f0 = 0 (n = 1).
- Metal reflection: glTF's conductor_fresnel is Schlick's with f0 = b: b at normal incidence,
  white at grazing, per channel. The fitted lobe is the table's for f0 = max(b), its ks times M;
  Schlick's F being linear in r0, a coloured metal gets two lobes of that one shape whose sum has
  r0_c = r0 b_c / max(b) in each channel (`metal_lobes`): ks r0_c with r0 = 1 and ks (1 - r0_c)
  with r0 = 0. A grey metal keeps one lobe, ks b / max(b) with the fitted r0. Each of a rough row's
  lobes is split so (a coloured rough metal gets six lobes): with the wider two kept whole, ks
  b / max(b), orange (0.8, 0.5, 0.2) of roughness 0.7 reflected 15 % too little blue at 80 degrees.
- Transmission (t > 0): one transmit lobe (Eq. 3.5, thin surface), ks = b * (1 - M) * t,
  m = max(r^2, 1e-4), r0 = f0, alpha = 0; Eq. 3.5's (1 - F) factor plays glTF's Fresnel weighting.
- Clearcoat (c > 0): one more reflect lobe, the table's for f0 = 0.04 at roughness r_c, its ks
  times c (the layer under it is not dimmed by the coat's Fresnel, as glTF's would be).
- Anisotropy a: the tangent width widens, mx = m + (1 - m) * a^2, my = m (the
  KHR_materials_anisotropy definition, applied to Beckmann m); tangent = the
  mesh's tangent (TANGENT, else MikkTSpace from the object's uvs), rotated by
  anisotropyRotation (`Material.anisotropy_rotation`) and, per texel, towards the
  anisotropyTexture's RG direction; its B channel s scales a, so the viewer
  narrows mx per pixel to my + (mx - my) s^2 (`Material.anisotropy_texture`,
  read by the loader).
- Normal map: normalTexture (linear) and its scale go to `Material.normal_texture`
  and `normal_scale` unchanged (read by the loader); the viewer perturbs the
  shading normal of the lobes with it. The light maps keep irradiance around the
  unperturbed normal (docs/SCENES.md).
- Rough dielectrics are diffuse: a dielectric reflect lobe (base or clearcoat)
  whose roughness r >= `diffuse_roughness` (0.5; sidecar `[bake] diffuse_roughness`)
  is dropped when the material does not transmit. Its highlight is too broad to be
  worth a cube map, and Blender's default Principled BSDF exports r = 0.5, so plain
  walls stay in the `diffuse` role (light map only). The base layer's dropped lobe
  reflected (1 - M) * s times its albedo under uniform light (the table's `specular_albedo`, about
  0.05 for f0 = 0.04): that much joins kd, grey, so a wall keeps its energy (up to kd = 1). Metal and
  transmit lobes are always kept. Lobes whose ks is 0 are dropped.
- Emission (radiance, W/(m^2 sr)) = e * k; the emissiveTexture (sRGB, glTF 3.9.3) multiplies it
  per texel (`Material.emission_texture`, read by the loader).
- Coverage (glTF 3.9.4): alphaMode, alphaCutoff (default 0.5) and the alpha of
  baseColorFactor and of the base colour texture go to `Material.alpha_mode`,
  `alpha_cutoff`, `alpha` and `alpha_texture` unchanged; OPAQUE drops the alpha (the
  spec: "the rendered output is fully opaque and any alpha value is ignored"). An
  unknown mode warns and is opaque.
- metallicRoughnessTexture (linear; G multiplies r, B multiplies M, per texel; read by the
  loader with the base colour's uv set and sampler): `Material.metallic_roughness_texture` keeps
  G and M' = M x B per texel. kd becomes b * (1 - t), multiplied per texel by (1 - M') (the viewer's
  raster passes, the bake's albedo). The lobes are those the texture can need: the metal lobe
  (ks = b, times M' per texel) where some texel has M' > 0, the dielectric lobe (ks = s, times
  1 - M') where some texel has M' < 1 and, unless the material transmits, the smallest
  roughness r * min G lies below `diffuse_roughness` (then it is kept at every texel, also where
  r * G is above); the transmit lobe as without the texture (times 1 - M'). Their m is the
  table's at the texture's mean roughness r mean(G), m divided by mean(G)^2, so that per texel
  m' = max(m G^2, 1e-4) is the table's m where G is the mean (the fitted m grows about as r^2; the
  lobe keeps that row's r0 and alpha) (an anisotropic lobe keeps
  a^2 = (mx - my) / (1 - my): mx' = m' + (1 - m') a^2); `Lobe.mr` marks them ("metal",
  "dielectric"). Clearcoat and override lobes do not follow the texture. The bake's paths, which
  scatter by the lobes (bake/scatter.py), take their per-texel ks but the factor's m. Roles
  follow from the kept lobes, so a texture that can reach a narrow lobe makes the object curved or planar.
- Volume (KHR_materials_volume, t > 0): thicknessFactor > 0 makes the material a closed glass
  solid (`Material.thickness`, `ior`, `attenuation_distance`, `attenuation_color`; core/volume.py):
  the transmit lobe is then the entry interface, the bake and the viewer add the exit interface,
  the refraction and the Beer-Lambert absorption inside. Its dielectric reflect and transmit
  lobes get Kurt's alpha = 1/2 (`INTERFACE_ALPHA`): a narrow Eq. 3.4 lobe then reflects F and
  transmits 1 - F at every view angle, as a smooth interface does, instead of alpha = 0's
  F cos theta_o (a clear bottle's edges went dark). thicknessFactor is taken in metres (the
  node's scale is not applied: one material may serve nodes of several scales). thicknessFactor
  0 (the default) is thin-walled: Eq. 3.5 alone. On a material without transmission the volume
  changes nothing (no light enters it) and is not read.
- Ignored, with a warning: thickness textures (the factor is used). Occlusion
  textures are not read (the bake computes occlusion itself). Warnings repeated over materials
  are summarised per kind.

Overrides
---------
A material's `extras.glint` and the sidecar's `[materials."NAME"]` may give any
of `kd` (RGB or grey number), `emission`, `lobes` (list of {kind, ks, mx, my, r0,
alpha}, or `m` for mx = my; missing keys take `glint.core.scene.Lobe`'s defaults). Each value is
checked by its field's one rule (core/material_schema.py, which the viewer's panel applies too).
The sidecar wins over extras, extras win over the rule above; `lobes` replaces
the whole list. `kd` still multiplies a base colour texture.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from glint.bake.gltf_fit_table import fit_table
from glint.bake.validate import add_warning, check_number, warn_unknown_keys
from glint.core.bsdf import M_MIN
from glint.core.errors import GlintError, WarningKind
from glint.core.gltf_brdf import GltfMaterialParams
from glint.core.material_schema import LOBE_SCHEMA, checked_lobe, lobe_value, material_value
from glint.core.scene import Lobe, Material

DIFFUSE_ROUGHNESS = 0.5
CLEARCOAT_R0 = 0.04  # KHR_materials_clearcoat: fixed ior 1.5
# Material extensions this rule reads; others are reported by the loader.
MATERIAL_EXTENSIONS = (
    "KHR_materials_emissive_strength", "KHR_materials_transmission", "KHR_materials_ior",
    "KHR_materials_specular", "KHR_materials_anisotropy", "KHR_materials_clearcoat",
    "KHR_materials_volume",
)
OVERRIDE_KEYS = ("kd", "emission", "lobes")
# Warnings that repeat per material: one summary line each (glint.core.errors.WarningKind).
IGNORED_TEXTURES = WarningKind("{n} materials have textures glint does not read; "
                               "the constant factors are used")
LOBE_KEYS = tuple(LOBE_SCHEMA)  # kind, ks, mx, my, m, r0, alpha


@dataclass
class GltfPbr:
    """The glTF parameters the rule reads (defaults are the glTF spec's)."""

    base_color: tuple = (1.0, 1.0, 1.0)
    metallic: float = 1.0
    roughness: float = 1.0
    transmission: float = 0.0
    ior: float = 1.5
    specular: float = 1.0
    specular_color: tuple = (1.0, 1.0, 1.0)
    anisotropy: float = 0.0
    anisotropy_rotation: float = 0.0
    clearcoat: float = 0.0
    clearcoat_roughness: float = 0.0
    emissive: tuple = (0.0, 0.0, 0.0)
    emissive_strength: float = 1.0
    thickness: float = 0.0  # KHR_materials_volume: thicknessFactor (0: thin-walled)
    attenuation_distance: float = float("inf")
    attenuation_color: tuple = (1.0, 1.0, 1.0)

    @classmethod
    def from_params(cls, params: GltfMaterialParams) -> "GltfPbr":
        """The factors of core/gltf_brdf.py's parameters (`Material.gltf`, the panel's), the rest at
        the specification's defaults: `_reference` read back."""
        return cls(**{f.name: getattr(params, f.name) for f in fields(GltfMaterialParams)})


def beckmann_m(roughness: float) -> float:
    """glTF perceptual roughness -> Beckmann m of Eq. 3.3."""
    r = float(np.clip(roughness, 0.0, 1.0))
    return max(r * r, M_MIN)


GREY_METAL = 0.02  # a metal whose channels all lie within 2 % of its brightest gets one lobe (`metal_lobes`)
INTERFACE_ALPHA = 0.5  # Kurt's alpha of a glass solid's lobes: sqrt(cos_i cos_o) cancels cos_i (module docstring)


def fresnel_r0(ior: float) -> float:
    """Schlick's reflectance at normal incidence for a dielectric of index `ior` in air."""
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def dielectric_f0(p: GltfPbr) -> float:
    """The specular layer's normal-incidence reflectance: ((n - 1) / (n + 1))^2 times the mean of
    KHR_materials_specular's colour, at most 1 (its specular factor scales the layer: `map_pbr`)."""
    return float(np.clip(fresnel_r0(max(p.ior, 1.0)) * np.mean(p.specular_color), 0.0, 1.0))


def _fitted(lobes_of, roughness: float, weight, m_scale: float = 1.0) -> list[tuple]:
    """[(ks (3,), m, r0, alpha)] of each fitted lobe of `lobes_of(roughness)` (one or two), ks times
    `weight`, m times `m_scale`."""
    out = []
    for lobe in lobes_of(float(np.clip(roughness, 0.0, 1.0))):
        # no cap at 1: with a metallicRoughnessTexture the viewer's per-texel m' = m G^2 must give the
        # table's m where G is the mean, and the widest lobe's m (up to 1) over mean(G)^2 exceeds 1 (capped,
        # a uniform texture of G 0.6 rendered 37 % off its factors); Eq. 3.3 holds for any m > 0
        m = float(max(lobe.m * m_scale, M_MIN))
        out.append((_rgb3(np.asarray(weight, np.float64) * lobe.ks), m, lobe.r0, lobe.alpha))
    return out


def metal_lobes(ks, m: tuple[float, float], r0: float, alpha: float, tint, mr: str) -> list[Lobe]:
    """A metal's reflect lobes from the fitted lobe (ks, m = (mx, my), r0, alpha) of its brightest
    channel, `tint` = b / max(b). Schlick's F = r0 (1 - w) + w, w = (1 - cos)^5, is linear in r0, so
    channel c's ks F(r0_c), r0_c = r0 tint_c, is ks r0_c F(1) + ks (1 - r0_c) F(0): two lobes of the
    one shape, ks r0_c with r0 = 1 (F = 1) and ks (1 - r0_c) with r0 = 0 (F = w). A grey metal
    (every channel within GREY_METAL of the brightest) keeps one lobe, ks tint with r0: a second
    lobe costs the viewer a pattern per pixel, for at most GREY_METAL of the light at grazing."""
    tint = np.asarray(tint, np.float64)
    ks = np.asarray(ks, np.float64)
    if float(np.min(tint)) >= 1.0 - GREY_METAL:
        return [Lobe("reflect", _rgb3(ks * tint), *m, r0, alpha, mr)]
    r0_c = np.clip(r0 * tint, 0.0, 1.0)
    return [Lobe("reflect", _rgb3(ks * r0_c), *m, 1.0, alpha, mr),
            Lobe("reflect", _rgb3(ks * (1.0 - r0_c)), *m, 0.0, alpha, mr)]


def map_pbr(p: GltfPbr, diffuse_roughness: float = DIFFUSE_ROUGHNESS,
            metallic_roughness: np.ndarray | None = None):
    """The rule of the module docstring: -> (kd (3,) float32, lobes, emission (3,) float32).
    `metallic_roughness`: the material's texture as `Material.metallic_roughness_texture` holds it
    (G the roughness multiplier, B the metallic M'), or None."""
    table = fit_table()
    base = np.clip(np.asarray(p.base_color, np.float64)[:3], 0.0, None)
    metal = float(np.clip(p.metallic, 0.0, 1.0))
    t = float(np.clip(p.transmission, 0.0, 1.0))
    a = float(np.clip(p.anisotropy, 0.0, 1.0))
    # `roughness` decides the rough rule (with a texture: the smallest roughness it can reach); the
    # fitted lobes are the table's at `fitted` (with a texture: at its mean G, the lobe's m divided by
    # that G^2, so that the viewer's per-texel m' = m G^2 gives the table's m where G is the mean)
    factor = float(np.clip(p.roughness, 0.0, 1.0))
    roughness, fitted, m_scale, mr = factor, factor, 1.0, ""
    if metallic_roughness is None:  # the factors: the lobes' weights at the one metallic M
        metal_ks, dielectric = metal, 1.0 - metal
    else:  # full weights, scaled per texel by M' or 1 - M'; kept if some texel needs them
        g, texel_metal = metallic_roughness[..., 1], metallic_roughness[..., 2]
        roughness *= float(np.min(g, initial=1.0))
        mean_g = float(np.mean(g)) if g.size else 1.0
        if mean_g > 0:
            fitted, m_scale = factor * mean_g, 1.0 / (mean_g * mean_g)
        metal_ks = 1.0 if np.max(texel_metal, initial=0.0) > 0 else 0.0
        dielectric = 1.0 if np.min(texel_metal, initial=1.0) < 1 else 0.0
        mr = "dielectric"
    rough = roughness >= diffuse_roughness and t == 0.0
    volume = p.thickness > 0 and t > 0
    f0 = dielectric_f0(p)
    s = float(np.clip(p.specular, 0.0, 1.0))

    def anisotropic(m):  # KHR_materials_anisotropy on Beckmann m: the tangent width widens
        return m + (1.0 - m) * a * a, m

    # fresnel_mix leaves the diffuse term (1 - s F) of the base colour (KHR_materials_specular)
    share = 1.0 - s * (1.0 - table.diffuse_share(f0)) if f0 > 0 else 1.0
    kd = base * (1.0 - metal if mr == "" else 1.0) * (1.0 - t) * share
    lobes = []
    if f0 > 0 and s > 0:
        if volume:  # a glass solid's entry interface: Kurt's alpha 1/2 (module docstring)
            m = beckmann_m(factor)
            layer = [Lobe("reflect", _rgb3(dielectric * s), *anisotropic(m), f0, INTERFACE_ALPHA, mr)]
        else:
            layer = [Lobe("reflect", ks, *anisotropic(m), r0, alpha, mr) for ks, m, r0, alpha
                     in _fitted(lambda r: table.specular_lobes(r, f0), fitted, dielectric * s, m_scale)]
        if not rough:
            lobes += layer
        else:  # a rough dielectric is diffuse: its layer's reflection joins kd, grey (module docstring),
            # never past 1 (glTF's white rough dielectric reflects more than it receives: Appendix B)
            kd = np.maximum(kd, np.minimum(kd + dielectric * s * table.specular_albedo_at(fitted, f0), 1.0))
    # a metal's Fresnel is Schlick's with f0 = base colour b (glTF conductor_fresnel): b at normal
    # incidence, white at grazing; the lobes are the table's for f0 = max(b) (module docstring)
    brightest = float(np.max(base))
    if brightest > 0:
        # each lobe split per channel (`metal_lobes`): a coloured rough metal's three lobes are six
        fits = _fitted(lambda r: table.specular_lobes(r, brightest), fitted, metal_ks, m_scale)
        for ks, m, r0, alpha in fits:
            lobes += metal_lobes(ks, anisotropic(m), r0, alpha, base / brightest, mr and "metal")
    if t > 0:
        lobes.append(Lobe("transmit", _rgb3(base * dielectric * t), *anisotropic(beckmann_m(factor)), f0,
                          INTERFACE_ALPHA if volume else 0.0, mr))
    if p.clearcoat > 0 and not (p.clearcoat_roughness >= diffuse_roughness and t == 0.0):
        for ks, m, r0, alpha in _fitted(lambda r: table.specular_lobes(r, CLEARCOAT_R0), p.clearcoat_roughness,
                                        p.clearcoat):
            lobes.append(Lobe("reflect", ks, m, m, r0, alpha))
    lobes = [lobe for lobe in lobes if max(lobe.ks) > 0]
    emission = np.asarray(p.emissive, np.float64)[:3] * p.emissive_strength
    return kd.astype(np.float32), lobes, np.clip(emission, 0.0, None).astype(np.float32)


def volume_fields(p: GltfPbr) -> dict:
    """Material's volume fields: a transmitting material with thicknessFactor > 0 is a glass solid
    (module docstring); {} for every other, whose Material keeps the thin defaults."""
    if not (p.thickness > 0 and p.transmission > 0):
        return {}
    color = np.clip(np.asarray(p.attenuation_color, np.float64), 0.0, 1.0)
    return {"ior": max(float(p.ior), 1.0), "thickness": float(p.thickness),
            "attenuation_distance": float(p.attenuation_distance),
            "attenuation_color": tuple(float(c) for c in color)}


def pbr_from_gltf(gm: dict, where: str, warnings: list[str], name: str | None = None) -> GltfPbr:
    """Read a glTF material JSON object into GltfPbr; warn about what the rule ignores
    (`name`: the material's, for the summary of a warning repeated over many materials)."""
    pmr = gm.get("pbrMetallicRoughness", {})
    ext = gm.get("extensions", {})
    p = GltfPbr(
        base_color=tuple(_floats(pmr.get("baseColorFactor", [1, 1, 1, 1]), 4, where,
                                 "baseColorFactor")[:3]),
        metallic=_float(pmr.get("metallicFactor", 1.0), where, "metallicFactor"),
        roughness=_float(pmr.get("roughnessFactor", 1.0), where, "roughnessFactor"),
        emissive=tuple(_floats(gm.get("emissiveFactor", [0, 0, 0]), 3, where, "emissiveFactor")),
    )
    e = ext.get("KHR_materials_emissive_strength", {})
    p.emissive_strength = _float(e.get("emissiveStrength", 1.0), where, "emissiveStrength")
    e = ext.get("KHR_materials_transmission", {})
    p.transmission = _float(e.get("transmissionFactor", 0.0), where, "transmissionFactor")
    e = ext.get("KHR_materials_ior", {})
    p.ior = _float(e.get("ior", 1.5), where, "ior")
    e = ext.get("KHR_materials_specular", {})
    p.specular = _float(e.get("specularFactor", 1.0), where, "specularFactor")
    p.specular_color = tuple(_floats(e.get("specularColorFactor", [1, 1, 1]), 3, where,
                                     "specularColorFactor"))
    e = ext.get("KHR_materials_anisotropy", {})
    p.anisotropy = _float(e.get("anisotropyStrength", 0.0), where, "anisotropyStrength")
    p.anisotropy_rotation = _float(e.get("anisotropyRotation", 0.0), where, "anisotropyRotation")
    e = ext.get("KHR_materials_clearcoat", {})
    p.clearcoat = _float(e.get("clearcoatFactor", 0.0), where, "clearcoatFactor")
    p.clearcoat_roughness = _float(e.get("clearcoatRoughnessFactor", 0.0), where,
                                   "clearcoatRoughnessFactor")
    e = ext.get("KHR_materials_volume", {})
    p.thickness = max(_float(e.get("thicknessFactor", 0.0), where, "thicknessFactor"), 0.0)
    distance = e.get("attenuationDistance")  # glTF: absent = infinite (no absorption)
    p.attenuation_distance = float("inf") if distance is None else _float(distance, where, "attenuationDistance")
    if p.attenuation_distance <= 0:
        add_warning(warnings, f"{where}: attenuationDistance must be > 0; no absorption")
        p.attenuation_distance = float("inf")
    p.attenuation_color = tuple(_floats(e.get("attenuationColor", [1, 1, 1]), 3, where, "attenuationColor"))

    ignored = [key for key, table in (
        ("transmissionTexture", ext.get("KHR_materials_transmission", {})),
        ("specularTexture", ext.get("KHR_materials_specular", {})),
        ("specularColorTexture", ext.get("KHR_materials_specular", {})),
        ("clearcoatTexture", ext.get("KHR_materials_clearcoat", {})),
        ("clearcoatRoughnessTexture", ext.get("KHR_materials_clearcoat", {})),
        ("clearcoatNormalTexture", ext.get("KHR_materials_clearcoat", {})),
        ("thicknessTexture", ext.get("KHR_materials_volume", {}))) if key in table]
    if ignored:
        add_warning(warnings, f"{where}: {', '.join(ignored)} not supported, "
                              "the constant factors are used",
                    IGNORED_TEXTURES, name, detail=", ".join(ignored), ignored=ignored)
    return p


ALPHA_MODES = ("OPAQUE", "MASK", "BLEND")


def coverage_from_gltf(gm: dict, alpha_texture: np.ndarray | None, where: str,
                       warnings: list[str]) -> dict:
    """alphaMode, alphaCutoff and the base colour alpha (glTF 3.9.4) -> Material's alpha fields."""
    mode = gm.get("alphaMode", "OPAQUE")
    if mode not in ALPHA_MODES:
        add_warning(warnings, f"{where}: alphaMode {mode!r} is not one of {', '.join(ALPHA_MODES)}; "
                              "rendered opaque")
        mode = "OPAQUE"
    if mode == "OPAQUE":
        return {}
    cutoff = _float(gm.get("alphaCutoff", 0.5), where, "alphaCutoff")
    factor = _floats(gm.get("pbrMetallicRoughness", {}).get("baseColorFactor", [1, 1, 1, 1]), 4, where,
                     "baseColorFactor")[3]
    texture = None
    if alpha_texture is not None and float(np.min(alpha_texture, initial=1.0)) < 1.0:
        texture = np.clip(np.nan_to_num(np.asarray(alpha_texture, np.float32)), 0.0, 1.0)
    return {"alpha_mode": mode, "alpha_cutoff": max(cutoff, 0.0),
            "alpha": float(np.clip(factor, 0.0, 1.0)), "alpha_texture": texture}


def material_from_gltf(gm: dict, name: str, *, kd_texture: np.ndarray | None = None,
                       emission_texture: np.ndarray | None = None,
                       alpha_texture: np.ndarray | None = None,
                       metallic_roughness_texture: np.ndarray | None = None,
                       normal_texture: np.ndarray | None = None,
                       anisotropy_texture: np.ndarray | None = None,
                       diffuse_roughness: float = DIFFUSE_ROUGHNESS,
                       override: dict | None = None, warnings: list[str] | None = None,
                       source: str = "") -> Material:
    """One glTF material -> Material: the rule, then `extras.glint`, then the sidecar override.
    `metallic_roughness_texture`: the glTF metallicRoughnessTexture as read (linear RGB)."""
    warnings = [] if warnings is None else warnings
    where = f"{source}: material '{name}'" if source else f"material '{name}'"
    pbr = pbr_from_gltf(gm, where, warnings, name)
    mr = None
    if metallic_roughness_texture is not None:
        mr = np.clip(np.nan_to_num(np.asarray(metallic_roughness_texture, np.float32)[..., :3]), 0.0, 1.0)
        mr[..., 2] *= float(np.clip(pbr.metallic, 0.0, 1.0))  # B x metallicFactor = the texel's M'
    kd, lobes, emission = map_pbr(pbr, diffuse_roughness, mr)
    lobes = [checked_lobe(lobe, f"{where} lobes[{k}]") for k, lobe in enumerate(lobes)]  # glTF's ranges keep them valid
    mat = Material(name=name, kd=kd, kd_texture=kd_texture, lobes=lobes, emission=emission, gltf=_reference(pbr),
                   emission_texture=emission_texture, metallic_roughness_texture=mr,
                   **volume_fields(pbr),
                   **_surface_detail(gm, pbr, normal_texture, anisotropy_texture, where),
                   double_sided=bool(gm.get("doubleSided", False)),
                   **coverage_from_gltf(gm, alpha_texture, where, warnings))
    extras = gm.get("extras")
    if isinstance(extras, dict) and "glint" in extras:
        apply_override(mat, parse_material_override(extras["glint"], f"{where} extras.glint",
                                                    warnings))
    if override:
        apply_override(mat, override)
    return mat


def _reference(p: GltfPbr):
    """The glTF factors as core/gltf_brdf.py's parameters (`Material.gltf`), for references; None
    where that BRDF does not cover the material (anisotropy, a glass solid) or its values are outside
    the specification's ranges (the mapping clamps them)."""
    if p.anisotropy > 0 or (p.thickness > 0 and p.transmission > 0):
        return None
    try:
        return GltfMaterialParams(**{f.name: getattr(p, f.name) for f in fields(GltfMaterialParams)})
    except GlintError:
        return None


def _surface_detail(gm: dict, p: GltfPbr, normal_texture, anisotropy_texture, where: str) -> dict:
    """The normal map (glTF normalTexture and its scale) and the anisotropy direction
    (KHR_materials_anisotropy rotation and texture) -> Material's fields; an anisotropy
    texture only where there is anisotropy for it to shape."""
    info = gm.get("normalTexture")
    scale = _float(info.get("scale", 1.0), where, "normalTexture.scale") if isinstance(info, dict) else 1.0
    return {"normal_texture": normal_texture, "normal_scale": scale,
            "anisotropy_rotation": p.anisotropy_rotation if p.anisotropy > 0 else 0.0,
            "anisotropy_texture": anisotropy_texture if p.anisotropy > 0 else None}


def apply_override(mat: Material, override: dict) -> Material:
    """Replace the fields given in a parsed override (see `parse_material_override`). The material is
    no longer its glTF factors' (`Material.gltf`)."""
    if any(key in override for key in OVERRIDE_KEYS):
        mat.gltf = None
    if "kd" in override:
        mat.kd = np.array(override["kd"], np.float32)
    if "emission" in override:
        mat.emission = np.array(override["emission"], np.float32)
    if "lobes" in override:
        mat.lobes = [Lobe(**vars(lobe)) for lobe in override["lobes"]]
    return mat


def override_table(entry: dict) -> dict:
    """The {kd, emission, lobes} table (a sidecar's [materials."NAME"], `parse_material_override`'s
    input) that gives a bake-manifest material entry again, as plain lists and numbers (an entry
    from the viewer's panel may hold numpy values); lobes keep LOBE_KEYS only: their manifest-only
    `mr` (how a metallic-roughness texture varies them per texel) has no sidecar key."""
    def plain(value):
        if isinstance(value, dict):
            return {k: plain(v) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return [plain(v) for v in value]
        return value.tolist() if hasattr(value, "tolist") else value  # numpy arrays and scalars

    table = {key: plain(entry[key]) for key in OVERRIDE_KEYS if key in entry}
    if isinstance(table.get("lobes"), list):
        table["lobes"] = [{k: v for k, v in lobe.items() if k in LOBE_KEYS} if isinstance(lobe, dict) else lobe
                          for lobe in table["lobes"]]
    return table


def parse_material_override(table, where: str, warnings: list[str]) -> dict:
    """Check a {kd, emission, lobes} table (sidecar or extras.glint) -> {key: value}."""
    if not isinstance(table, dict):
        raise GlintError(f"{where} must be a table with any of {', '.join(OVERRIDE_KEYS)}")
    warn_unknown_keys(table, OVERRIDE_KEYS, where, "", warnings)
    out = {}
    for key in ("kd", "emission"):
        if key in table:
            out[key] = np.array(material_value(key, table[key], where), np.float32)
    if "lobes" in table:
        if not isinstance(table["lobes"], list):
            raise GlintError(f"{where} lobes must be a list of tables "
                             "{ kind, ks, mx, my, r0, alpha }")
        out["lobes"] = [_lobe(item, f"{where} lobes[{i}]", warnings)
                        for i, item in enumerate(table["lobes"])]
    return out


def _lobe(item, where: str, warnings: list[str]) -> Lobe:
    """One lobe table; each value checked by its field's rule (core/material_schema.py)."""
    if not isinstance(item, dict):
        raise GlintError(f"{where} must be a table {{ kind, ks, mx, my, r0, alpha }}")
    warn_unknown_keys(item, LOBE_KEYS, where, "", warnings)
    if "m" in item and ("mx" in item or "my" in item):
        raise GlintError(f"{where}: give either m or mx/my, not both")
    fields = {key: lobe_value(key, item[key], where) for key in LOBE_KEYS if key in item}
    if "m" in fields:
        fields["mx"] = fields["my"] = fields.pop("m")
    if "ks" in fields:  # the scene's colours are float32
        fields["ks"] = tuple(float(c) for c in np.float32(fields["ks"]))
    return Lobe(**fields)


def _rgb3(value) -> tuple[float, float, float]:
    v = np.broadcast_to(np.asarray(value, np.float64), (3,))
    return (float(v[0]), float(v[1]), float(v[2]))


def _float(value, where: str, key: str) -> float:
    return check_number(value, f"{where}: {key}")


def _floats(value, n: int, where: str, key: str) -> list[float]:
    if not isinstance(value, list) or len(value) != n:
        raise GlintError(f"{where}: {key} must be a list of {n} numbers, not {value!r}")
    return [check_number(v, f"{where}: {key}") for v in value]
