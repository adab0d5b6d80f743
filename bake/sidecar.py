"""The optional sidecar `NAME.glint.toml` beside `NAME.glb` / `NAME.gltf`.

All tables are optional:

    [bake]                        # passed through as Scene.bake_settings
    quality = "preview"           # draft | preview | final
    texels_per_metre = 24
    probe_sharing = 1.0           # cube maps shared by small curved objects close together
                                  # (bake/cubemap.py "Probes"); 0: one per object
    cubemap_budget = 2048         # at most this many cube maps ...
    cubemap_budget_mib = 512      # ... and MiB of them: more sharing, then smaller faces
    diffuse_roughness = 0.5       # glTF dielectrics at least this rough get no lobe
                                  # (see bake/material_mapping.py); > 1 disables the rule
    [lights]
    units = "photometric"         # glTF candela / lux divided by 683 lm/W, or "radiometric"
    [sky]                         # light from infinitely far away
    radiance = [0.6, 0.7, 0.9]    # constant radiance W/(m^2 sr), linear RGB ...
    map = "sky.exr"               # ... or an equirectangular EXR/HDR (relative to this file)
    strength = 1.0                # multiplies either
    [materials."Floor"]           # by glTF material name: any of kd, emission, lobes
    kd = [0.3, 0.2, 0.1]
    lobes = [ { kind = "reflect", ks = [1, 1, 1], mx = 0.05, my = 0.05, r0 = 0.04, alpha = 0.0 } ]
    [objects."Table top"]         # by glTF node name (or mesh name)
    role = "planar"               # diffuse | curved | planar | transmissive
    [objects."Teapot"]            # cube-map settings of a curved or transmissive object:
    cubemap_size = 256            # face size, a power of two (default: bake/cubemap.py's rule)
    bounding_planes = false       # none; or true (automatic, bake/bounding_planes.py), or a list:
                                  # [ { point = [0, 0, 0], normal = [0, 1, 0] }, ... ]
    shared_probe = false          # its own cube map, never one shared with objects nearby
                                  # (a cubemap_size or bounding_planes false / list imply it)
    [cameras.default]             # extra cameras, after the glTF's own
    eye = [0, 1.6, 3]
    target = [0, 1, 0]
    yfov = 50                     # degrees (default 50); optional up, znear, zfar, aspect
    [camera_paths.tour]
    keys = [ { time = 0.0, eye = [0, 1.6, 3], target = [0, 1, 0] }, ... ]

`diffuse_roughness` sits in [bake] rather than [materials] because [materials]
is keyed by material name (a material could be called "diffuse_roughness").
Wrong types and values outside a key's range are errors naming the file, table, key,
value and what is allowed (each key's rule: bake/sidecar_schema.py); unknown keys are warnings
(a typo should not silently do nothing, nor stop the work).

The per-object cube-map settings reach the bake as `Object.options`
({"cubemap_size": int, "bounding_planes": bool | [{point, normal}], "shared_probe": bool}, empty when the sidecar
gives none); bake/gltf_loader.py resolves the names.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from glint.bake.bounding_planes import MAX_PLANES
from glint.bake.material_mapping import DIFFUSE_ROUGHNESS, parse_material_override
from glint.bake.sidecar_schema import BAKE, CAMERAS, LIGHTS, OBJECTS, PATH_KEY, PLANE, SCHEMA, SKY, checked
from glint.bake.settings import COMMAND_LINE_ONLY
from glint.bake.validate import warn_unknown_keys as _unknown
from glint.core.errors import GlintError
from glint.core.image_io import read_image
from glint.core.scene import Camera, CameraPath, Sky

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

SUFFIX = ".glint.toml"
TABLES = tuple(SCHEMA)
# [bake] keys the bake understands (bake/settings.py) and the material rule's threshold;
# others pass through with a warning. Every key's rule: bake/sidecar_schema.py.
BAKE_KEYS = tuple(key for key in BAKE if key not in COMMAND_LINE_ONLY)


@dataclass
class Sidecar:
    path: Path | None = None  # None when there is no sidecar
    bake: dict = field(default_factory=dict)
    units: str = "photometric"
    diffuse_roughness: float = DIFFUSE_ROUGHNESS
    sky: Sky | None = None
    materials: dict[str, dict] = field(default_factory=dict)  # name -> parse_material_override()
    objects: dict[str, str] = field(default_factory=dict)  # node or mesh name -> role
    # node or mesh name -> {"cubemap_size": int, "bounding_planes": bool | [{point, normal}]}
    object_options: dict[str, dict] = field(default_factory=dict)
    cameras: list[Camera] = field(default_factory=list)
    camera_paths: list[CameraPath] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    # (table, name) -> the `--set` assignment that names it (bake/edits.py): the loader refuses
    # such a material or object name when it matches nothing, where the file's would only warn.
    set_names: dict[tuple[str, str], str] = field(default_factory=dict)


def sidecar_path(scene_path: Path) -> Path:
    """`dir/NAME.glb` -> `dir/NAME.glint.toml`."""
    scene_path = Path(scene_path)
    return scene_path.with_name(scene_path.with_suffix("").name + SUFFIX)


def read_sidecar(scene_path: Path) -> Sidecar:
    """Read and check the sidecar beside `scene_path`; defaults when there is none."""
    path = sidecar_path(scene_path)
    text = read_sidecar_text(path)
    return Sidecar() if text is None else parse_sidecar(parse_toml(text, path), path)


def read_sidecar_text(path: Path) -> str | None:
    """The text of the sidecar file `path`, None when there is none."""
    if not path.exists():
        return None
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise GlintError(f"{path.name}: cannot read: {err}") from None


def parse_toml(text: str, path: Path) -> dict:
    """The sidecar's text as tomllib reads it; invalid TOML is one line naming the file."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise GlintError(f"{Path(path).name}: invalid TOML: {err}") from None


