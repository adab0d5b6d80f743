"""The glTF 2.0 metallic-roughness BRDF as a Mitsuba 3 plugin, `{"type": "gltf_pbr", "params": ...}`.

The twin of core/gltf_brdf.py (the reference written from the glTF specification, issue 24): the
same formulas, the same sections cited there ([B.3.2] ... [COAT], [HEITZ18]), the same alpha floor,
component probabilities and visible-normal sampling, written with drjit operations (numpy and drjit
do not mix inside a Mitsuba variant), so one class works in `scalar_rgb` and in the vectorised
variants. tests/test_mitsuba_gltf_bsdf.py holds the two equal at random directions (eval, pdf and
sample for the same random numbers) and checks the plugin against Mitsuba's own `roughconductor`.
Like core/gltf_brdf.py it never uses glint's own material model (bake/material_mapping.py,
core/bsdf.py).

Conventions. core/gltf_brdf.py's wo (viewer, the spec's V) is Mitsuba's si.wi and its wi (light,
the spec's L) is Mitsuba's wo. Mitsuba's eval() is f |cos theta_L| and sample()'s weight
f |cos theta_L| / pdf; sample1 picks the component (core/gltf_brdf.py's u1), sample2 its direction
(u2, u3). Isotropic: Mitsuba's own shading frame is the local frame (z = the shading normal).
One-sided unless `two_sided` (glTF's doubleSided): then a viewer below the surface sees the
material with the frame flipped (z -> -z), as the spec reverses the normal (3.9.6).
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict

from glint.core import gltf_brdf as ref
from glint.core.gltf_brdf import GltfMaterialParams

# Mitsuba and drjit are optional (glint[bench], and part of glint[test]): imported by the functions that need them.

PLUGIN = "gltf_pbr"
LUMA = (0.2126, 0.7152, 0.0722)  # core/gltf_brdf.py _luminance: picks components only
NORM_MIN = 1e-30                 # float32 stand-in for core/gltf_brdf.py's 1e-300 guards

_registered: set[str] = set()


def params_json(p: GltfMaterialParams) -> str:
    """GltfMaterialParams -> the plugin's `params` property (a JSON string)."""
    return json.dumps(asdict(p))


def register() -> None:
    """Register the plugin with the current Mitsuba variant (once per variant)."""
    import mitsuba as mi

    if mi.variant() in _registered:
        return
    cls = _plugin_class()
    mi.register_bsdf(PLUGIN, lambda props: cls(props))
    _registered.add(mi.variant())


def bsdf_dict(p: GltfMaterialParams, two_sided: bool = False, base_color_texture: dict | None = None) -> dict:
    """The plugin's mi.load_dict entry for a material; `base_color_texture`: a Mitsuba texture dict
    of the base-colour texture's linear values (the factor is the params')."""
    out = {"type": PLUGIN, "params": params_json(p), "two_sided": two_sided}
    if base_color_texture is not None:
        out["base_color_texture"] = base_color_texture
    return out


