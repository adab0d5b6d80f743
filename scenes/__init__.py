"""Built-in scenes, made by `scenes/generate.py`, and the SCENE argument resolver."""
from __future__ import annotations

from importlib import resources
from pathlib import Path

from glint.core.errors import GlintError

BUILTIN = {
    "cornell-box": ("cornell-box.glb", "Mitsuba 3's mitsuba.cornell_box(), for pixel-by-pixel comparison"),
    "living-room": ("living-room.glb", "lit interior: glossy floor and table, metal, brushed metal, frosted glass"),
    "material-classes": ("material-classes.glb", "one sphere per material class of the thesis (glossy ceramic, "
                                                 "chrome, brushed aluminium, frosted glass) in a small lit room"),
    "planar-classes": ("planar-classes.glb", "one planar reflector per planar material class (polished stone, "
                                             "varnished wood, glossy tiles, blurry aluminium), each its own plane"),
    "metal-floor-room": ("metal-floor-room.glb", "a closed room with a polished-metal floor (metallic 1, roughness "
                                                 "0.05), one ceiling light, coloured walls, a pedestal with a ball"),
    "glossy-floor-room": ("glossy-floor-room.glb", "metal-floor-room with a glossy dielectric floor (roughness 0.1, "
                                                   "r0 0.04, kd 0.4)"),
}


def builtin_path(name: str) -> Path:
    return Path(str(resources.files(__name__).joinpath(BUILTIN[name][0])))


def resolve(scene: str) -> Path:
    """A built-in scene name or a path to a .glb/.gltf file -> an existing file path."""
    if scene in BUILTIN:
        return builtin_path(scene)
    path = Path(scene)
    if path.suffix.lower() not in (".glb", ".gltf"):
        if not path.exists():
            names = ", ".join(BUILTIN)
            raise GlintError(f"unknown scene '{scene}': not a built-in scene ({names}) "
                             "and not a .glb/.gltf file")
        raise GlintError(f"{scene}: not a glTF file (expected .glb or .gltf)")
    if not path.exists():
        raise GlintError(f"{scene}: no such file")
    if not path.is_file():
        raise GlintError(f"{scene}: not a file")
    return path