def parse_sidecar(data: dict, path: Path) -> Sidecar:
    """Check a parsed TOML document; `path` names the file in messages and anchors `map`."""
    side = Sidecar(path=Path(path))
    name = side.path.name
    w = side.warnings
    _unknown(data, TABLES, name, "", w)
    for table in TABLES:
        if table in data and not isinstance(data[table], dict):
            raise GlintError(f"{name}: '{table}' must be a table ([{table}])")

    bake = dict(data.get("bake", {}))
    _unknown(bake, BAKE_KEYS, name, "[bake] ", w)
    for key in BAKE_KEYS:
        if key in bake:
            BAKE[key].check(bake[key], f"{name}: [bake]", key)
    side.diffuse_roughness = checked(BAKE, bake, "diffuse_roughness", f"{name}: [bake]")
    side.bake = bake

    lights = data.get("lights", {})
    _unknown(lights, LIGHTS, name, "[lights] ", w)
    side.units = checked(LIGHTS, lights, "units", f"{name}: [lights]")

    if "sky" in data:
        side.sky = _sky(data["sky"], side.path, w)

    for mat_name, table in data.get("materials", {}).items():
        side.materials[mat_name] = parse_material_override(
            table, f"{name}: [materials.\"{mat_name}\"]", w)

    for obj_name, table in data.get("objects", {}).items():
        where = f"{name}: [objects.\"{obj_name}\"]"
        if not isinstance(table, dict):
            raise GlintError(f"{where} must be a table")
        _unknown(table, OBJECTS, name, f"[objects.\"{obj_name}\"] ", w)
        if "role" in table:
            side.objects[obj_name] = checked(OBJECTS, table, "role", where)
        options = _cubemap_options(table, name, obj_name, w)
        if options:
            side.object_options[obj_name] = options

    for cam_name, table in data.get("cameras", {}).items():
        side.cameras.append(_camera(cam_name, table, name, w))

    for path_name, table in data.get("camera_paths", {}).items():
        side.camera_paths.append(_camera_path(path_name, table, name, w))
    return side


def _cubemap_options(table: dict, name: str, obj_name: str, w: list[str]) -> dict:
    """`cubemap_size` (a power of two), `bounding_planes` (true, false or a list of
    {point, normal} with a non-zero normal, made unit length) and `shared_probe` (true or false)
    of an [objects."NAME"] table."""
    where = f"{name}: [objects.\"{obj_name}\"]"
    options = {}
    for key in ("cubemap_size", "shared_probe"):
        if key in table:
            options[key] = checked(OBJECTS, table, key, where)
    if "bounding_planes" in table:
        planes = table["bounding_planes"]
        if isinstance(planes, bool):
            options["bounding_planes"] = planes
        elif isinstance(planes, list) and len(planes) <= MAX_PLANES:
            options["bounding_planes"] = [_plane(plane, f"{where} bounding_planes[{k}]", name,
                                                 f"[objects.\"{obj_name}\"] bounding_planes[{k}] ", w)
                                          for k, plane in enumerate(planes)]
        else:
            raise GlintError(f"{where} bounding_planes must be true, false or a list of at most "
                             f"{MAX_PLANES} {{ point = [x, y, z], normal = [x, y, z] }}, not {planes!r}")
    return options


def _plane(plane, where: str, name: str, prefix: str, w: list[str]) -> dict:
    if not isinstance(plane, dict):
        raise GlintError(f"{where} must be a table {{ point = [x, y, z], normal = [x, y, z] }}")
    _unknown(plane, PLANE, name, prefix, w)
    for key in PLANE:
        if key not in plane:
            raise GlintError(f"{where}: missing '{key}'")
    normal = checked(PLANE, plane, "normal", where)
    length = float(np.linalg.norm(normal))
    if not length > 1e-12:
        raise GlintError(f"{where} normal must not be zero")
    return {"point": checked(PLANE, plane, "point", where).tolist(), "normal": (normal / length).tolist()}


