"""Measures the bias of the bake's path regularisation (bake/scatter.py M_REGULARISE) on a room with a
near-mirror metal floor: the room's mean irradiance and its largest point for several minimum widths.

    python -m glint.bench.measure_regularisation [--m 1e-4] [--samples 1024]

The room: 2 x 2 x 2 m, grey walls and ceiling, a metal floor (glTF metallicFactor 1, roughnessFactor
sqrt(m)), lit by a 1.2 x 1.2 m lamp under the ceiling or by a point light (`write_metal_floor_room`,
also the scene of tests/test_bake_glossy_transport.py). The points: a 10 x 10 grid on each wall and
on the ceiling (500), facing into the room.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from glint.scenes.gltf_writer import GltfWriter, room_faces

WIDTHS = (1e-4, 0.005, 0.02, 0.05)


def write_metal_floor_room(path: Path, m: float = 0.05, light: str = "lamp") -> Path:
    """The room with a metal floor of Beckmann m (kd 0, ks = base colour 0.9, r0 1); `light` "lamp": a
    1.2 x 1.2 m lamp of radiance 1.5 facing down under the ceiling (large: its caustic off the floor
    is smooth enough for a few thousand samples per point), "point": a point light of 2 W/sr at
    (0, 1.8, 0)."""
    w = GltfWriter()
    wall = w.add_material("Wall", base_color=(0.7, 0.6, 0.5), roughness=1.0)
    floor = w.add_material("Floor", base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=math.sqrt(m))
    faces = room_faces(1.0, 2.0, wall, floor)
    if light == "lamp":
        lamp = w.add_material("Lamp", base_color=(0.0, 0.0, 0.0), emissive=(1, 1, 1), emissive_strength=1.5)
        faces["Lamp"] = ((0, 1.99, 0), (0.6, 0, 0), (0, 0, 0.6), lamp)
    w.add_quads(faces, normals=True)
    if light == "point":  # KHR_lights_punctual candela; the loader's default units: W/sr = cd / 683
        w.add_node("Point", light=w.add_light("Point", "point", intensity=2.0 * 683), translation=(0, 1.8, 0))
    w.write(path)
    return path


def room_points(per_side: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """A per_side x per_side grid on each wall and on the ceiling, inward normals."""
    g = np.linspace(-0.9, 0.9, per_side)
    ys = np.linspace(0.1, 1.9, per_side)
    points, normals = [], []
    for axis, sign in ((0, -1), (0, 1), (2, -1), (2, 1)):
        for s in g:
            for y in ys:
                p, n = np.zeros(3), np.zeros(3)
                p[axis], p[2 - axis], p[1] = sign, s, y
                n[axis] = -sign
                points.append(p)
                normals.append(n)
    for x in g:
        for z in g:
            points.append([x, 2.0, z])
            normals.append([0.0, -1.0, 0.0])
    return np.array(points, float), np.array(normals, float)


def main() -> None:
    import tempfile

    import glint.bake.scatter as scatter
    from glint.bake.gltf_loader import load_scene
    from glint.bake.irradiance import compute_irradiance
    from glint.bake.raytrace import RayTracer

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--m", type=float, default=1e-4)
    ap.add_argument("--samples", type=int, default=1024)
    args = ap.parse_args()
    points, normals = room_points()
    with tempfile.TemporaryDirectory() as tmp:
        for light in ("lamp", "point"):
            scene = load_scene(write_metal_floor_room(Path(tmp) / f"{light}.glb", args.m, light))
            for width in WIDTHS:
                scatter.M_REGULARISE = width  # read when the bake's lobe table is built (one per tracer)
                E = compute_irradiance(scene, RayTracer(scene), points, normals, args.samples, seed=3).irradiance
                E = E.mean(axis=1)
                print(f"{light}, floor m {args.m:g}, M_REGULARISE {width:g}: mean E {E.mean():.4f} W/m^2, "
                      f"largest point {E.max():.3f}", flush=True)


if __name__ == "__main__":
    main()
