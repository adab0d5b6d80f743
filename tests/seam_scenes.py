"""Test scenes built like real exports (issue 25): separately modelled meshes that touch or slightly
intersect, every material doubleSided (what Blender's glTF exporter writes with backface culling
off, its default), lit from outside through a window by a constant sky.

`write_interior`: a 2 x 2 x 2.2 m room (x, z in [-1, 1], y in [0, 2.2]) of single double-sided quads
(floor, ceiling, west, east and north walls; the north wall has a 1.2 x 1.1 m window opening), a
south wall 10 cm thick (a closed box from z = 1 to 1.1) over which the floor and the ceiling run to
its outer face, as modellers draw them; the sky lights the room through the window and every
outer face, so the thick wall has light on its outer side and only what the window lets in on
the room's side. In the room:

- a crown moulding along the west wall: a box 8 x 9 cm whose top stands 1 cm above the ceiling
  plane (it intersects the ceiling by 1 cm) and whose back touches the wall (coplanar faces);
- a skirting board along the east wall: a box 1.5 cm deep and 10 cm high, 1 mm off the wall, resting
  on the floor;
- a sofa-like box 0.8 x 0.45 x 0.45 m resting on the floor (its bottom face on the floor's plane).

`SEAMS` names, for each seam, the visible surface next to it, a strip of it within 10 cm of the
seam (as (object name, axis-aligned box)), and that surface's normal on the visible side.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from glint.scenes.generate import Mesh, add_mesh, box, merge, quad
from glint.scenes.gltf_writer import GltfWriter

X, Z, H = 1.0, 1.0, 2.2
THICK = 0.10  # the south wall's thickness
WINDOW_X, WINDOW_Y = (-0.6, 0.6), (0.8, 1.9)
MOULDING = 0.08, 0.09  # depth (x), height (y) of the moulding's cross-section
MOULDING_OVERLAP = 0.01  # how far the moulding's top stands above the ceiling plane
SKIRT_GAP, SKIRT_DEPTH, SKIRT_HEIGHT = 0.001, 0.015, 0.10
SOFA_MIN, SOFA_MAX = (-0.4, 0.0, 0.2), (0.4, 0.45, 0.65)
SKY = 1.0


def _north_wall() -> Mesh:
    """The north wall (z = -Z, facing +z) with a window opening, as a 3 x 3 grid of panels without the
    centre one (no T-junctions), a single quad thick."""
    xs = [-X, WINDOW_X[0], WINDOW_X[1], X]
    ys = [0.0, WINDOW_Y[0], WINDOW_Y[1], H]
    z = -Z
    return merge(*[quad((xs[i], ys[j], z), (xs[i + 1], ys[j], z), (xs[i + 1], ys[j + 1], z),
                        (xs[i], ys[j + 1], z), uv_size=(xs[i + 1] - xs[i], ys[j + 1] - ys[j]))
                   for j in range(3) for i in range(3) if (i, j) != (1, 1)])


def _box(lo, hi) -> Mesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return box(hi - lo, (lo + hi) / 2)


def interior_meshes(split_floor: bool = False) -> dict[str, Mesh]:
    """The room's meshes by name (world space, metres, Y up); `split_floor`: the floor as two meshes
    meeting at x = 0 ("Floor" west of it, "Floor east"), as a floor modelled in two pieces."""
    Zo = Z + THICK  # the south wall's outer face
    if split_floor:
        meshes = interior_meshes()
        meshes["Floor"] = quad((-X, 0, Zo), (0, 0, Zo), (0, 0, -Z), (-X, 0, -Z), uv_size=(X, Z + Zo))
        meshes["Floor east"] = quad((0, 0, Zo), (X, 0, Zo), (X, 0, -Z), (0, 0, -Z), uv_size=(X, Z + Zo))
        return meshes
    return {
        "Floor": quad((-X, 0, Zo), (X, 0, Zo), (X, 0, -Z), (-X, 0, -Z), uv_size=(2 * X, Z + Zo)),
        "Ceiling": quad((-X, H, -Z), (X, H, -Z), (X, H, Zo), (-X, H, Zo), uv_size=(2 * X, Z + Zo)),
        "Wall north": _north_wall(),
        "Wall west": quad((-X, 0, Z), (-X, 0, -Z), (-X, H, -Z), (-X, H, Z), uv_size=(2 * Z, H)),
        "Wall east": quad((X, 0, -Z), (X, 0, Z), (X, H, Z), (X, H, -Z), uv_size=(2 * Z, H)),
        "Wall south": _box((-X, 0.0, Z), (X, H, Zo)),
        "Moulding": _box((-X, H - MOULDING[1] + MOULDING_OVERLAP, -Z), (-X + MOULDING[0], H + MOULDING_OVERLAP, Z)),
        "Skirting": _box((X - SKIRT_GAP - SKIRT_DEPTH, 0.0, -Z), (X - SKIRT_GAP, SKIRT_HEIGHT, Z)),
        "Sofa": _box(SOFA_MIN, SOFA_MAX),
    }


def write_interior(path: Path, *, double_sided: bool = True, split_floor: bool = False) -> Path:
    """The scene as .glb with its sidecar (the sky); every material doubleSided unless told otherwise."""
    w = GltfWriter()
    paint = w.add_material("Paint", base_color=(0.8, 0.8, 0.8), roughness=1.0, double_sided=double_sided)
    wood = w.add_material("Wood", base_color=(0.5, 0.4, 0.3), roughness=1.0, double_sided=double_sided)
    fabric = w.add_material("Fabric", base_color=(0.4, 0.45, 0.5), roughness=1.0, double_sided=double_sided)
    material = {"Floor": wood, "Floor east": wood, "Sofa": fabric}
    for name, mesh in interior_meshes(split_floor).items():
        w.add_node(name, mesh=add_mesh(w, name, mesh, material.get(name, paint)))
    w.add_node("Camera", camera=w.add_camera("Camera", 1.2), translation=(0.0, 1.3, 0.9))
    path = Path(path)
    w.write(path)
    path.with_name(path.stem + ".glint.toml").write_text(f"[sky]\nradiance = {SKY}\n")
    return path


@dataclass(frozen=True)
class Strip:
    """Points of the visible surface `object` within 10 cm of a seam: the part of the object's surface
    inside the box [lo, hi], on the side facing `normal`; `along` is the axis that runs along the seam."""
    name: str
    object: str
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    normal: tuple[float, float, float]
    along: int


_M = H - MOULDING[1] + MOULDING_OVERLAP  # the moulding's underside
SEAMS = (
    # the ceiling next to the moulding, and the moulding's face next to the ceiling
    Strip("ceiling at moulding", "Ceiling", (-X + MOULDING[0], H, -0.9), (-X + MOULDING[0] + 0.1, H, 0.9), (0, -1, 0), 2),
    Strip("moulding at ceiling", "Moulding", (-X + MOULDING[0], H - 0.08, -0.9), (-X + MOULDING[0], H, 0.9),
          (1, 0, 0), 2),
    Strip("wall under moulding", "Wall west", (-X, _M - 0.1, -0.9), (-X, _M, 0.9), (1, 0, 0), 2),
    # the skirting board's face and top, the floor in front of it and the wall above it
    Strip("skirting face", "Skirting", (X - SKIRT_GAP - SKIRT_DEPTH, 0.0, -0.9),
          (X - SKIRT_GAP - SKIRT_DEPTH, SKIRT_HEIGHT, 0.9), (-1, 0, 0), 2),
    Strip("floor at skirting", "Floor", (X - SKIRT_GAP - SKIRT_DEPTH - 0.1, 0.0, -0.9),
          (X - SKIRT_GAP - SKIRT_DEPTH, 0.0, 0.9), (0, 1, 0), 2),
    Strip("wall over skirting", "Wall east", (X, SKIRT_HEIGHT, -0.9), (X, SKIRT_HEIGHT + 0.1, 0.9), (-1, 0, 0), 2),
    # the floor around the sofa and the sofa's sides at the floor
    Strip("floor before sofa", "Floor", (SOFA_MIN[0], 0.0, SOFA_MIN[2] - 0.1), (SOFA_MAX[0], 0.0, SOFA_MIN[2]),
          (0, 1, 0), 0),
    Strip("sofa front at floor", "Sofa", (SOFA_MIN[0], 0.0, SOFA_MIN[2]), (SOFA_MAX[0], 0.1, SOFA_MIN[2]), (0, 0, -1), 0),
    # the thick wall's room side next to the floor and the ceiling, and the floor and ceiling next to it
    Strip("floor at thick wall", "Floor", (-0.9, 0.0, Z - 0.1), (0.9, 0.0, Z), (0, 1, 0), 0),
    Strip("ceiling at thick wall", "Ceiling", (-0.9, H, Z - 0.1), (0.9, H, Z), (0, -1, 0), 0),
    Strip("thick wall at floor", "Wall south", (-0.9, 0.0, Z), (0.9, 0.1, Z), (0, 0, -1), 0),
    Strip("thick wall at ceiling", "Wall south", (-0.9, H - 0.1, Z), (0.9, H, Z), (0, 0, -1), 0),
)
# the thick wall's dark (room) side away from its borders
THICK_WALL_INTERIOR = Strip("thick wall interior", "Wall south", (-0.7, 0.3, Z), (0.7, 1.9, Z), (0, 0, -1), 0)


BLOCK = 0.25  # metres along a seam per block: 4 texels at the preview's 16 texels per metre
ALONG, ACROSS = 4, 3  # points per block along the seam and across the strip


def block_points(strip: Strip) -> tuple[np.ndarray, np.ndarray]:
    """(blocks, ALONG x ACROSS, 3) points on a strip, on a regular grid of BLOCK-long blocks centred
    along the seam, ACROSS rows across the strip (1/6, 1/2, 5/6 of its width); and the blocks' unit
    normal (3,). A flat strip (zero extent on one axis) has one axis along and one across."""
    lo, hi = np.asarray(strip.lo, float), np.asarray(strip.hi, float)
    flat = [a for a in range(3) if hi[a] - lo[a] < 1e-12]
    assert len(flat) == 1, strip
    across = ({0, 1, 2} - {flat[0], strip.along}).pop()
    length = hi[strip.along] - lo[strip.along]
    blocks = int(length // BLOCK)
    start = lo[strip.along] + 0.5 * (length - blocks * BLOCK)
    out = np.zeros((blocks, ALONG * ACROSS, 3))
    for b in range(blocks):
        k = 0
        for i in range(ALONG):
            for j in range(ACROSS):
                p = lo.copy()
                p[strip.along] = start + BLOCK * (b + (i + 0.5) / ALONG)
                p[across] = lo[across] + (hi[across] - lo[across]) * (2 * j + 1) / (2 * ACROSS)
                out[b, k] = p
                k += 1
    return out, np.asarray(strip.normal, float)
