"""The section 3.3 BSDF (Eq. 3.2-3.6) as a Mitsuba 3 plugin, `{"type": "glint", ...}`.

No Mitsuba plugin equals the thesis' model (kd/pi plus Kurt et al.'s anisotropic Beckmann
lobes with Schlick's Fresnel and the ((wi.n)(wo.n))^alpha factor, plus thin-surface
transmission lobes), so an end-to-end comparison with Mitsuba needs it as a plugin. The maths
is core/bsdf.py's, line by line, with the same numerical guards (its module docstring names
them), written with drjit operations only, so one class works in `scalar_rgb` and in the
vectorised `llvm_ad_rgb` / `cuda_ad_rgb` variants (no Python branching on values).

Conventions. core/bsdf.py calls the direction to the viewer wo and the one to the light wi;
Mitsuba calls them si.wi and wo. Below, names follow core/bsdf.py (`v` = viewer = si.wi,
`l` = light = Mitsuba's wo). Mitsuba's eval() is f_s |cos(theta_l)| and sample()'s weight
f_s |cos(theta_l)| / pdf (the path integrator's convention).

Frame and sides, as the viewer shades (shaders/raster_surface.glsl, specular.glsl):
- n is the shading normal (interpolated vertex normals); anisotropic lobes need the tangent,
  which the converter (bench/mitsuba_scene.py) stores per vertex as the mesh attributes
  `vertex_tangent` and `vertex_bitangent_sign`, computed by viewer/tangent_frames.py's `tangents` /
  `axis_tangents`: t = tangent Gram-Schmidt against n, b = sign n x t. Isotropic materials
  use Mitsuba's own shading frame (the BSDF is invariant under a rotation about n).
- The side is the geometric one (winding, as gl_FrontFacing). The back of a one-sided
  material is black, like the viewer's `dark` pixels and Mitsuba's own BSDFs; a double-sided
  or transmissive material (the viewer's MAT_TWO_SIDED) flips n there (z -> -z in the frame).

Sampling: one component chosen with probability proportional to its weight -- luminance of
kd (times the texture) for the diffuse part, of ks for each lobe -- then kd by cosine sampling
and a lobe by its half vector (Eq. 4.5-4.8, mirrored for transmission). The pdf is the mixture
sum_c P(c) pdf_c (the balance heuristic over components: one-sample MIS), pdf_c of a lobe
being Eq. 4.9. A lobe sample whose half vector faces away from the viewer (wo.h <= 0) is
dropped (weight 0): its direction's density is not in Eq. 4.9, so evaluating it with the
mixture would bias the estimate.
"""
from __future__ import annotations

import json
import math

from glint.bake.lights import LUMA as _LUMA
from glint.core import bsdf as ref

# Mitsuba and drjit are optional (glint[bench], and part of glint[test]): imported by the functions that need them, so the rest works without.

LUMA = [float(x) for x in _LUMA]  # Python floats: numpy scalars would leak into drjit's scalar variant

PLUGIN = "glint"
INV_PI = 1.0 / math.pi
TANGENT = "vertex_tangent"              # mesh attribute: unit tangent (3 floats per vertex)
BITANGENT_SIGN = "vertex_bitangent_sign"  # mesh attribute: +-1 (1 float per vertex)

_registered: set[str] = set()


def lobes_json(lobes) -> str:
    """glint.core.scene.Lobe list -> the plugin's `lobes` property (a JSON string)."""
    return json.dumps([lobe.to_dict() for lobe in lobes])


def register() -> None:
    """Register the plugin with the current Mitsuba variant (once per variant)."""
    import mitsuba as mi

    if mi.variant() in _registered:
        return
    cls = _plugin_class()  # made once, in the thread that set the variant
    mi.register_bsdf(PLUGIN, lambda props: cls(props))
    _registered.add(mi.variant())


