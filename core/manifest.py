"""The bake directory's manifest.json as typed data: the one contract between the bake and its readers.

bake/pipeline.py builds a `Manifest` and writes `to_json()`; the viewer and the commands read
`Bake.model` (core/bake_dir.py), a `Manifest.from_json` of the file. Each optional field's default is
written once, here, in its dataclass: a key absent from an older bake directory reads as that default
(no FORMAT_VERSION change), and `to_json` leaves out what the bake leaves out (a material's optional
entries where they have their defaults, `inputs` where a bake predates it), so that
`to_json(from_json(x)) == x`, key order included, for every manifest the bake writes.

Free-form parts stay dicts: `settings` (BakeSettings' fields), `stages`, `inputs` (core/skipped.py reads
them) and the statistics behind `Statistics`' accessors. The viewer's panel edits typed materials
(`dataclasses.replace`, checked by core/material_schema.py); they become JSON dicts again only where
they leave it: the GPU upload, Save and the background re-bake (`to_json`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

from glint.core.gltf_brdf import GltfMaterialParams
from glint.core.scene import Lobe

OPAQUE = "OPAQUE"


def lobe_from_json(d: dict) -> Lobe:
    """The one reading of a lobe dict (manifest or edit, `Lobe.to_dict`): absent keys take core.scene.Lobe's
    defaults (mx = my = 0.1, ...), the lobe's one set of defaults."""
    known = {k: d[k] for k in ("kind", "mx", "my", "r0", "alpha", "mr") if k in d}
    if "ks" in d:
        known["ks"] = tuple(d["ks"])
    return Lobe(**known)


def _fields(obj) -> dict:
    """A flat dataclass as JSON, its fields in their order (lists and tuples as lists)."""
    return {k: (list(v) if isinstance(v, (list, tuple)) else v) for k, v in vars(obj).items()}


@dataclass(frozen=True)
class Sampler:
    """A textured material's glTF sampler (`kd_sampler`); the default (REPEAT, LINEAR) is left out."""
    wrap_s: str = "REPEAT"
    wrap_t: str = "REPEAT"
    mag_filter: str = "LINEAR"

    @classmethod
    def from_json(cls, d: dict | None) -> "Sampler":
        return cls(**(d or {}))

    def to_json(self) -> dict:
        return _fields(self)


@dataclass(frozen=True)
class Volume:
    """A glass solid's `volume` (core/volume.py): ior, thickness (m), absorption sigma_a (1/m)."""
    ior: float = 1.5
    thickness: float = 0.0
    absorption: list = field(default_factory=lambda: [0.0, 0.0, 0.0])

    @classmethod
    def from_json(cls, d: dict) -> "Volume":
        return cls(**d)

    def to_json(self) -> dict:
        return _fields(self)


