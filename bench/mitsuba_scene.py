"""A glint Scene (core/scene.py, as bake/gltf_loader.py loads it with its sidecar) as a Mitsuba 3 scene.

The same scene for an independent path tracer: the end-to-end comparison of `glint bench
--mitsuba` (bench/mitsuba.py) renders it with Mitsuba and holds the viewer's images
against it. What maps to what:

- Objects: one `mi.Mesh` each, built from the loader's world-space arrays: positions,
  counter-clockwise faces (Mitsuba's front side too), the vertex normals (Mitsuba's shading
  frame, as the viewer interpolates them) and TEXCOORD_0 as Mitsuba's uv. Per-vertex tangents
  for anisotropic lobes (mesh attributes read by bench/mitsuba_bsdf.py), from the viewer's own
  function (viewer/tangent_frames.py `surface_tangents`: TANGENT, MikkTSpace, or a world axis; its
  vertex splits are the mesh's).
- Normal maps: Mitsuba's `normalmap` BSDF around the material's, with the map as a linear
  `bitmap` (glTF's scale applied to x and y, renormalised and re-encoded as 0..1). Mitsuba
  reads the map in its shading frame (s = dp/du made orthogonal to the interpolated normal,
  t = n x s), which is the viewer's (t, b = w n x t) wherever the uv layout is not mirrored
  (w = +1); on mirrored uv islands its y runs the other way. Anisotropy rotation and textures
  are not converted.
- Materials: bench/mitsuba_bsdf.py's plugin (the section 3.3 BSDF) with kd, the lobes and the
  side rule. A base-colour texture becomes a `bitmap` of kd x texture, linear (`raw`: the loader
  already decoded sRGB), bilinear and repeating like the viewer's sampler; glTF's uv (0, 0) is
  the first row of the image, which is also Mitsuba's bitmap convention (checked by a test).
  kd is clamped to [0, 1] as bake/irradiance.py and the viewer do.
  A metallic-roughness texture becomes the plugin's `mr` bitmap (linear, repeating, nearest with
  the base colour's magFilter NEAREST, else bilinear): per shading point kd x (1 - M') and the
  `mr` lobes' texel width and weight (bench/mitsuba_bsdf.py `_Lobe.at_texel`).
- Glass solids (Material.has_volume: KHR_materials_volume, core/volume.py): Mitsuba's own
  two-interface `dielectric` (int_ior = the ior, ext_ior 1, specular_transmittance = the transmit
  lobe's ks), `roughdielectric` (Beckmann, alpha_u = mx, alpha_v = my) where the lobe is wider
  than ROUGH_GLASS_M; absorption (attenuationColor / Distance) as a `homogeneous` interior medium
  of sigma_t = sigma_a and albedo 0, with the `volpath` integrator. So the comparison's glass is
  a true solid with refraction, not glint's model of it.
- Emissive materials: an `area` emitter of radiance = Material.emission (W/(m^2 sr), the
  loader's emissiveFactor x strength, as the bake reads it) on each such object; Mitsuba's
  area lights emit from the front, as the bake's one-sided emitters. A double-sided emitter
  would emit from both sides in the bake: Mitsuba has no such emitter, so it emits from the
  front only here and `convert` says so in its warnings.
- Punctual lights: the loader has already converted KHR_lights_punctual to radiometric units
  (photometric / 683 by default, bake/sidecar.py `[lights] units`): point -> `point` (W/sr),
  directional -> `directional` (W/m^2), spot -> the `glint_spot` emitter below, which has the
  glTF cone falloff squared of bake/lights.py `DeltaLights` (Mitsuba's `spot` falls off
  linearly in angle instead).
- Sky: constant -> `constant`; map -> `envmap` of map x radiance with
  to_world = rotate(+Y, 90 deg), the mapping bake/lights.py derives.
- Cameras: `perspective` from eye / forward / up with the vertical field of view
  (`fov_axis` "y", as viewer/camera.py), box pixel filter (the pixel's area, as the viewer's
  supersampling), linear RGB `hdrfilm`.
- Integrator: `path` with unlimited depth (`volpath` where glass absorbs).
"""
from __future__ import annotations

import math

import numpy as np

from glint.bench import mitsuba_bsdf, mitsuba_gltf_bsdf
from glint.core.scene import Scene
from glint.viewer.tangent_frames import surface_tangents

# Mitsuba and drjit are optional (glint[bench], and part of glint[test]): imported by the functions that need them, so the rest works without.

SPOT_PLUGIN = "glint_spot"
ROUGH_GLASS_M = 1e-3  # Beckmann m below which glass is Mitsuba's smooth `dielectric`
_spot_registered: set[str] = set()