# -- core/bsdf.py in drjit ---------------------------------------------------------------------------
def _maths():
    """The numpy reference's functions written with drjit (closures over the current variant)."""
    import drjit as dr
    import mitsuba as mi

    def schlick_F(cos_theta, r0):  # Eq. 2.9
        u = dr.clip(cos_theta, 0.0, 1.0)
        return r0 + (1.0 - r0) * dr.power(1.0 - u, 5)

    def beckmann_D(h, mx, my):  # Eq. 3.3; mx, my already >= M_MIN
        c = dr.maximum(h.z, ref.HZ_MIN)
        exponent = (h.x * h.x / (mx * mx) + h.y * h.y / (my * my)) / (c * c)
        D = dr.exp(-exponent) / (dr.pi * mx * my * dr.square(dr.square(c)))
        return dr.select(h.z > 0.0, D, 0.0)

    def half_vector(l, v):
        s = l + v
        length = dr.norm(s)
        return s / dr.maximum(length, ref.HALF_MIN), length > ref.HALF_MIN

    def shadowing(ci, co, alpha):  # ((wi.n)(wo.n))^alpha, floored (COS_MIN)
        return dr.power(dr.maximum(ci, ref.COS_MIN) * dr.maximum(co, ref.COS_MIN), alpha)

    def mirror(w):
        return mi.Vector3f(w.x, w.y, -w.z)

    def lobe_value(l, v, lobe):  # Eq. 3.4 / 3.5 without ks
        lr = mirror(l) if lobe.transmit else l
        h, ok = half_vector(lr, v)
        ci, co = lr.z, v.z
        oh = dr.dot(v, h)
        F = schlick_F(oh, lobe.r0)
        if lobe.transmit:
            F = 1.0 - F
        f = F * beckmann_D(h, lobe.mx, lobe.my) / (4.0 * dr.maximum(oh, ref.DOT_MIN) * shadowing(ci, co, lobe.alpha))
        return dr.select(ok & (ci >= 0.0) & (co >= 0.0) & (oh > 0.0), f, 0.0)

    def lobe_pdf(l, v, lobe):  # Eq. 4.9
        lr = mirror(l) if lobe.transmit else l
        h, ok = half_vector(lr, v)
        oh = dr.dot(v, h)
        p = beckmann_D(h, lobe.mx, lobe.my) * h.z / (4.0 * dr.maximum(oh, ref.DOT_MIN))
        return dr.select(ok & (oh > 0.0) & (h.z > 0.0), p, 0.0)

    def sample_half_vector(xi1, xi2, mx, my):  # Eq. 4.5-4.7, quadrant-correct as core/bsdf.py
        xi1 = dr.clip(xi1, ref.XI_MIN, 1.0)
        a = 2.0 * dr.pi * xi2
        phi = dr.atan2(my * dr.sin(a), mx * dr.cos(a))
        phi = dr.select(phi < 0.0, phi + 2.0 * dr.pi, phi)
        sp, cp = dr.sincos(phi)
        A = cp * cp / (mx * mx) + sp * sp / (my * my)
        theta = dr.atan(dr.sqrt(dr.maximum(-dr.log(xi1), 0.0) / A))
        st, ct = dr.sincos(theta)
        return mi.Vector3f(st * cp, st * sp, ct)

    return schlick_F, beckmann_D, lobe_value, lobe_pdf, sample_half_vector, mirror


class _Lobe:
    """One lobe's constants, roughness clamped as core/bsdf.py `clamp_roughness` does."""

    def __init__(self, d: dict):
        self.transmit = d["kind"] == "transmit"
        self.ks = [max(float(c), 0.0) for c in d["ks"]]
        self.mx = max(float(d["mx"]), ref.M_MIN)
        self.my = max(float(d["my"]), ref.M_MIN)
        self.r0 = float(d["r0"])
        self.alpha = float(d["alpha"])
        self.luminance = sum(w * c for w, c in zip(LUMA, self.ks))
        self.mr = d.get("mr", "")

    def at_texel(self, mr):
        """This lobe at a metallic-roughness texel `mr` (Color3f: g in y, M' in z), as the viewer's
        lobe_at_pixel (shaders/specular.glsl) and bake/material_mapping.py define it."""
        import drjit as dr
        import mitsuba as mi

        if not self.mr:
            return self
        out = _Lobe.__new__(_Lobe)
        out.transmit, out.r0, out.alpha, out.mr = self.transmit, self.r0, self.alpha, self.mr
        a2 = min(max((self.mx - self.my) / (1.0 - self.my), 0.0), 1.0) if self.my < 1.0 else 0.0
        m = dr.maximum(self.my * mr.y * mr.y, ref.M_MIN)
        out.mx, out.my = m + (1.0 - m) * a2, m
        scale = mr.z if self.mr == "metal" else 1.0 - mr.z
        out.ks = mi.Color3f(self.ks) * scale
        out.luminance = sum(w * c for w, c in zip(LUMA, self.ks)) * scale
        return out