@dataclass(frozen=True)
class Material:
    """A manifest material (bake/pipeline.py describe). Optional entries, left out of the JSON at their
    defaults: emission_texture, metallic_roughness_texture, kd_sampler, the coverage (alpha_mode OPAQUE:
    older bake dirs lack it), volume (None: thin), normal_texture with normal_scale, anisotropy, and
    gltf: the glTF factors the material was mapped from (core/scene.py `Material.gltf`), so that the
    panel shows them as their author set them; None (left out) for other materials and once an edit
    changed kd or the lobes by hand."""
    name: str = ""
    kd: list = field(default_factory=lambda: [0.8, 0.8, 0.8])
    emission: list = field(default_factory=lambda: [0.0, 0.0, 0.0])
    double_sided: bool = False
    lobes: list = field(default_factory=list)  # of core.scene.Lobe
    kd_texture: str | None = None
    emission_texture: str | None = None
    metallic_roughness_texture: str | None = None
    kd_sampler: Sampler = Sampler()
    alpha_mode: str = OPAQUE
    alpha_cutoff: float = 0.5
    alpha: float = 1.0
    volume: Volume | None = None
    normal_texture: str | None = None
    normal_scale: float = 1.0
    anisotropy_rotation: float = 0.0
    anisotropy_texture: str | None = None
    gltf: GltfMaterialParams | None = None

    @property
    def has_coverage(self) -> bool:
        return self.alpha_mode in ("MASK", "BLEND")

    @classmethod
    def from_json(cls, d: dict) -> "Material":
        plain = ("name", "kd", "emission", "double_sided", "kd_texture", "emission_texture",
                 "metallic_roughness_texture", "alpha_mode", "alpha_cutoff", "alpha", "normal_texture",
                 "normal_scale", "anisotropy_rotation", "anisotropy_texture")
        return cls(**{k: d[k] for k in plain if k in d}, lobes=[lobe_from_json(lobe) for lobe in d.get("lobes") or []],
                   kd_sampler=Sampler.from_json(d.get("kd_sampler")),
                   volume=Volume.from_json(d["volume"]) if d.get("volume") else None,
                   gltf=GltfMaterialParams(**d["gltf"]) if d.get("gltf") else None)

    def to_json(self) -> dict:
        out = {"name": self.name, "kd": list(self.kd), "emission": list(self.emission),
               "double_sided": self.double_sided, "lobes": [lobe.to_dict() for lobe in self.lobes],
               "kd_texture": self.kd_texture}
        if self.emission_texture is not None:
            out["emission_texture"] = self.emission_texture
        if self.metallic_roughness_texture is not None:
            out["metallic_roughness_texture"] = self.metallic_roughness_texture
        if self.kd_sampler != Sampler():
            out["kd_sampler"] = self.kd_sampler.to_json()
        if self.has_coverage:
            out.update(alpha_mode=self.alpha_mode, alpha_cutoff=self.alpha_cutoff, alpha=self.alpha)
        if self.volume is not None:
            out["volume"] = self.volume.to_json()
        if self.normal_texture is not None:
            out.update(normal_texture=self.normal_texture, normal_scale=self.normal_scale)
        if self.anisotropy_rotation:
            out["anisotropy_rotation"] = self.anisotropy_rotation
        if self.anisotropy_texture is not None:
            out["anisotropy_texture"] = self.anisotropy_texture
        if self.gltf is not None:
            out["gltf"] = _fields(self.gltf)
        return out


@dataclass(frozen=True)
class BoundingPlane:
    """A cube map's bounding plane (bake/bounding_planes.py): point, normal, the object it is of."""
    point: list
    normal: list
    object: str | None = None

    @classmethod
    def from_json(cls, d: dict) -> "BoundingPlane":
        return cls(d["point"], d["normal"], d.get("object"))

    def to_json(self) -> dict:
        return _fields(self)


@dataclass(frozen=True)
class CubeMapEntry:
    """An object's cube-map probe (bake/cubemap.py CubeMapPlan); shared_by 1 (an own map) is left out."""
    file: str
    size: int
    centre: list
    bounding_planes: list = field(default_factory=list)  # of BoundingPlane
    shared_by: int = 1

    @classmethod
    def from_json(cls, d: dict) -> "CubeMapEntry":
        return cls(d["file"], d["size"], d["centre"], [BoundingPlane.from_json(p) for p in d.get("bounding_planes") or []],
                   d.get("shared_by", 1))

    def to_json(self) -> dict:
        out = {"file": self.file, "size": self.size, "centre": list(self.centre),
               "bounding_planes": [p.to_json() for p in self.bounding_planes]}
        if self.shared_by != 1:
            out["shared_by"] = self.shared_by
        return out


@dataclass(frozen=True)
class Plane:
    """A planar object's plane: a point on it and its unit normal."""
    point: list
    normal: list

    def to_json(self) -> dict:
        return _fields(self)


