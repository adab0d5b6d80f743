"""Stress scenes for `glint bench --stress`: glTF files at the edges of what glint takes.

    from glint.scenes import stress
    case = stress.materials(out_dir, spheres=9)       # -> StressScene(name, path, ...)
    cases = stress.build(out_dir, "reduced")           # every case at the CI machine's size

Each case is one small function writing NAME.glb (scenes/gltf_writer.py, as scenes/generate.py
writes the built-ins) and NAME.glint.toml (exact lobes, roles, cameras, a camera path, bake
settings) into a directory, with size parameters; `SIZES` holds the full size (the scale the
suite is meant to prove, e.g. 500 objects and 2 M triangles) and the reduced one the CI machine
affords. What each case states for its checks (the brightest emitter's radiance, an exact
expected radiance, a reference case to compare with) travels in `StressScene`; bench/stress.py
bakes, renders and checks them.

Cases:
    materials   spheres (curved: cube maps) and panels (planar: mirror passes) at the BSDF's
                extremes: roughness 1e-4 .. 1, anisotropy 1:100 both ways, alpha 0 .. 1, r0 0 .. 1,
                thin glass; cameras head-on, grazing (89.9 degrees off a panel's normal), behind
                one-sided panels and inside a sphere.
    emitters    a lamp of radiance 1e5 (above half float's 65504): light maps, cube maps and mirror
                buffers must hold it without Inf.
    furnace     a closed box whose walls all emit Le and reflect kd = 0.5 diffusely: the radiance is
                Le / (1 - kd) = 2 Le everywhere (the rendering equation's Neumann series).
    scale-*     the same room at 1 mm, 1 m and 10 km (geometry, cameras, clip planes and texel
                density scaled alike, radiance unchanged): scale-invariant, so the images must agree.
    degenerate  zero-area triangles, an object of only zero-area triangles, missing normals,
                zero-length normals, missing texture coordinates under a textured material.
    big         many objects and triangles (500 objects, 2 M triangles at full size).
    many        a room with N small boxes, each its own glTF node sharing one mesh per material
                (linked duplicates, as Blender exports them), a third of them rough metal (curved:
                cube maps), one case many-N per N: 10, 300, 1000 (reduced), and 3000, 10000 (full)
                (`many_objects`; MANY_COUNTS). Per-object costs show here: draw calls, culling,
                cube-map arrays past GL_MAX_ARRAY_TEXTURE_LAYERS; no pixel may be black.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from glint.scenes.generate import Mesh, box, checker_texture, merge, quad, uv_sphere
from glint.scenes.gltf_writer import GltfWriter

GENERATOR = "glint scenes/stress.py"
LAMP_RADIANCE = 12.0       # W/(m^2 sr): the ordinary ceiling lamp of the rooms
HOT_RADIANCE = 1e5         # the emitters case's lamp: above half float's largest value, 65504
FURNACE_KD, FURNACE_LE = 0.5, 1.0
FURNACE_SAMPLES = 256  # paths per texel: the light maps' noise (after denoising) stays below 1.5 % (draft's 32: 5.5 %)
SCALES = {"scale-1mm": 1e-3, "scale-1m": 1.0, "scale-10km": 1e4}
MANY_COUNTS = (10, 300, 1000, 3000, 10000)
MANY_FLOOR = 4.0  # m: the square the boxes stand on, whatever their count
MANY_TRIANGLES = 12_000  # all boxes together, at least 12 per box
MANY_BLACK_FRACTION = 0.001  # of the pixels: a few at box edges, never a whole object

# Per size: the parameters of each case (full: the scale the suite is meant to prove).
SIZES = {
    "reduced": {"materials": {"segments": 24, "cubemap_size": 32},
                "big": {"objects": 50, "triangles": 200_000},
                "scale": {"segments": 24},
                "many": {"counts": MANY_COUNTS[:3]}},
    "full": {"materials": {"segments": 64, "cubemap_size": None},
             "big": {"objects": 500, "triangles": 2_000_000},
             "scale": {"segments": 64},
             "many": {"counts": MANY_COUNTS}},
}

# BSDF extremes (section 3.3): (name, lobes). ks = 1 throughout.
def _lobe(kind="reflect", mx=0.1, my=None, r0=0.04, alpha=0.0) -> dict:
    return {"kind": kind, "ks": [1.0, 1.0, 1.0], "mx": mx, "my": mx if my is None else my, "r0": r0, "alpha": alpha}


EXTREMES = [
    ("mirror 1e-4", [_lobe(mx=1e-4, r0=1.0)]),
    ("rough 1", [_lobe(mx=1.0, r0=0.5)]),
    ("aniso 1:100", [_lobe(mx=0.002, my=0.2, r0=1.0)]),
    ("aniso 100:1", [_lobe(mx=0.3, my=0.003, r0=1.0, alpha=0.25)]),
    ("alpha 1", [_lobe(mx=0.05, r0=0.5, alpha=1.0)]),
    ("r0 0", [_lobe(mx=0.05, r0=0.0)]),
    ("r0 1 alpha 0.5", [_lobe(mx=0.02, r0=1.0, alpha=0.5)]),
    ("thin glass", [_lobe("transmit", mx=1e-4, r0=0.04), _lobe(mx=1e-4, r0=0.04)]),
    ("frosted glass", [_lobe("transmit", mx=0.3, my=0.01, r0=0.0, alpha=1.0), _lobe(mx=0.3, r0=0.04)]),
]


@dataclass
class StressScene:
    name: str
    path: Path                     # the .glb (its sidecar beside it)
    emitter_radiance: float        # the brightest emitter's radiance (or sky), W/(m^2 sr)
    expected_radiance: float | None = None   # exact radiance of every pixel, where the case has one
    compare_with: str | None = None           # a case whose images this one's must equal
    path_name: str | None = None              # the camera path of the walkthrough
    notes: list[str] = field(default_factory=list)
    max_black_fraction: float | None = None   # of the still images' pixels (0 radiance): objects gone black


# -- building blocks ----------------------------------------------------------------------------
def inward(mesh: Mesh) -> Mesh:
    """The same surface seen from inside: winding and normals flipped (a room from a box)."""
    return Mesh(mesh.positions, -mesh.normals, mesh.indices[:, ::-1].copy(), mesh.uvs, mesh.tangents)


def scaled(mesh: Mesh, s: float) -> Mesh:
    return Mesh(mesh.positions * s, mesh.normals, mesh.indices, mesh.uvs, mesh.tangents)


def add_mesh(w: GltfWriter, name: str, mesh: Mesh, material: int) -> int:
    """As scenes/generate.py's, without its rounding to 1e-6 m (a 1 mm room would lose its shape)."""
    return w.add_mesh(name, mesh.positions, mesh.indices, material, normals=mesh.normals, uvs=mesh.uvs,
                      tangents=mesh.tangents)


