"""glTF 2.0 (.gltf + .bin, or .glb) + optional sidecar -> `glint.core.scene.Scene`.

The file is read here, not with `trimesh.load`: trimesh keeps only the first
camera (and drops the camera node's subtree), loses which glTF material and
primitive each geometry came from, skips KHR_lights_punctual, and reports
broken files with assertion errors. glint needs all of that exactly, and one
clear message per broken file. trimesh's reader (trimesh/exchange/gltf) was the
reference for the accessor decoding (bake/gltf_accessors.py).

This module runs the load; each part of the file has its own reader:
- bake/gltf_container.py   the .glb/.gltf container and its buffers -> GltfDocument
- bake/gltf_accessors.py   accessors (sparse, normalised), meshopt and Draco decoding
- bake/gltf_materials.py   materials, textures, images, samplers -> Material
- bake/gltf_primitives.py  mesh primitives -> Object (indices, normals, tangents, uvs)
- bake/gltf_scene.py       nodes and transforms, objects per node, lights, cameras

Conventions:
- One `Object` per (node, triangle primitive), in world space: positions by the
  node's world matrix, normals by its inverse transpose (the cofactor matrix),
  winding reversed where the matrix mirrors (negative determinant, glTF 3.7.4).
  Object.name is the node's name (else its mesh's, else "node<i>"), made unique
  with ".1", ".2", ... across primitives and repeated names.
- Missing normals are computed flat (one normal per face, vertices split), as
  the glTF spec requires of clients; zero-length or non-finite normals are
  replaced by the (area-weighted) face normal. Degenerate triangles are dropped.
- Object.uvs is the base colour texture's set (textureInfo.texCoord, default TEXCOORD_0; else
  the first of the emissive, metallic-roughness, normal and anisotropy textures')
  with its KHR_texture_transform applied: (0, 0) is the top-left of the image, and
  Material.kd_texture row 0 is the image's top row, so texel = (v * H, u * W).
- Object.tangents: glTF TANGENT in world space (w flipped under a mirroring matrix), or None.
- Primitives without a material get "default": a grey (kd 0.8) diffuse material.
- KHR_lights_punctual: intensity is candela (point, spot) or lux (directional);
  with `[lights] units = "photometric"` (default) it is divided by 683 lm/W to
  W/sr and W/m^2. Lights shine along the node's -Z; `range` is ignored with a
  warning (the inverse-square law applies everywhere).
- The base colour texture's glTF sampler (wrapS, wrapT, magFilter NEAREST) is kept in
  Material.kd_wrap / kd_nearest; minFilter is not read.
- COLOR_0 (RGB) is Object.colors; its alpha is warned about as not supported.
- What is not supported (skins, morph targets, animations, ...) is warned about, with a kind where it
  repeats per object or material, and counted in Scene.ignored_features.
- Cameras: every perspective camera on a node (eye = node origin, forward = -Z,
  up = +Y, in world space); orthographic cameras are skipped with a warning.
  The sidecar's [cameras] follow the glTF's.
"""
from __future__ import annotations

from functools import partial
from pathlib import Path

from glint.bake.edits import edited_sidecar
from glint.bake.gltf_accessors import Accessors
from glint.bake.gltf_container import MESHOPT, GltfDocument, read_gltf
from glint.bake.gltf_materials import MaterialReader
from glint.bake.gltf_primitives import PrimitiveReader
from glint.bake.gltf_scene import SceneGraphReader, node_world_matrices
from glint.bake.material_mapping import MATERIAL_EXTENSIONS
from glint.bake.probe_parts import split_large_reflectors
from glint.bake.roles import assign_roles
from glint.bake.sidecar import read_sidecar
from glint.bake.validate import add_warning, validate_scene
from glint.core.errors import GlintError, summarised
from glint.core.scene import Scene

# Compressed geometry is decoded where it is read (bake/gltf_accessors.py): KHR_draco_mesh_compression
# per primitive (DracoPy), EXT/KHR_meshopt_compression per bufferView (meshopt).
SUPPORTED_EXTENSIONS = frozenset(("KHR_lights_punctual", "KHR_mesh_quantization", "KHR_texture_transform",
                                  "KHR_draco_mesh_compression") + MESHOPT + MATERIAL_EXTENSIONS)


def load_scene(path: Path, edits: list = ()) -> Scene:
    """Read a .glb/.gltf and its sidecar `<stem>.glint.toml` into a checked Scene; `edits`:
    `KEY=VALUE` assignments applied on top of the sidecar (bake/edits.py, `--set`)."""
    path = Path(path)
    # Repeated warnings are summarised when loading ends, or fails (the error comes last).
    with summarised() as record:
        doc = _guarded(path, read_gltf, path)
        side, texts = edited_sidecar(path, edits) if edits else (read_sidecar(path), ())
        scene = _guarded(path, lambda: _SceneBuilder(doc, side).build())
        scene.edits = texts
        scene.ignored_features = record.ignored_features()
    return scene


