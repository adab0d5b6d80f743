"""The scene data model: what the bake reads, independent of the file format.

Everything is in world space, metres, Y up, linear RGB. A loader
(`bake/gltf_loader.py`) fills these classes; the bake stages only read them.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from glint.core.gltf_brdf import GltfMaterialParams
from glint.core.volume import absorption_coefficient

ROLES = ("diffuse", "curved", "planar", "transmissive")


@dataclass
class Lobe:
    """One specular lobe of the section 3.3 BSDF (Eq. 3.3-3.5).

    kind: "reflect" (Eq. 3.4) or "transmit" (Eq. 3.5, thin surface).
    ks:   RGB lobe weight (k_s of Eq. 3.2, or k_t of Eq. 3.6 for transmission).
    mx, my: Beckmann roughness along tangent / bitangent (Eq. 3.3).
    r0:   Schlick reflectance at normal incidence.
    alpha: Kurt et al.'s shadowing/masking exponent in [0, 1] (Eq. 3.4).
    mr:   how the material's metallic-roughness texture changes it per texel (bake/material_mapping.py):
          "" not at all; "dielectric" ks x (1 - M'), "metal" ks x M' (M' the texel's metallic), and for
          both m' = max(m g^2, 1e-4) (g the texel's roughness multiplier; an anisotropic lobe keeps a^2).
    """

    kind: str = "reflect"
    ks: tuple[float, float, float] = (1.0, 1.0, 1.0)
    mx: float = 0.1
    my: float = 0.1
    r0: float = 0.04
    alpha: float = 0.0
    mr: str = ""

    def to_dict(self) -> dict:
        d = {"kind": self.kind, "ks": list(map(float, self.ks)), "mx": float(self.mx),
             "my": float(self.my), "r0": float(self.r0), "alpha": float(self.alpha)}
        return {**d, "mr": self.mr} if self.mr else d  # untextured lobes: dicts (and hashes) as before


@dataclass
class Material:
    """Eq. 3.6: kd/pi + sum of reflection lobes + sum of transmission lobes, plus emission.

    kd_texture, when present, is an (H, W, 3) float32 array of linear RGB that
    multiplies kd, looked up with the object's `uvs` (the base colour's texCoord set, its
    KHR_texture_transform applied). kd_wrap is its glTF sampler's (wrapS, wrapT), each
    "REPEAT", "CLAMP_TO_EDGE" or "MIRRORED_REPEAT"; kd_nearest its magFilter NEAREST. The
    alpha_texture is sampled the same way.
    emission is emitted radiance (W / (m^2 sr)); non-zero makes the object an area light.
    emission_texture, when present, is an (H, W, 3) float32 array of linear RGB (glTF
    emissiveTexture, sRGB-decoded) that multiplies emission (glTF 3.9.3: emissiveFactor x
    emissiveTexture x emissiveStrength), looked up like kd_texture (same `uvs`, same sampler).

    metallic_roughness_texture, when present, is an (H, W, 3) float32 array (glTF
    metallicRoughnessTexture, linear, looked up like kd_texture): G multiplies the roughness factor
    (the `mr` lobes' widths follow it), B is the texel's metallic M' (metallicFactor already
    multiplied in), R is unused. kd is then the base colour at M' = 0 and is multiplied per texel
    by (1 - M').

    Coverage (glTF 3.9.4 "Alpha Coverage"): alpha_mode is "OPAQUE", "MASK" or "BLEND"; the
    alpha is `alpha` (baseColorFactor[3]) x `alpha_texture` (the base colour texture's alpha,
    (H, W) float32, linear, same uv as kd_texture; None = 1). MASK: the surface exists where
    alpha >= alpha_cutoff and not at all elsewhere; BLEND: it covers the fraction alpha.
    OPAQUE ignores the alpha.

    Volume (KHR_materials_volume, with transmit lobes): `thickness` > 0 makes the object a closed
    solid of refractive index `ior` (KHR_materials_ior) whose surface is two interfaces of one
    body, not a thin sheet (core/volume.py): light refracts in and out, with Fresnel at both, and is
    absorbed inside by Beer-Lambert with `attenuation_color` reached after `attenuation_distance`
    metres. thickness is glTF's thicknessFactor (the wall under the surface, metres; 0 = thin-walled:
    Eq. 3.5's thin surface, the ior and attenuation unused).

    normal_texture, when present, is an (H, W, 3) float32 array of the glTF normalTexture as
    stored (linear, 0..1: the tangent-space normal is 2 x value - 1), looked up like kd_texture;
    normal_scale multiplies its x and y (glTF normalTexture.scale). anisotropy_rotation (radians,
    counter-clockwise from the tangent towards the bitangent) and anisotropy_texture ((H, W, 3),
    linear: RG the direction in tangent space as 2 x value - 1, B a factor on the strength) are
    KHR_materials_anisotropy's; the lobes' mx, my carry the strength itself.

    gltf: the glTF factors the loader mapped the material from (core/gltf_brdf.py's parameters), kept
    so that a reference renders the material as its author defined it (bench/mitsuba_scene.py); None
    for a material not from glTF, or once an override (extras.glint, the sidecar, `--set`) changed it.
    """

    name: str
    kd: np.ndarray = field(default_factory=lambda: np.full(3, 0.8, np.float32))
    kd_texture: np.ndarray | None = None
    kd_wrap: tuple[str, str] = ("REPEAT", "REPEAT")
    kd_nearest: bool = False
    lobes: list[Lobe] = field(default_factory=list)
    emission: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))
    emission_texture: np.ndarray | None = None
    metallic_roughness_texture: np.ndarray | None = None
    double_sided: bool = False
    alpha_mode: str = "OPAQUE"
    alpha_cutoff: float = 0.5
    alpha: float = 1.0
    alpha_texture: np.ndarray | None = None
    normal_texture: np.ndarray | None = None
    normal_scale: float = 1.0
    anisotropy_rotation: float = 0.0
    anisotropy_texture: np.ndarray | None = None
    ior: float = 1.5
    thickness: float = 0.0
    attenuation_distance: float = float("inf")
    attenuation_color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    gltf: GltfMaterialParams | None = None

    @property
    def has_volume(self) -> bool:
        """A closed transmissive solid (two interfaces, refraction), not a thin sheet."""
        return self.thickness > 0 and bool(self.transmit_lobes)

    @property
    def absorption(self) -> np.ndarray:
        """Beer-Lambert coefficient sigma_a (1/m, RGB): exp(-sigma_a x) = attenuation_color^(x / distance)."""
        return absorption_coefficient(self.attenuation_color, self.attenuation_distance)

    @property
    def has_coverage(self) -> bool:
        """MASK or BLEND: parts of the surface let everything through."""
        return self.alpha_mode in ("MASK", "BLEND")

    @property
    def is_emissive(self) -> bool:
        return bool(np.any(np.asarray(self.emission) > 0))

    @property
    def transmit_lobes(self) -> list[Lobe]:
        return [lobe for lobe in self.lobes if lobe.kind == "transmit"]

    @property
    def two_sided(self) -> bool:
        """Scatters light on both sides: glTF doubleSided, or thin transmissive (light passes it
        either way). The bake gives such objects a light map per side; the viewer's MAT_TWO_SIDED."""
        return bool(self.double_sided or self.transmit_lobes)


@dataclass
class Object:
    """One mesh instance with its node transform applied (world space).

    positions (N, 3) float64, normals (N, 3) float32 unit length, uvs (N, 2)
    float32 or None (texture coordinates, not light-map coordinates),
    indices (M, 3) int64 with counter-clockwise front faces.
    """

    name: str
    positions: np.ndarray
    normals: np.ndarray
    indices: np.ndarray
    material: int
    uvs: np.ndarray | None = None
    # glTF COLOR_0 (N, 3) linear RGB in 0..1: multiplies the material's base colour (None = 1)
    colors: np.ndarray | None = None
    # glTF TANGENT (N, 4) in world space: xyz unit tangent, w = +-1, the bitangent being
    # w x (normal x tangent) (glTF 3.7.2.1); None = computed by the viewer (MikkTSpace)
    tangents: np.ndarray | None = None
    role: str = "diffuse"
    role_overridden: bool = False
    options: dict = field(default_factory=dict)  # sidecar [objects."NAME"]: cubemap_size, bounding_planes, shared_probe
    part_of: str = ""  # the object this one is a part of (bake/probe_parts.py), "" for a whole object

    @property
    def triangle_areas(self) -> np.ndarray:
        p = self.positions[self.indices]
        return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)

    @property
    def area(self) -> float:
        return float(self.triangle_areas.sum())

    @property
    def bounds(self) -> np.ndarray:
        return np.stack([self.positions.min(axis=0), self.positions.max(axis=0)])


@dataclass
class PointLight:
    position: np.ndarray
    intensity: np.ndarray  # radiant intensity, W/sr (RGB)
    name: str = ""


@dataclass
class SpotLight:
    position: np.ndarray
    direction: np.ndarray  # unit vector the cone points along
    intensity: np.ndarray  # W/sr on the axis (RGB)
    inner_cone: float = 0.0  # radians
    outer_cone: float = np.pi / 4
    name: str = ""


@dataclass
class DirectionalLight:
    direction: np.ndarray  # unit vector the light travels along
    irradiance: np.ndarray  # W/m^2 on a surface facing the light (RGB)
    name: str = ""


@dataclass
class Sky:
    """Radiance arriving from infinitely far away: a constant, or an equirectangular map.

    The map is (H, W, 3) float32, equirectangular, row 0 straight up (+Y); the
    direction <-> pixel mapping lives in one place, `bake/lights.py`. `radiance`
    multiplies the map.
    """

    radiance: np.ndarray = field(default_factory=lambda: np.ones(3, np.float32))
    map: np.ndarray | None = None
    source: str = ""  # file the map came from (for hashing / messages)


@dataclass
class Camera:
    name: str
    eye: np.ndarray
    forward: np.ndarray  # unit view direction
    up: np.ndarray  # unit, orthogonal to forward
    yfov: float  # vertical field of view, radians
    aspect: float | None = None
    znear: float = 0.01
    zfar: float = 1000.0


@dataclass
class CameraPath:
    name: str
    keys: list[dict]  # [{"time": s, "eye": [x,y,z], "target": [x,y,z]}, ...]


@dataclass
class Scene:
    name: str
    source: Path | None
    objects: list[Object] = field(default_factory=list)
    materials: list[Material] = field(default_factory=list)
    point_lights: list[PointLight] = field(default_factory=list)
    spot_lights: list[SpotLight] = field(default_factory=list)
    directional_lights: list[DirectionalLight] = field(default_factory=list)
    sky: Sky | None = None
    cameras: list[Camera] = field(default_factory=list)
    camera_paths: list[CameraPath] = field(default_factory=list)
    bake_settings: dict = field(default_factory=dict)  # [bake] table of the sidecar
    sidecar: Path | None = None
    # `--set` assignments applied on top of the sidecar, as TOML text (bake/edits.py): part of the
    # bake's source hash; an edited scene bakes into a directory of its own (edited_bake_dir).
    edits: tuple[str, ...] = ()
    warnings: list[str] = field(default_factory=list)
    # glTF features the loader ignored, with how many materials, objects, cameras or uses
    # had each ("normalTexture": 12): what the viewer will show wrong (manifest statistics).
    ignored_features: dict[str, int] = field(default_factory=dict)

    def material_of(self, obj: Object) -> Material:
        return self.materials[obj.material]

    @property
    def emitters(self) -> list[Object]:
        return [o for o in self.objects if self.material_of(o).is_emissive]

    @property
    def has_light(self) -> bool:
        return bool(self.emitters or self.point_lights or self.spot_lights
                    or self.directional_lights
                    or (self.sky is not None and (self.sky.map is not None
                                                  or np.any(self.sky.radiance > 0))))

    @property
    def bounds(self) -> np.ndarray:
        b = np.array([o.bounds for o in self.objects])
        return np.stack([b[:, 0].min(axis=0), b[:, 1].max(axis=0)])
