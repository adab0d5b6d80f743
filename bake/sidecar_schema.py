"""The sidecar's schema: every key of every table but [materials] (core/material_schema.py holds
those), with its type, its range or choices and its default, and the one check that applies it.

The sidecar reader (bake/sidecar.py), the bake settings (bake/settings.py `resolve_settings`: the
[bake] keys, the command line's `--samples`, `--texels-per-metre`, `-j`) and `--set` (bake/edits.py,
through the sidecar reader) all check a value with `Key.check` (core/schema.py), so a key has one rule and one
message: "NAME.glint.toml: [bake] padding must be a whole number from 0 to 64, not -5". Unknown
keys are warnings (bake/validate.py warn_unknown_keys, with each table's known keys from here).
docs/SCENES.md "The sidecar" lists the same ranges.
"""
from __future__ import annotations

from glint.bake.material_mapping import DIFFUSE_ROUGHNESS
from glint.core.scene import ROLES
from glint.core.schema import Key

QUALITIES = ("draft", "preview", "final")
# max_page_size: xatlas itself packs up to 32768 (slowly: docs/BAKE.md, "Light-map pages (xatlas)"),
# but one page beyond 8192^2 texels is more than 1 GiB of float RGBA in the bake and a
# texture larger than many GPUs take; below 64 a page holds hardly a chart and its padding.
BAKE = {
    "quality": Key("choice", choices=QUALITIES, default="preview"),
    "samples": Key("whole", lo=1, default=128),  # hemisphere paths per texel
    "texels_per_metre": Key("number", lo=0, above=True, default=16.0),  # light-map resolution
    "padding": Key("whole", lo=0, hi=64, default=2),  # texels between charts
    "max_page_size": Key("whole", lo=64, hi=8192, default=2048),
    "max_depth": Key("whole", lo=1, hi=1024, default=64),  # bounces of a path
    # adaptive sampling: undersampled texels get up to this many times `samples` paths; 1: off
    "adaptive_samples": Key("whole", lo=1, hi=1024, default=8),
    "denoise": Key("bool", default=True),
    # texels seeing more back faces than this share are invalid (inside walls)
    "backface_threshold": Key("number", lo=0, hi=1, default=0.2),
    "seed": Key("whole", lo=0, hi=2 ** 32 - 1, default=0),
    "jobs": Key("whole", lo=0, default=0),  # 0: one per core
    # a Dask scheduler's address or local:N (parallel/executor.py checks its form); command line only
    "scheduler": Key("string"),
    "probe_sharing": Key("number", lo=0, default=1.0),  # 0: a probe per object
    "cubemap_budget": Key("whole", lo=1, default=2048),  # probes
    "cubemap_budget_mib": Key("number", lo=0, above=True, default=512.0),
    # glTF dielectrics at least this rough get no lobe (bake/material_mapping.py); > 1 disables the rule
    "diffuse_roughness": Key("number", lo=0, default=DIFFUSE_ROUGHNESS),
}
LIGHTS = {"units": Key("choice", choices=("photometric", "radiometric"), default="photometric")}
SKY = {
    "radiance": Key("rgb", lo=0, default=1.0),  # W/(m^2 sr), linear RGB
    "map": Key("string"),  # an equirectangular EXR/HDR, relative to the sidecar
    "strength": Key("number", lo=0, default=1.0),
}
OBJECTS = {
    "role": Key("choice", choices=ROLES),
    "cubemap_size": Key("power2", lo=4, hi=4096),  # default: bake/cubemap.py's rule
    "bounding_planes": Key("bool"),  # or a list of planes: bake/sidecar.py reads those
    "shared_probe": Key("bool"),
}
PLANE = {"point": Key("vec3"), "normal": Key("vec3")}
CAMERAS = {
    "eye": Key("vec3"), "target": Key("vec3"),
    "yfov": Key("number", lo=0, hi=180, above=True, below=True, default=50.0),  # degrees
    "up": Key("vec3", default=[0.0, 1.0, 0.0]),
    "znear": Key("number", lo=0, above=True, default=0.01),
    "zfar": Key("number", lo=0, above=True, default=1000.0),
    "aspect": Key("number", lo=0, above=True),  # default: the image's
}
PATH_KEY = {"time": Key("number"), "eye": Key("vec3"), "target": Key("vec3"),
            "yfov": Key("number", lo=0, hi=180, above=True, below=True)}
CAMERA_PATHS = {"keys": None}  # a list of PATH_KEY tables: bake/sidecar.py reads it
SCHEMA = {"bake": BAKE, "lights": LIGHTS, "sky": SKY, "materials": None, "objects": OBJECTS,
          "cameras": CAMERAS, "camera_paths": CAMERA_PATHS}


def checked(schema: dict, table: dict, key: str, where: str):
    """`table[key]` checked by `schema[key]`, or the key's default (checked too) when absent."""
    spec = schema[key]
    return spec.check(table[key] if key in table else spec.default, where, key)