def _plugin_class():
    import drjit as dr
    import mitsuba as mi

    _, _, lobe_value, lobe_pdf, sample_half_vector, _ = _maths()
    Flags = mi.BSDFFlags

    class GlintBSDF(mi.BSDF):
        """Properties: `kd` (texture, linear RGB; a bitmap already multiplied by kd), `lobes` (JSON
        list of glint.core.scene.Lobe dicts), `two_sided` (bool), optional `mr` (the material's
        metallic-roughness texture: G roughness multiplier, B metallic M'; it scales kd by 1 - M'
        and changes the lobes marked `mr`)."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.kd = props.get_texture("kd", 0.0)
            self.mr = props.get_texture("mr") if "mr" in props else None
            self.lobes = [_Lobe(d) for d in json.loads(props.get("lobes", "[]"))]
            self.lobes = [lobe for lobe in self.lobes if lobe.luminance > 0.0]
            transmit = any(lobe.transmit for lobe in self.lobes)
            self.two_sided = bool(props.get("two_sided", False)) or transmit
            self.anisotropic = any(lobe.mx != lobe.my for lobe in self.lobes)
            sides = Flags.FrontSide | (Flags.BackSide if self.two_sided else Flags(0))
            self.m_components = [Flags.DiffuseReflection | sides] + [
                (Flags.GlossyTransmission if lobe.transmit else Flags.GlossyReflection) | sides
                for lobe in self.lobes]
            flags = Flags(0)
            for c in self.m_components:
                flags = flags | c
            self.m_flags = flags

        # -- frames --------------------------------------------------------------------------------
        def _frame(self, si, active):
            """(frame, back): the viewer's shading frame (see the module docstring) and whether the
            viewer looks at the geometric back face."""
            back = dr.dot(si.n, si.to_world(si.wi)) < 0.0
            if not self.anisotropic:
                return None, back
            n = si.sh_frame.n
            T = mi.Vector3f(si.shape.eval_attribute_3(TANGENT, si, active))
            sign = si.shape.eval_attribute_1(BITANGENT_SIGN, si, active)
            t = T - n * dr.dot(n, T)
            length = dr.norm(t)
            t = dr.select(length > 1e-12, t / dr.maximum(length, 1e-12), si.sh_frame.s)
            b = dr.select(sign < 0.0, -1.0, 1.0) * dr.cross(n, t)
            return mi.Frame3f(t, b, n), back

        def _to_glint(self, si, frame, back, w):
            """Mitsuba's local direction -> the viewer's frame (z flipped on a two-sided back)."""
            if frame is not None:
                w = frame.to_local(si.to_world(w))
            return mi.Vector3f(w.x, w.y, dr.select(back, -w.z, w.z))

        def _to_mitsuba(self, si, frame, back, w):
            w = mi.Vector3f(w.x, w.y, dr.select(back, -w.z, w.z))
            return si.to_local(frame.to_world(w)) if frame is not None else w

        def _setup(self, si, active):
            frame, back = self._frame(si, active)
            if not self.two_sided:  # (no `~back`: a Python bool's ~ is an int in scalar variants)
                active = active & (dr.dot(si.n, si.to_world(si.wi)) >= 0.0)
            v = self._to_glint(si, frame, back, si.wi)
            active = active & (v.z >= 0.0)  # core/bsdf.py: zero for a viewer below the shading horizon
            kd = dr.clip(self.kd.eval(si, active), 0.0, 1.0)
            lobes = self.lobes
            if self.mr is not None:
                mr = dr.clip(self.mr.eval(si, active), 0.0, 1.0)
                kd = kd * (1.0 - mr.z)
                lobes = [lobe.at_texel(mr) for lobe in self.lobes]
            return frame, back, v, kd, lobes, active

        def _weights(self, kd, lobes):
            """Component probabilities: luminance of kd and of each lobe's ks, normalised."""
            w = [LUMA[0] * kd.x + LUMA[1] * kd.y + LUMA[2] * kd.z] + [mi.Float(lobe.luminance) for lobe in lobes]
            total = w[0]
            for x in w[1:]:
                total = total + x
            inv = dr.select(total > 0.0, 1.0 / dr.maximum(total, 1e-30), 0.0)
            return [x * inv for x in w]

        def _eval_pdf(self, v, l, kd, lobes, weights):
            """(f_s (Eq. 3.6), mixture pdf) for viewer v, light l in the viewer's frame."""
            same = (l.z >= 0.0) & (v.z >= 0.0)
            f = dr.select(same, kd * INV_PI, 0.0)
            pdf = weights[0] * dr.select(same, dr.maximum(l.z, 0.0) * INV_PI, 0.0)
            for lobe, w in zip(lobes, weights[1:]):
                f = f + mi.Color3f(lobe.ks) * lobe_value(l, v, lobe)
                pdf = pdf + w * lobe_pdf(l, v, lobe)
            return f, pdf

        # -- the BSDF interface ---------------------------------------------------------------------
        def eval_pdf(self, ctx, si, wo, active=True):
            frame, back, v, kd, lobes, active = self._setup(si, active)
            l = self._to_glint(si, frame, back, wo)
            f, pdf = self._eval_pdf(v, l, kd, lobes, self._weights(kd, lobes))
            return dr.select(active, f * dr.abs(l.z), 0.0), dr.select(active, pdf, 0.0)

        def eval(self, ctx, si, wo, active=True):
            return self.eval_pdf(ctx, si, wo, active)[0]

        def pdf(self, ctx, si, wo, active=True):
            return self.eval_pdf(ctx, si, wo, active)[1]

        def sample(self, ctx, si, sample1, sample2, active=True):
            frame, back, v, kd, lobes, active = self._setup(si, active)
            weights = self._weights(kd, lobes)
            # Component by sample1 against the running sum of the weights.
            l = mi.warp.square_to_cosine_hemisphere(sample2)
            valid = mi.Bool(True)
            component = mi.UInt32(0)
            flags = mi.UInt32(+Flags.DiffuseReflection)
            cdf = weights[0]
            for i, (lobe, w) in enumerate(zip(lobes, weights[1:])):
                h = sample_half_vector(sample2.x, sample2.y, lobe.mx, lobe.my)
                oh = dr.dot(v, h)
                d = 2.0 * oh * h - v  # Eq. 4.8
                if lobe.transmit:
                    d = mi.Vector3f(d.x, d.y, -d.z)
                pick = sample1 >= cdf
                l = dr.select(pick, d, l)
                valid = dr.select(pick, oh > 0.0, valid)
                component = dr.select(pick, mi.UInt32(i + 1), component)
                kind = Flags.GlossyTransmission if lobe.transmit else Flags.GlossyReflection
                flags = dr.select(pick, mi.UInt32(+kind), flags)
                cdf = cdf + w
            f, pdf = self._eval_pdf(v, l, kd, lobes, weights)
            ok = active & valid & (pdf > 0.0)
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = self._to_mitsuba(si, frame, back, l)
            bs.pdf = dr.select(ok, pdf, 0.0)
            bs.eta = 1.0
            bs.sampled_component = component
            bs.sampled_type = flags
            weight = f * dr.abs(l.z) / dr.maximum(pdf, 1e-30)
            return bs, dr.select(ok, weight, 0.0)

        def to_string(self):
            return f"GlintBSDF[lobes={len(self.lobes)}, two_sided={self.two_sided}]"

    return GlintBSDF
