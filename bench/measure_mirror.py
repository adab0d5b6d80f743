"""GPU time of the planar reflectors' mirror passes: mirror passes, MIP build and the whole
frame with 1, 2 and 4 reflectors in view and one pass each, against no passes at all.

    python3 -m glint.bench.measure_mirror [--size 640x360] [--frames 10] [--out DIR]

Scene "mirror-4" (built here with scenes/gltf_writer.py, baked at --quality preview into DIR):
a 6 x 3 x 6 m room lit by a ceiling panel and the sky through nothing -- a closed room --
with four glossy planar reflectors on four planes, all in view of its camera: a polished
floor (m = 0.06), a lacquered table top (m = 0.03), a mirror panel on the back wall (m = 0.005)
and a glossy panel on the left wall (m = 0.1); plus a few diffuse boxes to reflect.
N reflectors = the mirror-pass budget N (the planner keeps the N largest on screen; the
others show their diffuse part), so the scene and the view stay the same. Also the built-in
living-room (floor and table top: 2 reflectors) from its first camera.

Printed: the median over --frames frames (after two warm-up frames) of the renderer's
per-pass GPU times (viewer/timing.py: timer queries on a GPU, glFinish-bracketed wall clock on
llvmpipe), supersample 1.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.core.atomic import atomic_write_text
from glint.core.bake_dir import Bake
from glint.scenes import resolve
from glint.scenes.gltf_writer import GltfWriter, quad, room_faces
from glint.services import bake_scene
from glint.viewer.camera import ViewCamera
from glint.viewer.context import headless_context
from glint.viewer.renderer import Renderer


def box(w, name, lo, hi, material):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c, h = (lo + hi) / 2, (hi - lo) / 2
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = np.zeros(3)
            n[axis] = sign
            a, b = np.eye(3)[(axis + 1) % 3] * h[(axis + 1) % 3], np.eye(3)[(axis + 2) % 3] * h[(axis + 2) % 3]
            u, v = (a, b) if sign > 0 else (b, a)
            p, i = quad(c + n * h, u, v)
            w.add_node(f"{name} {axis}{'+' if sign > 0 else '-'}",
                       mesh=w.add_mesh(f"{name} {axis}{sign}", p, i, material, normals=np.tile(n, (4, 1))))


def write_mirror4(path: Path) -> Path:
    w = GltfWriter()

    def lobe(m, r0=0.04):
        return {"glint": {"lobes": [{"kind": "reflect", "ks": [1, 1, 1], "mx": m, "my": m, "r0": r0, "alpha": 0.0}]}}

    wall = w.add_material("Wall", base_color=(0.7, 0.7, 0.65), roughness=1.0)
    mats = {"Floor": w.add_material("Floor", base_color=(0.35, 0.22, 0.12), roughness=1.0, extras=lobe(0.06)),
            "Table top": w.add_material("Table top", base_color=(0.1, 0.06, 0.04), roughness=1.0,
                                        extras=lobe(0.03, 0.05)),
            "Mirror": w.add_material("Mirror", base_color=(0.02, 0.02, 0.02), roughness=1.0,
                                     extras=lobe(0.005, 0.9)),
            "Panel": w.add_material("Panel", base_color=(0.2, 0.3, 0.5), roughness=1.0, extras=lobe(0.1))}
    lamp = w.add_material("Lamp", base_color=(0.8, 0.8, 0.8), emissive=(1, 1, 1), emissive_strength=15.0)
    red = w.add_material("Red", base_color=(0.7, 0.1, 0.1), roughness=1.0)
    faces = {  # name: (centre, u, v, material); front faces inwards
        **room_faces(3.0, 3.0, wall, mats["Floor"]),
        "Lamp": ((0, 2.99, 0), (0.5, 0, 0), (0, 0, 0.5), lamp),
        "Mirror": ((0.5, 1.4, -2.99), (0.9, 0, 0), (0, 0.7, 0), mats["Mirror"]),
        "Panel": ((-2.99, 1.3, -0.5), (0, 0, -1.0), (0, 0.8, 0), mats["Panel"]),
        "Table top": ((0.4, 0.75, -1.0), (0.6, 0, 0), (0, 0, -0.4), mats["Table top"]),
    }
    w.add_quads(faces, normals=True)
    box(w, "Cabinet", (1.6, 0, -2.6), (2.6, 1.2, -2.0), red)
    box(w, "Table base", (0.2, 0, -1.2), (0.6, 0.74, -0.8), wall)
    box(w, "Crate", (-1.8, 0, -1.8), (-1.0, 0.6, -1.0), red)
    w.add_node("Camera", camera=w.add_camera("Camera", math.radians(60)), translation=(1.8, 1.6, 2.5),
               rotation=_look_rotation((1.8, 1.6, 2.5), (-0.6, 0.8, -1.5)))
    w.write(path)
    atomic_write_text(path.with_name(path.stem + ".glint.toml"),
                      '[objects."Table top"]\nrole = "planar"\n[objects."Mirror"]\nrole = "planar"\n'
                      '[objects."Panel"]\nrole = "planar"\n')
    return path


def _look_rotation(eye, target):
    """xyzw quaternion turning -Z towards target (Y up)."""
    f = np.subtract(target, eye) / np.linalg.norm(np.subtract(target, eye))
    r = np.cross(f, (0, 1, 0))
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    m = np.stack([r, u, -f], axis=1)  # columns: the node's x, y, z axes
    t = np.trace(m)
    qw = math.sqrt(max(0.0, 1 + t)) / 2
    qx = math.copysign(math.sqrt(max(0.0, 1 + m[0, 0] - m[1, 1] - m[2, 2])) / 2, m[2, 1] - m[1, 2])
    qy = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] + m[1, 1] - m[2, 2])) / 2, m[0, 2] - m[2, 0])
    qz = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] - m[1, 1] + m[2, 2])) / 2, m[1, 0] - m[0, 1])
    return (qx, qy, qz, qw)


def bake(scene_file: Path, out: Path):
    scene = load_scene(scene_file)
    bake_scene(scene, resolve_settings(scene.bake_settings, quality="preview"), out, progress=False)
    return Bake(out)


def measure(bake_obj, budgets, size, frames):
    ctx = headless_context()
    camera = ViewCamera.from_manifest(bake_obj.model.cameras[0])
    rows = []
    for budget in budgets:
        r = Renderer(ctx, bake_obj, mirror_budget=budget)
        for _ in range(2):
            r.render(camera, *size)
        r.timer.reset()
        for _ in range(frames):
            r.render(camera, *size)
        s = r.stats
        ms = s["gpu_ms_median"]
        rows.append((budget, s["mirror"]["passes_run"], ms.get("mirror_passes", 0.0), ms.get("mirror_mips", 0.0),
                     ms.get("occlusion_queries", 0.0), ms.get("specular", 0.0), ms["total"],
                     s["specular"]["mirror_buffer_lookups"], s["device"]))
        r.release()
    ctx.release()
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--out", type=Path, default=Path("/tmp/glint-measure-mirror"))
    args = ap.parse_args()
    size = tuple(int(x) for x in args.size.lower().split("x"))
    args.out.mkdir(parents=True, exist_ok=True)
    scenes = [("mirror-4", bake(write_mirror4(args.out / "mirror-4.glb"), args.out / "mirror-4.bake"), (0, 1, 2, 4))]
    living = bake(Path(resolve("living-room")), args.out / "living-room.bake")
    scenes.append(("living-room", living, (0, 1, 4)))
    print(f"{size[0]}x{size[1]}, supersample 1, median of {args.frames} frames")
    print("scene        budget passes  mirror_passes  mirror_mips  occlusion  specular   frame total  mirror look-ups")
    device = None
    for name, b, budgets in scenes:
        for budget, passes, mp, mm, oq, sp, total, lookups, device in measure(b, budgets, size, args.frames):
            print(f"{name:12s} {budget:6d} {passes:6d} {mp:12.2f} {mm:12.2f} {oq:10.2f} {sp:9.2f} {total:13.2f} "
                  f"{lookups:16d}")
    print("device:", device)


if __name__ == "__main__":
    main()