def register() -> None:
    """Register glint's plugins (BSDF, spot light) with the current Mitsuba variant."""
    import mitsuba as mi

    mitsuba_bsdf.register()
    if mi.variant() not in _spot_registered:
        cls = _spot_class()  # made once, in the thread that set the variant
        mi.register_emitter(SPOT_PLUGIN, lambda props: cls(props))
        _spot_registered.add(mi.variant())


def _rgb(value) -> dict:
    return {"type": "rgb", "value": [float(x) for x in np.asarray(value, np.float64).reshape(3)]}


def _vector(v) -> list[float]:
    return [float(x) for x in np.asarray(v, np.float64).reshape(3)]


def glass_dict(material) -> dict:
    """A glass solid as Mitsuba's dielectric or roughdielectric (module docstring)."""
    lobe = material.transmit_lobes[0]
    out = {"type": "dielectric", "int_ior": float(material.ior), "ext_ior": 1.0,
           "specular_transmittance": _rgb(np.clip(lobe.ks, 0.0, 1.0))}
    if max(lobe.mx, lobe.my) > ROUGH_GLASS_M:
        out.update(type="roughdielectric", distribution="beckmann", alpha_u=float(lobe.mx), alpha_v=float(lobe.my))
    return out


def bsdf_dict(material) -> dict:
    if material.has_volume:
        return glass_dict(material)
    kd = np.clip(np.nan_to_num(np.asarray(material.kd, np.float64).reshape(3)), 0.0, 1.0)
    if material.kd_texture is not None:
        import mitsuba as mi

        texture = np.clip(np.nan_to_num(np.asarray(material.kd_texture, np.float32)[..., :3]), 0.0, 1.0)
        kd_texture = {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(texture * kd.astype(np.float32))),
                      "raw": True, "filter_type": "bilinear", "wrap_mode": "repeat"}
    else:
        kd_texture = _rgb(kd)
    bsdf = {"type": mitsuba_bsdf.PLUGIN, "kd": kd_texture, "lobes": mitsuba_bsdf.lobes_json(material.lobes),
            "two_sided": bool(material.double_sided)}
    if material.metallic_roughness_texture is not None:
        bsdf["mr"] = _bitmap(material.metallic_roughness_texture, material)
    if material.normal_texture is None:
        return bsdf
    return {"type": "normalmap", "bsdf": bsdf,
            "normalmap": _bitmap(normal_map_encoding(material.normal_texture, material.normal_scale), material)}


def normal_map_encoding(texture, scale: float) -> np.ndarray:
    """A glTF normal map with its scale applied (x, y times scale, renormalised: what the viewer's
    normalize(t x + b y + n z) does) and encoded again as 0..1, float32 (H, W, 3)."""
    n = np.nan_to_num(np.asarray(texture, np.float64)[..., :3]) * 2.0 - 1.0
    n[..., :2] *= scale
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    return np.ascontiguousarray((n * 0.5 + 0.5).astype(np.float32))


def _bitmap(texture, material) -> dict:
    """A material texture as a linear `bitmap` read as the viewer does: bilinear (or nearest with
    the base colour's magFilter NEAREST), repeating."""
    import mitsuba as mi

    image = np.clip(np.nan_to_num(np.asarray(texture, np.float32)[..., :3]), 0.0, 1.0)
    return {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(image)), "raw": True,
            "filter_type": "nearest" if material.kd_nearest else "bilinear", "wrap_mode": "repeat"}


def mesh(obj, bsdf, emitter=None, interior=None):
    """One object as an `mi.Mesh` with its BSDF (and area emitter, interior medium), world space."""
    import mitsuba as mi

    has_uv = obj.uvs is not None
    uvs = np.asarray(obj.uvs, np.float32).reshape(-1, 2) if has_uv else None
    source, faces, frame = surface_tangents(obj.positions, obj.normals, uvs, obj.indices, obj.tangents)
    positions = np.asarray(obj.positions, np.float64).reshape(-1, 3)[source]
    normals = np.asarray(obj.normals, np.float32).reshape(-1, 3)[source]
    props = mi.Properties()
    props["bsdf"] = bsdf
    if emitter is not None:
        props["emitter"] = emitter
    if interior is not None:
        props["interior"] = interior
    m = mi.Mesh(obj.name or "object", len(positions), len(faces), props=props, has_vertex_normals=True,
                has_vertex_texcoords=has_uv)
    params = mi.traverse(m)

    def put(key, array):  # each variant's own buffer type (a drjit array; scalar_rgb's is dynamic too)
        params[key] = type(params[key])(np.ascontiguousarray(array).ravel())

    put("vertex_positions", positions.astype(np.float32))
    put("faces", faces.astype(np.uint32))
    put("vertex_normals", normals)
    if has_uv:
        put("vertex_texcoords", uvs[source])
    params.update()
    m.add_attribute(mitsuba_bsdf.TANGENT, 3, type(params["vertex_normals"])(frame[:, :3].ravel()))
    m.add_attribute(mitsuba_bsdf.BITANGENT_SIGN, 1, type(params["vertex_normals"])(frame[:, 3].copy()))
    return m