# -- core/gltf_brdf.py in drjit -----------------------------------------------------------------------
class _Maths:
    """core/gltf_brdf.py's functions for one material, with drjit (closures over the variant)."""

    def __init__(self, p: GltfMaterialParams):
        import mitsuba as mi

        self.p = p
        self.alpha = ref.alpha_of(p.roughness)
        self.coat_alpha = ref.alpha_of(p.clearcoat_roughness)
        self.base = [float(c) for c in p.base_color]
        f0 = [min(ref.ior_f0(p.ior) * float(c), 1.0) * p.specular for c in p.specular_color]  # [SPEC]
        self.f0, self.f90 = f0, float(p.specular)
        self.mi = mi

    # building blocks, as in core/gltf_brdf.py
    @staticmethod
    def normalize(v):
        import drjit as dr

        length = dr.norm(v)
        return v / dr.maximum(length, NORM_MIN), length > 0.0

    def mirror(self, w):
        return self.mi.Vector3f(w.x, w.y, -w.z)

    @staticmethod
    def d_ggx(h, alpha):  # [B.3.2]
        import drjit as dr

        a2 = alpha * alpha
        den = a2 * h.z * h.z + h.x * h.x + h.y * h.y
        return dr.select(h.z > 0.0, a2 / (dr.pi * dr.square(dr.maximum(den, NORM_MIN))), 0.0)

    @staticmethod
    def root(c, alpha):
        import drjit as dr

        a2 = alpha * alpha
        return dr.sqrt(a2 + (1.0 - a2) * c * c)

    def vis_hc(self, nl, nv, hl, hv, alpha):  # [B.3.2] height-correlated
        import drjit as dr

        nl, nv = dr.abs(nl), dr.abs(nv)
        den = 2.0 * (nv * self.root(nl, alpha) + nl * self.root(nv, alpha))
        return dr.select((hl > 0.0) & (hv > 0.0), 1.0 / dr.maximum(den, NORM_MIN), 0.0)

    def vis_sep(self, nl, nv, hl, hv, alpha):  # [TRANS] separable
        import drjit as dr

        visible = (hl * nl > 0.0) & (hv * nv > 0.0)
        nl, nv = dr.abs(nl), dr.abs(nv)
        den = (nl + self.root(nl, alpha)) * (nv + self.root(nv, alpha))
        return dr.select(visible, 1.0 / dr.maximum(den, NORM_MIN), 0.0)

    def g1(self, nv, alpha):  # [HEITZ18]
        import drjit as dr

        nv = dr.maximum(nv, 0.0)
        return 2.0 * nv / dr.maximum(nv + self.root(nv, alpha), NORM_MIN)

    @staticmethod
    def fresnel_w(c):  # [B.3.4]
        import drjit as dr

        return dr.power(1.0 - dr.minimum(dr.abs(c), 1.0), 5)

    def coat_fresnel(self, nv):  # [COAT]
        return ref.COAT_F0 + (1.0 - ref.COAT_F0) * self.fresnel_w(nv)

    def specular_brdf(self, l, v, alpha):
        import drjit as dr

        h, ok = self.normalize(l + v)
        f = self.vis_hc(l.z, v.z, dr.dot(h, l), dr.dot(h, v), alpha) * self.d_ggx(h, alpha)
        return dr.select(ok & (l.z > 0.0) & (v.z > 0.0), f, 0.0), h

    def specular_btdf(self, l, v, alpha):
        import drjit as dr

        h, ok = self.normalize(v + self.mirror(l))
        f = self.vis_sep(l.z, v.z, dr.dot(h, l), dr.dot(h, v), alpha) * self.d_ggx(h, alpha)
        return dr.select(ok & (l.z < 0.0) & (v.z > 0.0), f, 0.0), h

    def base_at(self, texel=None):
        """The base colour (Color3f) and its luminance: the factor, times the base-colour texture's
        linear texel where the material has one ([B.2]: baseColor = factor x texture)."""
        base = self.mi.Color3f(self.base)
        if texel is not None:
            base = base * texel
        return base, LUMA[0] * base[0] + LUMA[1] * base[1] + LUMA[2] * base[2]

    # the BRDF
    def evaluate(self, l, v, texel=None):
        """core/gltf_brdf.py evaluate: f(l, v) without the cosine, Color3f (`texel`: the
        base-colour texture's value at the hit, `base_at`)."""
        import drjit as dr

        mi, p = self.mi, self.p
        spec, h = self.specular_brdf(l, v, self.alpha)
        btdf, h_t = self.specular_btdf(l, v, self.alpha)
        above = l.z > 0.0
        fw = self.fresnel_w(dr.select(above, dr.abs(dr.dot(v, h)), dr.abs(dr.dot(v, h_t))))
        f0 = mi.Color3f(self.f0)
        fres = f0 + (self.f90 - f0) * fw                                                # [SPEC]
        fmax = dr.maximum(dr.maximum(fres[0], fres[1]), fres[2])
        base, _ = self.base_at(texel)
        diffuse = dr.select(above, base * (1.0 / math.pi), mi.Color3f(0.0))             # [B.3.3]
        base_layer = (1.0 - p.transmission) * diffuse + p.transmission * (btdf * base)  # [TRANS]
        dielectric = fres * spec + (1.0 - fmax) * base_layer
        metal = (base + (1.0 - base) * fw) * spec                                       # [B.3.4]
        material = (1.0 - p.metallic) * dielectric + p.metallic * metal                 # [B.2]
        if p.clearcoat > 0.0:                                                           # [COAT]
            coat, _ = self.specular_brdf(l, v, self.coat_alpha)
            w = p.clearcoat * self.coat_fresnel(v.z)
            material = (1.0 - w) * material + w * coat
        return dr.select(v.z > 0.0, material, mi.Color3f(0.0))

    def probabilities(self, nv, texel=None):
        """core/gltf_brdf.py component_probabilities: [diffuse, specular, transmission, clearcoat]."""
        import drjit as dr

        p = self.p
        _, base_luma = self.base_at(texel)
        nv = dr.clip(nv, 0.0, 1.0)
        fw = self.fresnel_w(nv)
        f0max = max(self.f0)
        f_diel = f0max + (self.f90 - f0max) * fw
        f_metal = base_luma + (1.0 - base_luma) * fw
        under = 1.0 - p.clearcoat * self.coat_fresnel(nv)
        w = [(1 - p.metallic) * (1 - p.transmission) * base_luma * (1.0 - f_diel) * under,
             ((1 - p.metallic) * f_diel + p.metallic * f_metal) * under,
             (1 - p.metallic) * p.transmission * base_luma * (1.0 - f_diel) * under,
             p.clearcoat * self.coat_fresnel(nv)]
        total = w[0] + w[1] + w[2] + w[3]
        ok = total > 0.0
        inv = 1.0 / dr.select(ok, total, 1.0)
        return [dr.select(ok, w[0] * inv, 1.0)] + [dr.select(ok, x * inv, 0.0) for x in w[1:]]

    def vndf_reflect_pdf(self, l, v, alpha):
        import drjit as dr

        h, ok = self.normalize(l + v)
        pdf = self.g1(v.z, alpha) * self.d_ggx(h, alpha) / (4.0 * dr.maximum(v.z, NORM_MIN))
        return dr.select(ok & (l.z > 0.0) & (v.z > 0.0) & (dr.dot(v, h) > 0.0), pdf, 0.0)

    def pdf(self, l, v, texel=None):
        """core/gltf_brdf.py pdf: the mixture's density."""
        import drjit as dr

        prob = self.probabilities(v.z, texel)
        out = prob[0] * dr.select((l.z > 0.0) & (v.z > 0.0), l.z * (1.0 / math.pi), 0.0)
        out = out + prob[1] * self.vndf_reflect_pdf(l, v, self.alpha)
        if self.p.transmission > 0.0:
            out = out + prob[2] * dr.select(l.z < 0.0, self.vndf_reflect_pdf(self.mirror(l), v, self.alpha), 0.0)
        if self.p.clearcoat > 0.0:
            out = out + prob[3] * self.vndf_reflect_pdf(l, v, self.coat_alpha)
        return dr.select(v.z > 0.0, out, 0.0)

    def visible_normal(self, v, alpha, u1, u2):
        """[HEITZ18] listing 1, as core/gltf_brdf.py sample_visible_normal."""
        import drjit as dr

        mi = self.mi
        vh, _ = self.normalize(mi.Vector3f(alpha * v.x, alpha * v.y, v.z))
        lensq = vh.x * vh.x + vh.y * vh.y
        inv = dr.rsqrt(dr.select(lensq > 0.0, lensq, 1.0))
        t1 = dr.select(lensq > 0.0, mi.Vector3f(-vh.y * inv, vh.x * inv, 0.0), mi.Vector3f(1.0, 0.0, 0.0))
        t2 = dr.cross(vh, t1)
        r = dr.sqrt(u1)
        s_phi, c_phi = dr.sincos(2.0 * dr.pi * u2)
        p1, p2 = r * c_phi, r * s_phi
        s = 0.5 * (1.0 + vh.z)
        p2 = (1.0 - s) * dr.sqrt(dr.maximum(1.0 - p1 * p1, 0.0)) + s * p2
        nh = p1 * t1 + p2 * t2 + dr.sqrt(dr.maximum(1.0 - p1 * p1 - p2 * p2, 0.0)) * vh
        return self.normalize(mi.Vector3f(alpha * nh.x, alpha * nh.y, dr.maximum(nh.z, 0.0)))[0]


