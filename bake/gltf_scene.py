"""The glTF scene graph -> a Scene's objects, lights and cameras, in world space.

Reads the nodes of the scene shown (glTF 3.5: `scene`, else every root) and their transforms
(`matrix`, or translation, rotation and scale) into world matrices, one per path from a root; each
node's mesh primitives become Objects (bake/gltf_primitives.py), named after the node (else its
mesh); KHR_lights_punctual lights become point, spot and directional lights (along the node's -Z,
photometric units divided by 683 lm/W); perspective cameras become Cameras (eye the node's origin,
forward -Z, up +Y), followed by the sidecar's.
"""
from __future__ import annotations

from functools import partial

import numpy as np

from glint.bake.gltf_container import GltfDocument, numbers
from glint.bake.gltf_primitives import PrimitiveReader
from glint.bake.validate import add_warning
from glint.core.errors import GlintError, WarningKind
from glint.core.scene import Camera, DirectionalLight, PointLight, Scene, SpotLight

LUMENS_PER_WATT = 683.0  # luminous efficacy that defines the candela

# Warnings that repeat per object, light or camera: one summary line each (glint.core.errors.WarningKind).
SKINNED = WarningKind("{n} objects are skinned; skins are not supported, shown as stored "
                      "(the bind pose)")
MORPHED = WarningKind("{n} objects have morph target weights, not supported; shown without "
                      "their morph targets")
SPOT_CONES = WarningKind("{n} spot lights have cone angles outside 0 <= inner < outer <= pi/2; "
                         "clamped")
ORTHOGRAPHIC = WarningKind("{n} cameras are orthographic; only perspective cameras are "
                           "supported, skipped")
LIGHT_RANGE = WarningKind("{n} lights have a range, not supported; inverse-square falloff "
                          "everywhere")