def sky_dict(sky) -> dict | None:
    if sky is None:
        return None
    radiance = np.asarray(sky.radiance, np.float64).reshape(3)
    if sky.map is None:
        return {"type": "constant", "radiance": _rgb(radiance)} if np.any(radiance > 0) else None
    import mitsuba as mi

    image = np.nan_to_num(np.maximum(np.asarray(sky.map, np.float32)[..., :3], 0.0), nan=0.0, posinf=0.0)
    return {"type": "envmap", "bitmap": mi.Bitmap(np.ascontiguousarray(image * radiance.astype(np.float32))),
            "to_world": mi.ScalarTransform4f().rotate([0.0, 1.0, 0.0], 90.0)}


def sensor_dict(camera, width: int, height: int, spp: int = 16, seed: int = 0) -> dict:
    """A viewer camera (viewer/camera.py ViewCamera, or glint.core.scene.Camera) as a `perspective` sensor."""
    import mitsuba as mi

    eye = np.asarray(camera.eye, np.float64)
    return {"type": "perspective", "fov_axis": "y", "fov": math.degrees(camera.yfov),
            "near_clip": float(camera.znear), "far_clip": float(camera.zfar),
            "to_world": mi.ScalarTransform4f().look_at(origin=_vector(eye), target=_vector(eye + camera.forward),
                                                       up=_vector(camera.up)),
            "film": {"type": "hdrfilm", "width": int(width), "height": int(height), "pixel_format": "rgb",
                     "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": int(spp), "seed": int(seed)}}


def gltf_reference(material) -> dict | None:
    """The glTF specification's BRDF (bench/mitsuba_gltf_bsdf.py; `register()` it first) for a material
    the loader mapped from glTF factors and nothing changed (`Material.gltf`), with at most a
    base-colour texture (the plugin's `base_color_texture`; it reads no other texture):
    the material as its author defined it, not glint's lobes. None for any other."""
    textured = any(t is not None for t in (material.metallic_roughness_texture,
                                           material.normal_texture, material.alpha_texture,
                                           material.emission_texture, material.anisotropy_texture))
    if material.gltf is None or textured or material.alpha_mode != "OPAQUE":
        return None
    base = None if material.kd_texture is None else _bitmap(material.kd_texture, material)
    return mitsuba_gltf_bsdf.bsdf_dict(material.gltf, two_sided=bool(material.double_sided), base_color_texture=base)


def convert(scene: Scene, sensors: list[dict] = (), gltf: bool = False) -> tuple[dict, list[str]]:
    """(Mitsuba scene dict, warnings) of a glint Scene; load it with mi.load_dict after `register()`.
    `gltf`: materials from glTF factors are rendered by the specification's BRDF (`gltf_reference`),
    the others by glint's own BSDF (bench/mitsuba_bsdf.py), each listed in the warnings."""
    import mitsuba as mi

    register()
    warnings = []
    out = {"type": "scene", "integrator": {"type": "path", "max_depth": -1}}
    references = [gltf_reference(m) if gltf else None for m in scene.materials]
    if gltf:
        mitsuba_gltf_bsdf.register()
        warnings += [f"material '{m.name}': glint's BSDF (no glTF factors with at most a base-colour texture to render)"
                     for m, r in zip(scene.materials, references) if r is None]
    bsdfs = [mi.load_dict(r if r is not None else bsdf_dict(m)) for m, r in zip(scene.materials, references)]
    media = [mi.load_dict({"type": "homogeneous", "sigma_t": _rgb(m.absorption), "albedo": 0.0})
             if m.has_volume and np.any(m.absorption > 0) else None for m in scene.materials]
    if any(medium is not None for medium in media):
        out["integrator"] = {"type": "volpath", "max_depth": -1}
    for i, obj in enumerate(scene.objects):
        if not len(obj.indices):
            continue
        material = scene.material_of(obj)
        emitter = None
        if material.is_emissive:
            emission = np.maximum(np.nan_to_num(np.asarray(material.emission, np.float64), nan=0.0, posinf=0.0), 0.0)
            emitter = mi.load_dict({"type": "area", "radiance": _rgb(emission)})
            if material.double_sided:
                warnings.append(f"'{obj.name}': double-sided emitter emits from its front side only in Mitsuba")
        out[f"object_{i:04d}"] = mesh(obj, bsdfs[obj.material], emitter, media[obj.material])
    for i, light in enumerate(scene.point_lights):
        out[f"point_{i}"] = {"type": "point", "position": _vector(light.position), "intensity": _rgb(light.intensity)}
    for i, light in enumerate(scene.spot_lights):
        out[f"spot_{i}"] = {"type": SPOT_PLUGIN, "position": _vector(light.position),
                            "direction": _vector(light.direction), "intensity": _rgb(light.intensity),
                            "inner_cone": float(light.inner_cone), "outer_cone": float(light.outer_cone)}
    for i, light in enumerate(scene.directional_lights):
        out[f"directional_{i}"] = {"type": "directional", "direction": _vector(light.direction),
                                   "irradiance": _rgb(light.irradiance)}
    sky = sky_dict(scene.sky)
    if sky is not None:
        out["sky"] = sky
    for i, sensor in enumerate(sensors):
        out[f"sensor_{i:04d}"] = sensor
    return out, warnings