def _plugin_class():
    import drjit as dr
    import mitsuba as mi

    Flags = mi.BSDFFlags

    class GltfPbrBSDF(mi.BSDF):
        """Properties: `params` (JSON of core/gltf_brdf.py GltfMaterialParams; bad values raise
        glint's one-line GlintError), `two_sided` (bool, glTF's doubleSided), optionally
        `base_color_texture` (a texture of linear values: baseColor = factor x texture, [B.2])."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.params = GltfMaterialParams(**json.loads(props.get("params", "{}")))
            self.m = _Maths(self.params)
            self.two_sided = bool(props.get("two_sided", False))
            self.base_texture = props.get_texture("base_color_texture") if "base_color_texture" in props else None
            sides = Flags.FrontSide | (Flags.BackSide if self.two_sided else Flags(0))
            self.m_components = [Flags.DiffuseReflection | sides, Flags.GlossyReflection | sides,
                                 Flags.GlossyTransmission | sides, Flags.GlossyReflection | sides]
            flags = Flags(0)
            for c in self.m_components:
                flags = flags | c
            self.m_flags = flags

        def _local(self, si, w):
            """The material's frame: z flipped when a two-sided material is seen from below."""
            if not self.two_sided:
                return w
            return mi.Vector3f(w.x, w.y, dr.select(si.wi.z < 0.0, -w.z, w.z))

        def _texel(self, si, active):
            return None if self.base_texture is None else self.base_texture.eval(si, active)

        def eval_pdf(self, ctx, si, wo, active=True):
            v, l = self._local(si, si.wi), self._local(si, wo)
            texel = self._texel(si, active)
            f = self.m.evaluate(l, v, texel)
            pdf = self.m.pdf(l, v, texel)
            return (dr.select(active, f * dr.abs(l.z), mi.Color3f(0.0)), dr.select(active, pdf, 0.0))

        def eval(self, ctx, si, wo, active=True):
            return self.eval_pdf(ctx, si, wo, active)[0]

        def pdf(self, ctx, si, wo, active=True):
            return self.eval_pdf(ctx, si, wo, active)[1]

        def sample(self, ctx, si, sample1, sample2, active=True):
            m = self.m
            sample1 = mi.Float(sample1)  # a numpy scalar from a caller would make numpy bools below
            v = self._local(si, si.wi)
            texel = self._texel(si, active)
            prob = m.probabilities(v.z, texel)
            # cosine-weighted, polar mapping as core/gltf_brdf.py (not Mitsuba's concentric one), so the
            # two map the same random numbers to the same directions (the twin test compares them)
            r = dr.sqrt(sample2.x)
            s_phi, c_phi = dr.sincos(2.0 * dr.pi * sample2.y)
            cosine = mi.Vector3f(r * c_phi, r * s_phi, dr.sqrt(dr.maximum(1.0 - sample2.x, 0.0)))
            h = m.visible_normal(v, m.alpha, sample2.x, sample2.y)
            reflected = 2.0 * dr.dot(v, h) * h - v
            h = m.visible_normal(v, m.coat_alpha, sample2.x, sample2.y)
            coat = 2.0 * dr.dot(v, h) * h - v
            c1 = prob[0]
            c2 = c1 + prob[1]
            c3 = c2 + prob[2]
            l = dr.select(sample1 < c1, cosine,
                          dr.select(sample1 < c2, reflected, dr.select(sample1 < c3, m.mirror(reflected), coat)))
            transmit = (sample1 >= c2) & (sample1 < c3)
            l = m.normalize(l)[0]
            side = dr.select(transmit, l.z < 0.0, l.z > 0.0)  # as core/gltf_brdf.py: wrong side dropped
            f = m.evaluate(l, v, texel)
            pdf = m.pdf(l, v, texel)
            ok = active & side & (pdf > 0.0) & (v.z > 0.0)
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = self._local(si, l)  # the flip is its own inverse
            bs.pdf = dr.select(ok, pdf, 0.0)
            bs.eta = 1.0
            bs.sampled_component = dr.select(sample1 < c1, mi.UInt32(0), dr.select(
                sample1 < c2, mi.UInt32(1), dr.select(sample1 < c3, mi.UInt32(2), mi.UInt32(3))))
            bs.sampled_type = dr.select(sample1 < c1, mi.UInt32(+Flags.DiffuseReflection), dr.select(
                transmit, mi.UInt32(+Flags.GlossyTransmission), mi.UInt32(+Flags.GlossyReflection)))
            weight = f * dr.abs(l.z) / dr.maximum(pdf, NORM_MIN)
            return bs, dr.select(ok, weight, mi.Color3f(0.0))

        def to_string(self):
            return f"GltfPbrBSDF[{params_json(self.params)}, two_sided={self.two_sided}]"

    return GltfPbrBSDF