@dataclass(frozen=True)
class ObjectEntry:
    """A manifest object: `bounds` [lo, hi]; `lightmap_back` (absent in older bake dirs: False) whether
    it has its own back-side light map; `plane` for planar objects; `cubemap` or None."""
    name: str
    material: int = 0
    role: str = "diffuse"
    bounds: list = field(default_factory=lambda: [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    triangles: int = 0
    lightmap_back: bool = False
    plane: Plane | None = None
    cubemap: CubeMapEntry | None = None

    @classmethod
    def from_json(cls, d: dict) -> "ObjectEntry":
        plane = d.get("plane")
        return cls(**{k: d[k] for k in ("name", "material", "role", "bounds", "triangles", "lightmap_back") if k in d},
                   plane=Plane(plane["point"], plane["normal"]) if plane else None,
                   cubemap=CubeMapEntry.from_json(d["cubemap"]) if d.get("cubemap") else None)

    def to_json(self) -> dict:
        out = {"name": self.name, "material": self.material, "role": self.role,
               "bounds": [list(b) for b in self.bounds], "triangles": self.triangles,
               "lightmap_back": self.lightmap_back}
        if self.plane is not None:
            out["plane"] = self.plane.to_json()
        out["cubemap"] = self.cubemap.to_json() if self.cubemap is not None else None
        return out


@dataclass(frozen=True)
class PointLight:
    name: str
    position: list
    intensity: list


@dataclass(frozen=True)
class SpotLight:
    name: str
    position: list
    direction: list
    intensity: list
    inner_cone: float
    outer_cone: float


@dataclass(frozen=True)
class DirectionalLight:
    name: str
    direction: list
    irradiance: list


@dataclass(frozen=True)
class Lights:
    point: list = field(default_factory=list)
    spot: list = field(default_factory=list)
    directional: list = field(default_factory=list)

    @classmethod
    def from_json(cls, d: dict | None) -> "Lights":
        d = d or {}
        return cls([PointLight(**x) for x in d.get("point") or []], [SpotLight(**x) for x in d.get("spot") or []],
                   [DirectionalLight(**x) for x in d.get("directional") or []])

    def to_json(self) -> dict:
        return {"point": [_fields(x) for x in self.point], "spot": [_fields(x) for x in self.spot],
                "directional": [_fields(x) for x in self.directional]}


@dataclass(frozen=True)
class Sky:
    """Constant radiance (multiplying the map, where there is one: its file in the bake dir)."""
    radiance: list = field(default_factory=lambda: [1.0, 1.0, 1.0])
    map: str | None = None

    def to_json(self) -> dict:
        return _fields(self)


@dataclass(frozen=True)
class Camera:
    """A scene camera (its aspect, None where the file gave none, is not used by the viewer)."""
    name: str = ""
    eye: list = field(default_factory=lambda: [0.0, 0.0, 0.0])
    forward: list = field(default_factory=lambda: [0.0, 0.0, -1.0])
    up: list = field(default_factory=lambda: [0.0, 1.0, 0.0])
    yfov: float = 0.8726646259971648  # 50 degrees (viewer/camera.py DEFAULT_YFOV)
    aspect: float | None = None
    znear: float = 0.01
    zfar: float = 1000.0

    def to_json(self) -> dict:
        return _fields(self)


@dataclass(frozen=True)
class CameraKey:
    """A camera-path key: time (s), eye, target, and its own yfov or None (the path's)."""
    time: float
    eye: list
    target: list
    yfov: float | None = None

    def to_json(self) -> dict:
        out = {"time": self.time, "eye": list(self.eye), "target": list(self.target)}
        return {**out, "yfov": self.yfov} if self.yfov is not None else out


@dataclass(frozen=True)
class CameraPath:
    name: str
    keys: list  # of CameraKey

    @classmethod
    def from_json(cls, d: dict) -> "CameraPath":
        return cls(d.get("name", ""), [CameraKey(**k) for k in d["keys"]])

    def to_json(self) -> dict:
        return {"name": self.name, "keys": [k.to_json() for k in self.keys]}


@dataclass(frozen=True)
class SceneInfo:
    """The scene's name, source path (information only) and content hash (bake/pipeline.py source_hash)."""
    name: str = ""
    source: str | None = None
    hash: str = ""

    def to_json(self) -> dict:
        return _fields(self)


@dataclass(frozen=True)
class Atlas:
    """The light-map atlas: page size, page count, texel density and padding (bake/unwrap.py)."""
    width: int = 0
    height: int = 0
    pages: int = 0
    texels_per_metre: float = 0.0
    padding: int = 0

    def to_json(self) -> dict:
        return _fields(self)


@dataclass(frozen=True)
class Statistics:
    """The bake's statistics, free-form JSON (times, rays, ...) with typed access to what is read."""
    data: dict = field(default_factory=dict)

    @property
    def lightmaps(self) -> dict:
        """statistics.lightmaps: texels, invalid_texels, rays, seconds, ... ({} where not baked)."""
        return self.data.get("lightmaps") or {}

    @property
    def cubemaps(self) -> dict:
        return self.data.get("cubemaps") or {}

    @property
    def last_bake(self) -> dict | None:
        """What the bake that wrote it redid and why (core/skipped.py); None in older bake dirs."""
        return self.data.get("last_bake")

    @property
    def ignored_features(self) -> dict:
        """{glTF feature: count} the loader ignored ({} in older bake dirs)."""
        return self.data.get("ignored_features") or {}

    @property
    def cluster(self) -> dict | None:
        """Where a bake on a Dask cluster ran (parallel/executor.py); None otherwise."""
        return self.data.get("cluster")


@dataclass(frozen=True)
class Manifest:
    """manifest.json (core/bake_dir.py). `inputs` None: a bake dir older than it (left out of the JSON);
    `lightmaps_back` empty: no object has a back side (older bake dirs lack it)."""
    format: str = "glint-bake"
    version: int = 1
    scene: SceneInfo = SceneInfo()
    settings: dict = field(default_factory=dict)
    stages: dict = field(default_factory=dict)
    inputs: dict | None = None
    objects: list = field(default_factory=list)  # of ObjectEntry
    materials: list = field(default_factory=list)  # of Material
    lights: Lights = Lights()
    sky: Sky | None = None
    cameras: list = field(default_factory=list)  # of Camera
    camera_paths: list = field(default_factory=list)  # of CameraPath
    atlas: Atlas = Atlas()
    lightmaps: list = field(default_factory=list)  # front pages' files
    lightmaps_back: list = field(default_factory=list)  # back pages' files
    statistics: Statistics = Statistics()

    @classmethod
    def from_json(cls, d: dict) -> "Manifest":
        return cls(format=d.get("format", "glint-bake"), version=d.get("version", 1),
                   scene=SceneInfo(**(d.get("scene") or {})), settings=dict(d.get("settings") or {}),
                   stages=dict(d.get("stages") or {}), inputs=d.get("inputs"),
                   objects=[ObjectEntry.from_json(o) for o in d.get("objects") or []],
                   materials=[Material.from_json(m) for m in d.get("materials") or []],
                   lights=Lights.from_json(d.get("lights")),
                   sky=Sky(**d["sky"]) if d.get("sky") else None,
                   cameras=[Camera(**c) for c in d.get("cameras") or []],
                   camera_paths=[CameraPath.from_json(p) for p in d.get("camera_paths") or []],
                   atlas=Atlas(**(d.get("atlas") or {})), lightmaps=list(d.get("lightmaps") or []),
                   lightmaps_back=list(d.get("lightmaps_back") or []),
                   statistics=Statistics(dict(d.get("statistics") or {})))

    def description_json(self) -> dict:
        """objects, materials, lights, sky, cameras, camera_paths: what bake/pipeline.py describe writes."""
        return {"objects": [o.to_json() for o in self.objects], "materials": [m.to_json() for m in self.materials],
                "lights": self.lights.to_json(), "sky": self.sky.to_json() if self.sky is not None else None,
                "cameras": [c.to_json() for c in self.cameras], "camera_paths": [p.to_json() for p in self.camera_paths]}

    def to_json(self) -> dict:
        out = {"format": self.format, "version": self.version, "scene": self.scene.to_json(),
               "settings": dict(self.settings), "stages": dict(self.stages)}
        if self.inputs is not None:
            out["inputs"] = self.inputs
        return {**out, **self.description_json(), "atlas": self.atlas.to_json(), "lightmaps": list(self.lightmaps),
                "lightmaps_back": list(self.lightmaps_back), "statistics": dict(self.statistics.data)}

    # -- what readers ask ----------------------------------------------------------------------------
    def has_back(self, obj: int) -> bool:
        """Whether object `obj` has its own back-side light map (else its back face reads the front's)."""
        return bool(self.lightmaps_back) and self.objects[obj].lightmap_back

    def material_of(self, obj: ObjectEntry) -> Material:
        return self.materials[int(obj.material)]