def node_world_matrices(tree: dict, source: str = "glTF") -> dict[int, list[np.ndarray]]:
    """Node index -> world matrices (4x4, one per path from the scene's roots)."""
    nodes = tree.get("nodes", [])
    scenes = tree.get("scenes")
    if scenes:
        scene_index = tree.get("scene", 0)
        if not 0 <= scene_index < len(scenes):
            raise GlintError(f"{source}: malformed glTF: scene {scene_index} does not exist")
        roots = list(scenes[scene_index].get("nodes", []))
    else:  # no scenes: every node that is nobody's child is a root
        children = {c for n in nodes for c in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    out: dict[int, list[np.ndarray]] = {}

    def visit(index: int, parent: np.ndarray, path: tuple):
        if not isinstance(index, int) or not 0 <= index < len(nodes):
            raise GlintError(f"{source}: malformed glTF: node {index} does not exist")
        if index in path:
            raise GlintError(f"{source}: malformed glTF: node {index} is its own ancestor")
        world = parent @ local_matrix(nodes[index], f"{source}: node {index}")
        out.setdefault(index, []).append(world)
        for child in nodes[index].get("children", []):
            visit(child, world, path + (index,))

    for root in roots:
        visit(root, np.eye(4), ())
    return out


def local_matrix(node: dict, where: str = "node") -> np.ndarray:
    """A node's local 4x4 matrix: `matrix` (column-major) or T * R * S."""
    if "matrix" in node:
        m = np.asarray(node["matrix"], np.float64)
        if m.shape != (16,):
            raise GlintError(f"{where}: malformed glTF: matrix must have 16 numbers")
        return m.reshape(4, 4).T
    t = np.asarray(node.get("translation", [0, 0, 0]), np.float64)
    q = np.asarray(node.get("rotation", [0, 0, 0, 1]), np.float64)
    s = np.asarray(node.get("scale", [1, 1, 1]), np.float64)
    if t.shape != (3,) or q.shape != (4,) or s.shape != (3,):
        raise GlintError(f"{where}: malformed glTF: translation/rotation/scale have wrong length")
    m = np.eye(4)
    m[:3, :3] = quaternion_matrix(q) * s  # R @ diag(s)
    m[:3, 3] = t
    return m


def quaternion_matrix(q) -> np.ndarray:
    """Rotation matrix of a glTF (x, y, z, w) quaternion (normalised first).

    Not pyrr.matrix33.create_from_quaternion: equal within 1e-15, but different in the last bit
    for 92 % of random quaternions, which would change every baked vertex position's bytes."""
    q = np.asarray(q, np.float64)
    norm = np.linalg.norm(q)
    x, y, z, w = q / norm if norm > 0 else (0.0, 0.0, 0.0, 1.0)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


class SceneGraphReader:
    """The nodes of one glTF document: their objects, lights and cameras."""

    def __init__(self, doc: GltfDocument, side, primitives: PrimitiveReader, warnings: list[str]):
        self.doc, self.side, self.primitives = doc, side, primitives
        self.warn = partial(add_warning, warnings)

    def objects(self, scene: Scene, worlds) -> dict[str, tuple[str, str]]:
        """Fill scene.objects; return object name -> (node name, mesh name) for the sidecar."""
        aliases = {}
        for node_index, node, mesh in self._nodes_with("mesh", "meshes", worlds):
            node_name = node.get("name") or mesh.get("name") or f"node{node_index}"
            mesh_name = mesh.get("name") or f"mesh{node['mesh']}"
            if "skin" in node:
                self.warn(f"{self.doc.source}: object '{node_name}' is skinned; skins are not "
                          "supported, shown as stored (the bind pose)", SKINNED, node_name,
                          ignored=["skins"])
            weights = node.get("weights", mesh.get("weights", []))
            if any(w != 0 for w in weights) and any(p.get("targets") for p in mesh.get("primitives", [])):
                self.warn(f"{self.doc.source}: object '{node_name}' has morph target weights, not "
                          "supported; shown without its morph targets", MORPHED, node_name,
                          ignored=["morph targets"])
            for world in worlds[node_index]:
                for p, prim in enumerate(mesh.get("primitives", [])):
                    obj = self.primitives.read(scene, prim, world, node_name,
                                               f"mesh '{mesh_name}' primitive {p}")
                    if obj is not None:
                        scene.objects.append(obj)
                        aliases[obj.name] = (node_name, mesh_name)
        return aliases

    def _nodes_with(self, key: str, table: str, worlds):
        """(node index, node, the item of `table` it refers to by `key`) for each node in the scene
        (`worlds`: node index -> world matrices) that has `key`, in node order."""
        nodes = self.doc.table("nodes")
        for node_index in sorted(worlds):
            node = nodes[node_index]
            if key in node:
                yield node_index, node, self.doc.item(table, node[key], f"node {node_index}")

    def lights(self, scene: Scene, worlds) -> None:
        ext = self.doc.json.get("extensions", {}).get("KHR_lights_punctual", {})
        lights = ext.get("lights", [])
        scale = 1.0 / LUMENS_PER_WATT if self.side.units == "photometric" else 1.0
        nodes = self.doc.table("nodes")
        for node_index in sorted(worlds):
            ref = nodes[node_index].get("extensions", {}).get("KHR_lights_punctual")
            if ref is None:
                continue
            li = self.doc.index(ref.get("light"), len(lights), f"node {node_index}",
                             "KHR_lights_punctual light")
            light = lights[li]
            name = light.get("name") or nodes[node_index].get("name") or f"light{li}"
            where = f"{self.doc.source}: light '{name}'"
            if "range" in light:
                self.warn(f"{where}: range not supported; inverse-square falloff everywhere",
                          LIGHT_RANGE, name, ignored=["light range"])
            color = numbers(light.get("color", [1, 1, 1]), 3, f"{where} color", minimum=0.0)
            intensity = numbers([light.get("intensity", 1.0)], 1, f"{where} intensity",
                                minimum=0.0)
            power = (color * intensity * scale).astype(np.float32)
            kind = light.get("type")
            for world in worlds[node_index]:
                position = world[:3, 3].copy()
                if not np.all(np.isfinite(world)):
                    raise GlintError(f"{where}: its node transform is not finite")
                direction = _unit(world[:3, :3] @ [0.0, 0.0, -1.0])
                if kind == "point":
                    scene.point_lights.append(PointLight(position, power, name))
                elif kind == "spot":
                    spot = light.get("spot", {})
                    inner, outer = numbers([spot.get("innerConeAngle", 0.0),
                                            spot.get("outerConeAngle", np.pi / 4)], 2,
                                           f"{where} cone angles")
                    if not 0 <= inner < outer <= np.pi / 2:
                        self.warn(f"{self.doc.source}: spot light '{name}': cone angles "
                                  f"{inner}, {outer} need 0 <= inner < outer <= pi/2; clamped",
                                  SPOT_CONES, name)
                        outer = float(np.clip(outer, 1e-4, np.pi / 2))
                        inner = float(np.clip(inner, 0.0, outer * (1 - 1e-6)))
                    scene.spot_lights.append(SpotLight(position, direction, power, inner,
                                                       outer, name))
                elif kind == "directional":
                    scene.directional_lights.append(DirectionalLight(direction, power, name))
                else:
                    raise self.doc.bad(f"light '{name}' has unknown type {kind!r}")

    def cameras(self, scene: Scene, worlds) -> None:
        for node_index, node, cam in self._nodes_with("camera", "cameras", worlds):
            name = node.get("name") or cam.get("name") or f"camera{node['camera']}"
            if cam.get("type") != "perspective":
                self.warn(f"{self.doc.source}: camera '{name}' is {cam.get('type')}; only "
                          "perspective cameras are supported, skipped", ORTHOGRAPHIC, name,
                          ignored=[f"{cam.get('type')} cameras"])
                continue
            p = cam.get("perspective", {})
            where = f"{self.doc.source}: camera '{name}'"
            if "yfov" not in p:
                raise self.doc.bad(f"camera '{name}' has no yfov")
            yfov, znear = numbers([p["yfov"], p.get("znear", 0.01)], 2, f"{where} yfov/znear",
                                  minimum=1e-9)
            zfar = float(numbers([p.get("zfar", 1000.0)], 1, f"{where} zfar", minimum=znear)[0])
            aspect = p.get("aspectRatio")
            if aspect is not None:
                aspect = float(numbers([aspect], 1, f"{where} aspectRatio", minimum=1e-9)[0])
            for world in worlds[node_index]:
                if not np.all(np.isfinite(world)):
                    raise GlintError(f"{where}: its node transform is not finite")
                forward = _unit(world[:3, :3] @ [0.0, 0.0, -1.0])
                up = world[:3, :3] @ [0.0, 1.0, 0.0]
                up = _unit(up - forward * np.dot(up, forward))
                if abs(np.linalg.norm(forward) - 1) > 1e-6 or abs(np.linalg.norm(up) - 1) > 1e-6:
                    raise GlintError(f"{where}: its node transform is singular (zero scale)")
                scene.cameras.append(Camera(
                    name=self._camera_name(scene, name), eye=world[:3, 3].copy(),
                    forward=forward, up=up, yfov=float(yfov), aspect=aspect,
                    znear=float(znear), zfar=zfar))
        for cam in self.side.cameras:
            if any(c.name == cam.name for c in scene.cameras):
                self.warn(f"{self.side.path.name}: camera '{cam.name}' has the name of a "
                          "glTF camera; both are kept")
            scene.cameras.append(cam)

    @staticmethod
    def _camera_name(scene: Scene, name: str) -> str:
        taken = {c.name for c in scene.cameras}
        out, k = name, 0
        while out in taken:
            k += 1
            out = f"{name}.{k}"
        return out


def _unit(v) -> np.ndarray:
    v = np.asarray(v, np.float64)
    n = np.linalg.norm(v)
    return v / n if n > 0 else v