def look_at(name: str, eye, target, yfov: float, up=(0.0, 1.0, 0.0), *, where: str = "",
            znear: float = 0.01, zfar: float = 1000.0, aspect: float | None = None) -> Camera:
    """A Camera looking from eye at target; `up` is made orthogonal to the view direction."""
    eye = np.asarray(eye, np.float64)
    forward = np.asarray(target, np.float64) - eye
    if np.linalg.norm(forward) < 1e-9:
        raise GlintError(f"{where}: eye and target are the same point")
    forward /= np.linalg.norm(forward)
    up = np.asarray(up, np.float64)
    up = up - forward * np.dot(up, forward)
    if np.linalg.norm(up) < 1e-6:
        raise GlintError(f"{where}: the view direction is parallel to up; give another 'up'")
    up /= np.linalg.norm(up)
    return Camera(name=name, eye=eye, forward=forward, up=up, yfov=float(yfov),
                  aspect=aspect, znear=znear, zfar=zfar)


def _camera(cam_name: str, table, name: str, w: list[str]) -> Camera:
    where = f"{name}: [cameras.{cam_name}]"
    if not isinstance(table, dict):
        raise GlintError(f"{where} must be a table")
    _unknown(table, CAMERAS, name, f"[cameras.{cam_name}] ", w)
    for key in ("eye", "target"):
        if key not in table:
            raise GlintError(f"{where}: missing '{key}'")
    v = {key: checked(CAMERAS, table, key, where) for key in CAMERAS if key in table or CAMERAS[key].default is not None}
    return look_at(cam_name, v["eye"], v["target"], math.radians(v["yfov"]), v["up"], where=where,
                   znear=v["znear"], zfar=v["zfar"], aspect=v.get("aspect"))


def _camera_path(path_name: str, table, name: str, w: list[str]) -> CameraPath:
    """Keys keep eye/target as 3 floats; an optional per-key yfov is converted to radians."""
    where = f"{name}: [camera_paths.{path_name}]"
    if not isinstance(table, dict):
        raise GlintError(f"{where} must be a table")
    _unknown(table, ("keys",), name, f"[camera_paths.{path_name}] ", w)
    keys = table.get("keys")
    if not isinstance(keys, list) or not keys:
        raise GlintError(f"{where}: 'keys' must be a non-empty list of "
                         "{ time = ..., eye = [...], target = [...] }")
    out, last = [], -math.inf
    for i, key in enumerate(keys):
        kw = f"{where} keys[{i}]"
        if not isinstance(key, dict):
            raise GlintError(f"{kw} must be a table {{ time, eye, target }}")
        _unknown(key, PATH_KEY, name,
                 f"[camera_paths.{path_name}] keys[{i}] ", w)
        for k in ("time", "eye", "target"):
            if k not in key:
                raise GlintError(f"{kw}: missing '{k}'")
        t = checked(PATH_KEY, key, "time", kw)
        if t <= last:
            raise GlintError(f"{kw}: times must increase ({t} after {last})")
        last = t
        item = {"time": t, "eye": checked(PATH_KEY, key, "eye", kw).tolist(),
                "target": checked(PATH_KEY, key, "target", kw).tolist()}
        if "yfov" in key:
            item["yfov"] = math.radians(checked(PATH_KEY, key, "yfov", kw))
        out.append(item)
    return CameraPath(name=path_name, keys=out)


def _sky(table, path: Path, w: list[str]) -> Sky:
    """[sky]: `strength` times either a constant `radiance` or an equirectangular `map`.

    With a map, `Sky.map` already includes the strength and `Sky.radiance` is (1, 1, 1).
    """
    name = path.name
    _unknown(table, SKY, name, "[sky] ", w)
    strength = checked(SKY, table, "strength", f"{name}: [sky]")
    if "radiance" in table and "map" in table:
        raise GlintError(f"{name}: [sky] give either 'radiance' or 'map', not both")
    if "map" in table:
        map_path = (path.parent / checked(SKY, table, "map", f"{name}: [sky]")).resolve()
        image = read_sky_map(map_path, where=f"{name}: [sky] map")
        return Sky(radiance=np.ones(3, np.float32), map=image * np.float32(strength),
                   source=str(map_path))
    radiance = checked(SKY, table, "radiance", f"{name}: [sky]")
    return Sky(radiance=(radiance * strength).astype(np.float32))


def read_sky_map(path: Path, where: str = "sky map") -> np.ndarray:
    """An equirectangular EXR/HDR/... -> (H, W, 3) float32 linear RGB, via OpenImageIO."""

    pixels = read_image(path, where)
    if pixels.shape[2] < 3:
        pixels = np.repeat(pixels[:, :, :1], 3, axis=2)
    pixels = np.ascontiguousarray(pixels[:, :, :3])
    if not np.all(np.isfinite(pixels)):
        raise GlintError(f"{where}: {path} contains NaN or infinite pixels")
    if np.any(pixels < 0):
        raise GlintError(f"{where}: {path} contains negative radiance")
    return pixels