def _guarded(path: Path, fn, *args):
    """Run fn; a structure the explicit checks did not foresee still gives one line."""
    try:
        return fn(*args)
    except GlintError:
        raise
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as err:
        raise GlintError(f"{path.name}: malformed glTF ({type(err).__name__}: {err})") from err


class _SceneBuilder:
    """One load: the readers of the document's parts, run in order, and the sidecar's names
    (roles, object options, material settings) matched against what they read."""

    def __init__(self, doc: GltfDocument, side):
        self.doc, self.side, self.tree = doc, side, doc.json
        self.source = doc.source
        self.warnings: list[str] = []
        self.warn = partial(add_warning, self.warnings)
        self.materials = MaterialReader(doc, side, self.warnings)
        primitives = PrimitiveReader(doc, Accessors(doc), self.materials, self.warnings)
        self.graph = SceneGraphReader(doc, side, primitives, self.warnings)

    def build(self) -> Scene:
        doc, side = self.doc, self.side
        scene = Scene(name=doc.path.stem, source=doc.path, sidecar=side.path,
                      bake_settings=dict(side.bake), sky=side.sky,
                      camera_paths=list(side.camera_paths))
        self._check_extensions()
        animations = len(self.doc.table("animations"))
        if animations:
            self.warn(f"{self.source}: {animations} animation(s) not played; the scene is shown "
                      "as stored", ignored={"animations": animations})
        worlds = node_world_matrices(self.tree, self.source)
        scene.materials = self.materials.read()
        aliases = self.graph.objects(scene, worlds)
        self.graph.lights(scene, worlds)
        self.graph.cameras(scene, worlds)
        self._check_material_names()
        assign_roles(scene, self._role_overrides(scene, aliases))
        options = self._object_options(scene, aliases)
        for obj in scene.objects:
            obj.options = options.get(obj.name, {})
        split_large_reflectors(scene)  # after the options: a probe the sidecar fixed keeps its object whole
        scene.warnings = list(side.warnings) + self.warnings
        validate_scene(scene)
        return scene

    # ---- extensions

    def _check_extensions(self):
        required = set(self.tree.get("extensionsRequired", [])) - SUPPORTED_EXTENSIONS
        if required:
            raise GlintError(f"{self.source}: requires glTF extension(s) "
                             f"{', '.join(sorted(required))} that glint does not support; "
                             "export again without them")
        used = set(self.tree.get("extensionsUsed", [])) - SUPPORTED_EXTENSIONS
        if used:
            self.warn(f"{self.source}: glTF extension(s) {', '.join(sorted(used))} not "
                      f"supported, ignored",
                      ignored={ext: max(_uses(self.tree, ext), 1) for ext in sorted(used)})

    # ---- sidecar roles

    def _role_overrides(self, scene: Scene, aliases) -> dict[str, str]:
        """[objects."NAME"] matches an object name, else a node name, else a mesh name."""
        out = {}
        for key, role in self.side.objects.items():
            out.update({h: role for h in self._matching(scene, aliases, key)})
        return out

    def _object_options(self, scene: Scene, aliases) -> dict[str, dict]:
        """[objects."NAME"] cube-map settings (bake/sidecar.py) by object name, matched as roles are."""
        out = {}
        for key, options in self.side.object_options.items():
            hits = self._matching(scene, aliases, key, warn=key not in self.side.objects)
            out.update({h: dict(options) for h in hits})
        return out

    def _matching(self, scene: Scene, aliases, key: str, warn: bool = True) -> list[str]:
        hits = [o.name for o in scene.objects if o.name == key]
        hits = hits or [o.name for o in scene.objects if aliases[o.name][0] == key]
        hits = hits or [o.name for o in scene.objects if aliases[o.name][1] == key]
        if not hits and ("objects", key) in self.side.set_names:
            raise GlintError(f"{self.side.set_names['objects', key]}: no object, node or mesh is called {key!r}")
        if not hits and warn:  # once per table
            self.warn(f"{self.side.path.name}: [objects.\"{key}\"]: no object, node or "
                      "mesh has that name")
        return hits

    def _check_material_names(self) -> None:
        for key in self.side.materials:
            if key not in self.materials.names and ("materials", key) in self.side.set_names:
                names = sorted(self.materials.names)
                known = ", ".join(repr(n) for n in names[:6]) + (", ..." if len(names) > 6 else "")
                raise GlintError(f"{self.side.set_names['materials', key]}: no material is called {key!r} "
                                 f"(the scene has {known})")
            if key not in self.materials.names:
                self.warn(f"{self.side.path.name}: [materials.\"{key}\"]: no material has "
                          "that name")


def _uses(tree, extension: str) -> int:
    """How many `extensions` tables of the glTF JSON name `extension` (materials, nodes, ...)."""
    if isinstance(tree, list):
        return sum(_uses(v, extension) for v in tree)
    if not isinstance(tree, dict):
        return 0
    here = isinstance(tree.get("extensions"), dict) and extension in tree["extensions"]
    return int(here) + sum(_uses(v, extension) for v in tree.values())