def _toml_vec(v) -> str:
    return "[" + ", ".join(f"{float(x):.9g}" for x in v) + "]"


def _lobes_toml(lobes: list[dict]) -> str:
    rows = []
    for lb in lobes:
        rows.append("{ " + ", ".join(f'{k} = "{v}"' if isinstance(v, str) else
                                     f"{k} = {_toml_vec(v) if isinstance(v, list) else f'{v:.9g}'}"
                                     for k, v in lb.items()) + " }")
    return "lobes = [\n  " + ",\n  ".join(rows) + ",\n]\n"


def _camera_toml(name: str, eye, target, yfov: float, znear: float, zfar: float, up=(0, 1, 0)) -> str:
    return (f"[cameras.{name}]\neye = {_toml_vec(eye)}\ntarget = {_toml_vec(target)}\nup = {_toml_vec(up)}\n"
            f"yfov = {yfov:g}\nznear = {znear:.9g}\nzfar = {zfar:.9g}\n\n")


def _path_toml(name: str, keys) -> str:
    rows = [f"  {{ time = {t:g}, eye = {_toml_vec(e)}, target = {_toml_vec(g)} }}" for t, e, g in keys]
    return f"[camera_paths.{name}]\nkeys = [\n" + ",\n".join(rows) + ",\n]\n\n"