def render(mi_scene, sensor: int = 0, spp: int | None = None, seed: int = 0) -> np.ndarray:
    """(H, W, 3) float32 linear radiance of one sensor of a loaded scene."""
    import mitsuba as mi

    image = mi.render(mi_scene, sensor=sensor, spp=spp or 0, seed=seed)
    return np.nan_to_num(np.array(image, np.float32)[..., :3], nan=0.0, posinf=0.0)


# -- the spot light of bake/lights.py -----------------------------------------------------------------
def _spot_class():
    import drjit as dr
    import mitsuba as mi

    # An emitter pointer: the object itself in scalar variants (which have no EmitterPtr)
    pointer = (lambda e: e) if mi.variant().startswith("scalar") else mi.EmitterPtr

    class GlintSpot(mi.Emitter):
        """A point light with the glTF cone of bake/lights.py DeltaLights: intensity (W/sr on the
        axis) x clamp(cos(angle to the axis) x scale + offset, 0, 1)^2 / d^2."""

        def __init__(self, props):
            mi.Emitter.__init__(self, props)
            self.position = mi.ScalarPoint3f(props.get("position"))
            axis = np.asarray(props.get("direction"), np.float64)
            axis = axis / max(np.linalg.norm(axis), 1e-30)
            self.axis = mi.ScalarVector3f(axis.tolist())
            self.intensity = props.get_unbounded_texture("intensity")
            ci, co = math.cos(props.get("inner_cone")), math.cos(props.get("outer_cone"))
            self.scale = 1.0 / max(0.001, ci - co)
            self.offset = -co * self.scale
            self.m_flags = +mi.EmitterFlags.DeltaPosition

        def _radiant(self, it_p, si_dummy, active):
            d = mi.Point3f(self.position) - it_p
            dist2 = dr.squared_norm(d)
            dist = dr.sqrt(dist2)
            l = d / dr.maximum(dist, 1e-30)
            att = dr.square(dr.clip(-dr.dot(l, mi.Vector3f(self.axis)) * self.scale + self.offset, 0.0, 1.0))
            value = self.intensity.eval(si_dummy, active) * att / dr.maximum(dist2, 1e-30)
            return l, dist, value

        def sample_direction(self, it, sample, active=True):
            si = dr.zeros(mi.SurfaceInteraction3f)
            l, dist, value = self._radiant(it.p, si, active)
            ds = mi.DirectionSample3f(p=mi.Point3f(self.position), n=mi.Normal3f(0.0), uv=mi.Point2f(0.0),
                                      time=it.time, pdf=mi.Float(1.0), delta=mi.Bool(True), d=l, dist=dist,
                                      emitter=pointer(self))
            return ds, dr.select(active, value, 0.0)

        def pdf_direction(self, it, ds, active=True):
            return mi.Float(0.0)

        def eval_direction(self, it, ds, active=True):
            si = dr.zeros(mi.SurfaceInteraction3f)
            return dr.select(active, self._radiant(it.p, si, active)[2], 0.0)

        def eval(self, si, active=True):
            return mi.Color3f(0.0)

        def sample_ray(self, time, sample1, sample2, sample3, active=True):
            raise NotImplementedError("glint_spot: light tracing is not supported (the path integrator needs none)")

        def to_string(self):
            return "GlintSpot[]"

    return GlintSpot