def _write(w: GltfWriter, out_dir: Path, name: str, sidecar: str) -> Path:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = w.write(out_dir / f"{name}.glb")
    (out_dir / f"{name}.glint.toml").write_text(f"# {name}: written by scenes/stress.py\n\n" + sidecar)
    return path


def _room(w: GltfWriter, size=(6.0, 3.0, 6.0), s: float = 1.0, lamp: float = LAMP_RADIANCE) -> None:
    """A closed room (floor at y = 0, centred on x = z = 0) with a lamp in the ceiling, scaled by s."""
    X, H, Z = size
    walls = w.add_material("Walls", base_color=(0.6, 0.6, 0.6), roughness=1.0)
    lamp_m = w.add_material("Lamp", base_color=(0.8, 0.8, 0.8), emissive=(1, 1, 1), emissive_strength=lamp)
    w.add_node("Room", mesh=add_mesh(w, "Room", scaled(inward(box((X, H, Z), (0, H / 2, 0))), s), walls))
    light = quad((-0.6, 0, -0.4), (0.6, 0, -0.4), (0.6, 0, 0.4), (-0.6, 0, 0.4))  # faces down
    w.add_node("Lamp", mesh=add_mesh(w, "Lamp", scaled(light, s), lamp_m), translation=(0, (H - 0.01) * s, 0))


# -- the cases ----------------------------------------------------------------------------------
def materials(out_dir, segments: int = 24, cubemap_size: int | None = 32) -> StressScene:
    """Spheres and panels at the BSDF extremes, seen head-on, at grazing angles and from behind."""
    w = GltfWriter(GENERATOR)
    _room(w)
    side = ["[bake]\nquality = \"draft\"\n\n"]
    n = len(EXTREMES)
    for k, (name, lobes) in enumerate(EXTREMES):
        m = w.add_material(name, base_color=(0.2, 0.2, 0.2), roughness=0.5, double_sided=name.endswith("glass"))
        x = -2.4 + 4.8 * k / (n - 1)
        w.add_node(f"Sphere {name}", mesh=add_mesh(w, f"Sphere {name}", uv_sphere(0.22, segments, segments // 2), m),
                   translation=(x, 1.2, -1.5))
        # one-sided panels standing on the floor, facing +z (the head-on camera), and a floor strip
        panel = quad((-0.22, 0, 0), (0.22, 0, 0), (0.22, 0.6, 0), (-0.22, 0.6, 0))
        w.add_node(f"Panel {name}", mesh=add_mesh(w, f"Panel {name}", panel, m), translation=(x, 0.05, -0.4))
        strip = quad((-0.2, 0, 1.2), (0.2, 0, 1.2), (0.2, 0, 0.2), (-0.2, 0, 0.2))
        w.add_node(f"Strip {name}", mesh=add_mesh(w, f"Strip {name}", strip, m), translation=(x, 0.002, 0))
        side.append(f"[materials.\"{name}\"]\nkd = [0.1, 0.1, 0.1]\n" + _lobes_toml(lobes) + "\n")
        role = "transmissive" if name.endswith("glass") else "curved"
        side.append(f"[objects.\"Sphere {name}\"]\nrole = \"{role}\"\n"
                    + (f"cubemap_size = {cubemap_size}\n" if cubemap_size else "") + "\n")
        side.append(f"[objects.\"Strip {name}\"]\nrole = \"planar\"\n\n")
    cams = [("head_on", (0, 1.2, 2.5), (0, 1.0, -1.5), 70),
            # 89.9 degrees off the strips' normal: the eye 2 mm above them, looking along them
            ("grazing", (0, 0.002 + 1.2 * math.tan(math.radians(0.1)), 2.6), (0, 0.002, -1.5), 40),
            ("behind", (0, 0.4, -0.9), (0, 0.3, 2.5), 80),          # the panels' back faces
            ("inside", (-2.4, 1.2, -1.5), (2.4, 1.2, -1.5), 90)]    # inside the first sphere
    for name, eye, target, fov in cams:
        side.append(_camera_toml(name, eye, target, fov, 1e-4, 100.0))
    side.append(_path_toml("walk", [(0, (2.0, 1.5, 2.5), (0, 1.0, -1.5)), (4, (-2.0, 0.5, 1.0), (0, 0.5, -1.5)),
                                    (8, (0, 2.5, 0.5), (0, 0, -1.5)), (12, (2.0, 1.5, 2.5), (0, 1.0, -1.5))]))
    return StressScene("materials", _write(w, out_dir, "materials", "".join(side)), LAMP_RADIANCE, path_name="walk")


def emitters(out_dir, cubemap_size: int | None = 32) -> StressScene:
    """Lamps of radiance 1e5 (one close to a wall, one facing the room), a chrome sphere and a
    mirror floor panel."""
    w = GltfWriter(GENERATOR)
    _room(w, lamp=1.0)
    hot = w.add_material("Hot lamp", base_color=(0.8, 0.8, 0.8), emissive=(1, 1, 1), emissive_strength=HOT_RADIANCE)
    chrome = w.add_material("Chrome", base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=0.05)
    mirror = w.add_material("Mirror", base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=0.05)
    # 4 cm square, facing the north wall from 2 cm: its texels there see irradiance ~ pi 1e5 / 2
    lamp = quad((-0.02, -0.02, 0), (0.02, -0.02, 0), (0.02, 0.02, 0), (-0.02, 0.02, 0))
    w.add_node("Hot lamp", mesh=add_mesh(w, "Hot lamp", inward(lamp), hot), translation=(0, 1.5, -2.98))
    # and a 12 cm one facing the room: the cube map of the ball and the mirror pass see 1e5 directly
    w.add_node("Hot panel", mesh=add_mesh(w, "Hot panel", scaled(lamp, 3.0), hot), translation=(-0.5, 1.4, -2.9))
    w.add_node("Chrome ball", mesh=add_mesh(w, "Chrome ball", uv_sphere(0.3, 32, 16), chrome),
               translation=(0.6, 1.3, -2.2))
    w.add_node("Mirror panel", mesh=add_mesh(w, "Mirror panel", quad((-1, 0, 1), (1, 0, 1), (1, 0, -1), (-1, 0, -1)),
                                             mirror), translation=(0, 0.001, -1.5))
    side = ["[bake]\nquality = \"draft\"\n\n",
            "[materials.\"Chrome\"]\nkd = 0\n" + _lobes_toml([_lobe(mx=0.003, r0=0.95)]) + "\n",
            "[materials.\"Mirror\"]\nkd = 0\n" + _lobes_toml([_lobe(mx=1e-4, r0=1.0)]) + "\n",
            "[objects.\"Chrome ball\"]\nrole = \"curved\"\n" + (f"cubemap_size = {cubemap_size}\n" if cubemap_size else "")
            + "\n", "[objects.\"Mirror panel\"]\nrole = \"planar\"\n\n",
            _camera_toml("lamp", (0.3, 1.4, -1.0), (0, 1.5, -3.0), 60, 1e-3, 100.0),
            _camera_toml("mirror", (0, 1.0, 0.5), (0, 0.5, -3.0), 60, 1e-3, 100.0)]
    return StressScene("emitters", _write(w, out_dir, "emitters", "".join(side)), HOT_RADIANCE)


def furnace(out_dir) -> StressScene:
    """A closed box, every wall emitting Le with kd = FURNACE_KD: L = Le / (1 - kd) everywhere."""
    w = GltfWriter(GENERATOR)
    m = w.add_material("Furnace", base_color=(FURNACE_KD,) * 3, roughness=1.0, emissive=(1, 1, 1),
                       emissive_strength=FURNACE_LE)
    w.add_node("Box", mesh=add_mesh(w, "Box", inward(box((2, 2, 2), (0, 1, 0))), m))
    side = (f"[bake]\nquality = \"draft\"\nsamples = {FURNACE_SAMPLES}\nmax_depth = 64\n\n"
            f"[materials.\"Furnace\"]\nkd = {FURNACE_KD:g}\nemission = {FURNACE_LE:g}\n\n"
            + _camera_toml("inside", (0.3, 1.2, 0.6), (-0.5, 0.8, -1.0), 80, 1e-3, 10.0))
    return StressScene("furnace", _write(w, out_dir, "furnace", side), FURNACE_LE,
                       expected_radiance=FURNACE_LE / (1 - FURNACE_KD))


def scale_room(out_dir, name: str, s: float, segments: int = 24, texels_per_metre: float = 8.0) -> StressScene:
    """The same furnished room scaled by s: walls, a box, a chrome sphere (cube map), a glossy
    floor panel (mirror pass); cameras, clip planes and texel density scaled with it."""
    w = GltfWriter(GENERATOR)
    _room(w, size=(4.0, 2.5, 4.0), s=s)
    red = w.add_material("Red", base_color=(0.6, 0.1, 0.08), roughness=1.0)
    chrome = w.add_material("Chrome", base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=0.05)
    gloss = w.add_material("Gloss", base_color=(0.3, 0.3, 0.3), roughness=0.1)
    w.add_node("Box", mesh=add_mesh(w, "Box", scaled(box((0.8, 0.8, 0.8), (-0.8, 0.4, -0.8)), s), red))
    w.add_node("Ball", mesh=add_mesh(w, "Ball", scaled(uv_sphere(0.35, segments, segments // 2), s), chrome),
               translation=(0.8 * s, 0.35 * s, -0.6 * s))
    w.add_node("Panel", mesh=add_mesh(w, "Panel", scaled(quad((-1, 0, 1.6), (1, 0, 1.6), (1, 0, 0), (-1, 0, 0)), s),
                                      gloss), translation=(0, 0.002 * s, 0))
    eye, target = np.array([1.5, 1.6, 1.8]), np.array([-0.5, 0.5, -1.2])
    # 128 paths per texel: the rooms' light maps differ by their noise (float rounding sends the
    # paths elsewhere at each scale), which the comparison must not mistake for a scale effect
    side = (f"[bake]\nquality = \"draft\"\nsamples = 128\ntexels_per_metre = {texels_per_metre / s:.9g}\n\n"
            "[materials.\"Chrome\"]\nkd = 0\n" + _lobes_toml([_lobe(mx=0.01, r0=0.95)]) + "\n"
            "[materials.\"Gloss\"]\n" + _lobes_toml([_lobe(mx=0.02, r0=0.04)]) + "\n"
            "[objects.\"Ball\"]\nrole = \"curved\"\ncubemap_size = 32\n\n[objects.\"Panel\"]\nrole = \"planar\"\n\n"
            + _camera_toml("view", eye * s, target * s, 60, 0.01 * s, 100.0 * s)
            + _path_toml("walk", [(0, eye * s, target * s), (4, np.array([-1.5, 1.2, 1.5]) * s, np.array([0.8, 0.3, -1]) * s),
                                  (8, eye * s, target * s)]))
    return StressScene(name, _write(w, out_dir, name, side), LAMP_RADIANCE,
                       compare_with=None if name == "scale-1m" else "scale-1m", path_name="walk",
                       notes=[f"scale {s:g}"])


def degenerate(out_dir) -> StressScene:
    """Zero-area triangles, a zero-area object, missing and zero normals, a texture without UVs."""
    w = GltfWriter(GENERATOR)
    _room(w)
    plain = w.add_material("Plain", base_color=(0.5, 0.5, 0.5), roughness=1.0)
    textured = w.add_material("Textured", base_color=(1, 1, 1), roughness=1.0, base_color_texture=checker_texture(16))
    glossy = w.add_material("Glossy", base_color=(0.3, 0.3, 0.3), roughness=0.1)
    b = box((0.6, 0.6, 0.6), (0, 0.3, 0))
    p = b.positions
    # the box plus collinear and repeated-vertex triangles
    extra = np.array([[0, 0, 1], [3, 3, 3]])  # a repeated vertex, one point three times
    w.add_node("Slivers", mesh=w.add_mesh("Slivers", np.r_[p, [[0, 0, 0], [1, 0, 0], [2, 0, 0]]],
                                          np.r_[b.indices, extra, [[len(p), len(p) + 1, len(p) + 2]]], plain,
                                          normals=np.r_[b.normals, np.zeros((3, 3))]),
               translation=(-1.5, 0, -1))
    w.add_node("No normals", mesh=w.add_mesh("No normals", p, b.indices, plain), translation=(0, 0, -1))
    w.add_node("Zero normals", mesh=w.add_mesh("Zero normals", p, b.indices, glossy, normals=np.zeros_like(p)),
               translation=(1.5, 0, -1))
    w.add_node("No UVs", mesh=w.add_mesh("No UVs", p, b.indices, textured, normals=b.normals), translation=(0, 0, 1))
    w.add_node("Zero area", mesh=w.add_mesh("Zero area", np.zeros((3, 3)), [[0, 1, 2]], plain), translation=(1, 1, 1))
    s = uv_sphere(0.3, 16, 8)
    w.add_node("Sphere no UVs", mesh=w.add_mesh("Sphere no UVs", s.positions, s.indices, glossy, normals=s.normals),
               translation=(1.5, 1.0, 1))
    side = ("[bake]\nquality = \"draft\"\n\n[materials.\"Glossy\"]\n" + _lobes_toml([_lobe(mx=0.02, r0=0.5)]) + "\n"
            "[objects.\"Sphere no UVs\"]\nrole = \"curved\"\ncubemap_size = 32\n\n"
            + _camera_toml("view", (0, 1.8, 2.8), (0, 0.3, -0.5), 70, 0.01, 100.0))
    return StressScene("degenerate", _write(w, out_dir, "degenerate", side), LAMP_RADIANCE)


def big(out_dir, objects: int = 50, triangles: int = 200_000) -> StressScene:
    """`objects` spheres on a grid in a large room, `triangles` triangles in all (about)."""
    w = GltfWriter(GENERATOR)
    per = max(triangles // objects, 8)
    # a uv_sphere of s segments and s/2 rings has about s^2 - 2 s triangles
    seg = max(4, int(round(1 + math.sqrt(1 + per))))
    seg += seg % 2
    side_n = math.ceil(math.sqrt(objects))
    extent = 1.0 * side_n
    _room(w, size=(extent + 2, 3.0, extent + 2))
    mats = [w.add_material(f"Paint {k}", base_color=(0.2 + 0.15 * k, 0.5, 0.8 - 0.15 * k), roughness=1.0)
            for k in range(4)]
    mesh = uv_sphere(0.35, seg, seg // 2)
    for k in range(objects):
        i, j = divmod(k, side_n)
        m = mats[k % len(mats)]
        w.add_node(f"Ball {k}", mesh=add_mesh(w, f"Ball {k}", mesh, m),
                   translation=(-extent / 2 + 0.5 + j, 0.4, -extent / 2 + 0.5 + i))
    e = extent / 2 + 0.9
    side = ("[bake]\nquality = \"draft\"\ntexels_per_metre = 4\n\n"
            + _camera_toml("overview", (e, 2.6, e), (0, 0.3, 0), 70, 0.01, 1000.0))
    # The report's notes give the renderer's own object and triangle counts (the room included).
    return StressScene("big", _write(w, out_dir, "big", side), LAMP_RADIANCE)


def subdivided(mesh: Mesh, k: int) -> Mesh:
    """A box of `generate.box` (4 vertices per face) with each face cut into k x k quads."""
    faces = []
    t = np.linspace(0.0, 1.0, k + 1)
    for f in range(len(mesh.positions) // 4):
        p0, p1, _, p3 = mesh.positions[4 * f: 4 * f + 4]
        grid = p0 + t[:, None, None] * (p1 - p0) + t[None, :, None] * (p3 - p0)  # (k+1, k+1, 3): [i along p1, j along p3]
        ij = np.arange((k + 1) ** 2).reshape(k + 1, k + 1)
        a, b, c, d = ij[:-1, :-1], ij[1:, :-1], ij[1:, 1:], ij[:-1, 1:]
        tri = np.stack([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], 2).reshape(-1, 3)
        faces.append(Mesh(grid.reshape(-1, 3), np.tile(mesh.normals[4 * f], ((k + 1) ** 2, 1)), tri))
    return merge(*faces)


def many_objects(out_dir, objects: int = 1000, metal_every: int | None = 3, name: str | None = None,
                 triangles: int = MANY_TRIANGLES) -> StressScene:
    """`objects` boxes on a grid over a MANY_FLOOR square, each its own node; box size shrinks with
    the count so that they cover about the same part of the frame at any count, and each box's
    faces are subdivided so that all boxes together have about `triangles` triangles (at least 12
    per box): the frame's raster work stays alike and the per-object costs show. Every
    `metal_every`-th box is rough metal (None: all diffuse). Two meshes in the file, whatever the
    count: the nodes share them."""
    w = GltfWriter(GENERATOR)
    _room(w)
    side_n = math.ceil(math.sqrt(objects))
    pitch = MANY_FLOOR / side_n
    s = 0.5 * pitch
    paint = w.add_material("Paint", base_color=(0.7, 0.35, 0.2), roughness=1.0)
    metal = w.add_material("Metal", base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=0.3)
    cuts = max(1, round(math.sqrt(triangles / (12 * objects))))
    shape = subdivided(box((s, s, s), (0, s / 2, 0)), cuts)
    meshes = {m: add_mesh(w, f"Box {k}", shape, m) for k, m in enumerate((paint, metal))}
    for k in range(objects):
        i, j = divmod(k, side_n)
        m = metal if metal_every and k % metal_every == metal_every - 1 else paint
        w.add_node(f"Box {k}", mesh=meshes[m],
                   translation=(-MANY_FLOOR / 2 + pitch * (j + 0.5), 0.0, -MANY_FLOOR / 2 + pitch * (i + 0.5)))
    name = name or f"many-{objects}"
    # 8 texels per metre: the light maps stay small at 10,000 boxes; the boxes' faces get a texel or so
    side = ("[bake]\nquality = \"draft\"\ntexels_per_metre = 8\n\n"
            + _camera_toml("view", (0.0, 2.2, 2.8), (0.0, 0.1, -0.6), 60, 0.01, 100.0))
    # Every surface in view is lit (the lamp faces the floor; a box's bottom lies on it, unseen):
    # a black pixel is an object drawn without its light or its cube map.
    return StressScene(name, _write(w, out_dir, name, side), LAMP_RADIANCE, notes=[f"{objects} boxes"],
                       max_black_fraction=MANY_BLACK_FRACTION)


CASES = ("materials", "emitters", "furnace", "scale-1mm", "scale-1m", "scale-10km", "degenerate", "big", "many")


def build(out_dir, size: str = "reduced", cases=CASES) -> list[StressScene]:
    """Write the chosen cases at `size` ("reduced" or "full") into out_dir."""
    p = SIZES[size]
    made = []
    for name in cases:
        if name == "materials":
            made.append(materials(out_dir, **p["materials"]))
        elif name == "emitters":
            made.append(emitters(out_dir, cubemap_size=p["materials"]["cubemap_size"]))
        elif name == "furnace":
            made.append(furnace(out_dir))
        elif name in SCALES:
            made.append(scale_room(out_dir, name, SCALES[name], **p["scale"]))
        elif name == "degenerate":
            made.append(degenerate(out_dir))
        elif name == "big":
            made.append(big(out_dir, **p["big"]))
        elif name == "many":
            made += [many_objects(out_dir, n) for n in p["many"]["counts"]]
        else:
            raise ValueError(f"unknown stress case {name!r}")
    return made
