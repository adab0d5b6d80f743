"""Generate the built-in scenes: `python3 -m glint.scenes.generate [OUTDIR]` (default: this package).

Writes cornell-box.glb, living-room.glb, material-classes.glb, planar-classes.glb,
metal-floor-room.glb and glossy-floor-room.glb. Their
sidecars (NAME.glint.toml beside them: exact lobes, roles, sky, camera paths) are written by hand. The output
is deterministic (vertex data rounded to 1e-6 before it becomes float32, PNGs
stored uncompressed), and tests/test_scenes.py checks that the committed files
are exactly what this script writes.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from glint.scenes import teapot
from glint.scenes.gltf_writer import GltfWriter

HERE = Path(__file__).resolve().parent
GENERATOR = "glint scenes/generate.py"


# -- mesh building ---------------------------------------------------------------------------
@dataclass
class Mesh:
    positions: np.ndarray  # (N, 3)
    normals: np.ndarray  # (N, 3)
    indices: np.ndarray  # (M, 3), counter-clockwise seen from the side the normals face
    uvs: np.ndarray | None = None  # (N, 2), glTF convention (v down the image)
    tangents: np.ndarray | None = None  # (N, 4)

    def transformed(self, matrix: np.ndarray) -> "Mesh":
        """Bake a 4x4 transform into the vertices (normals by the inverse transpose)."""
        m = np.asarray(matrix, float)
        p = self.positions @ m[:3, :3].T + m[:3, 3]
        n = self.normals @ np.linalg.inv(m[:3, :3])
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        t = None
        if self.tangents is not None:
            t3 = self.tangents[:, :3] @ m[:3, :3].T
            t = np.c_[t3 / np.linalg.norm(t3, axis=1, keepdims=True), self.tangents[:, 3]]
        idx = self.indices if np.linalg.det(m[:3, :3]) > 0 else self.indices[:, ::-1]
        return Mesh(p, n, idx, self.uvs, t)


def merge(*meshes: Mesh) -> Mesh:
    offsets = np.cumsum([0] + [len(m.positions) for m in meshes[:-1]])
    uvs = None
    if all(m.uvs is not None for m in meshes):
        uvs = np.concatenate([m.uvs for m in meshes])
    tangents = None
    if all(m.tangents is not None for m in meshes):
        tangents = np.concatenate([m.tangents for m in meshes])
    return Mesh(np.concatenate([m.positions for m in meshes]),
                np.concatenate([m.normals for m in meshes]),
                np.concatenate([m.indices + o for m, o in zip(meshes, offsets)]), uvs, tangents)


def quad(p0, p1, p2, p3, uv_size=(1.0, 1.0)) -> Mesh:
    """Planar quad with corners counter-clockwise seen from its front."""
    p = np.array([p0, p1, p2, p3], float)
    n = np.cross(p[1] - p[0], p[3] - p[0])
    n /= np.linalg.norm(n)
    u, v = uv_size
    uvs = np.array([[0, v], [u, v], [u, 0], [0, 0]], float)  # v runs down the image
    return Mesh(p, np.tile(n, (4, 1)), np.array([[0, 1, 2], [0, 2, 3]]), uvs)


def box(size, centre=(0.0, 0.0, 0.0), uv_scale: float | None = None) -> Mesh:
    """Axis-aligned closed box, 4 vertices per face (hard edges), outward normals.

    uv_scale: texture repeats per metre (None: each face gets the unit square).
    """
    h = np.asarray(size, float) / 2
    c = np.asarray(centre, float)
    faces = []
    # (normal axis, sign): corners counter-clockwise seen from outside
    for axis in range(3):
        for sign in (1.0, -1.0):
            a, b = (axis + 1) % 3, (axis + 2) % 3
            if sign < 0:
                a, b = b, a
            corners = []
            for da, db in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = np.zeros(3)
                p[axis] = sign * h[axis]
                p[a] = da * h[a]
                p[b] = db * h[b]
                corners.append(p + c)
            size_uv = (1.0, 1.0) if uv_scale is None else (2 * h[a] * uv_scale, 2 * h[b] * uv_scale)
            faces.append(quad(*corners, uv_size=size_uv))
    return merge(*faces)


def disc(radius: float, segments: int, y: float = 0.0, facing_up: bool = True) -> Mesh:
    """Flat disc in the plane y, as a fan around its centre."""
    t = 2 * np.pi * np.arange(segments) / segments
    ring = np.c_[radius * np.cos(t), np.full(segments, y), radius * np.sin(t)]
    p = np.vstack([[0.0, y, 0.0], ring])
    i = np.arange(segments)
    idx = np.c_[np.zeros(segments, int), 1 + (i + 1) % segments, 1 + i]  # CCW seen from +y
    n = np.tile([0.0, 1.0, 0.0], (len(p), 1))
    if not facing_up:
        idx, n = idx[:, ::-1], -n
    uvs = 0.5 + 0.5 * np.c_[p[:, 0], p[:, 2]] / radius
    return Mesh(p, n, idx, uvs)


def lathe(profile, segments: int) -> Mesh:
    """Surface of revolution about +Y of a 2D polyline [(r, y), ...].

    Walking along the profile, the outside is on the right (r, y) -> normal
    (dy, -dr): a profile that runs up the outside of a solid gets outward normals.
    UVs: u = angle / 2 pi, v = arc length fraction; tangents run around the axis.
    """
    prof = np.asarray(profile, float)
    d = np.diff(prof, axis=0)
    seg_n = np.c_[d[:, 1], -d[:, 0]]
    seg_n /= np.linalg.norm(seg_n, axis=1, keepdims=True)
    # Smooth normals along the profile (a hard edge is two separate profiles).
    n2 = np.vstack([seg_n[:1], seg_n[:-1] + seg_n[1:], seg_n[-1:]])
    n2 /= np.linalg.norm(n2, axis=1, keepdims=True)
    arc = np.r_[0, np.cumsum(np.linalg.norm(d, axis=1))]
    t = 2 * np.pi * np.arange(segments + 1) / segments  # duplicate seam column for UVs
    c, s = np.cos(t)[None, :], -np.sin(t)[None, :]  # angle grows counter-clockwise seen from +y
    r, y = prof[:, :1], prof[:, 1:]
    rows, cols = len(prof), len(t)
    ones = np.ones((rows, cols))
    p = np.stack([r * c, y * ones, r * s], -1)
    n = np.stack([n2[:, :1] * c, n2[:, 1:] * ones, n2[:, :1] * s], -1)
    tan = np.stack([s * ones, 0 * ones, -c * ones], -1)  # d p / d angle, normalised
    uvs = np.stack([ones * t / (2 * np.pi), ones * (arc / arc[-1])[:, None]], -1)
    # glTF bitangent = cross(normal, tangent) * w; make it follow +v (along the profile).
    dp_dv = np.c_[d[:, 0], d[:, 1]]
    dp_dv = np.vstack([dp_dv, dp_dv[-1:]])
    along = np.stack([dp_dv[:, :1] * c, dp_dv[:, 1:] * ones, dp_dv[:, :1] * s], -1)
    w = np.where((np.cross(n, tan) * along).sum(-1) >= 0, 1.0, -1.0)
    g = np.arange(rows * cols).reshape(rows, cols)
    a, b, cc, dd = g[:-1, :-1], g[:-1, 1:], g[1:, 1:], g[1:, :-1]
    idx = np.concatenate([np.stack([a, b, cc], -1).reshape(-1, 3),
                          np.stack([a, cc, dd], -1).reshape(-1, 3)])
    mesh = Mesh(p.reshape(-1, 3), n.reshape(-1, 3), idx, uvs.reshape(-1, 2),
                np.c_[tan.reshape(-1, 3), w.reshape(-1)])
    return orient(drop_degenerate(mesh))


def uv_sphere(radius: float, segments: int, rings: int) -> Mesh:
    phi = np.linspace(0, np.pi, rings + 1)  # from the south pole up
    return lathe(np.c_[radius * np.sin(phi), -radius * np.cos(phi)], segments)


def cylinder(radius: float, height: float, segments: int, caps=True) -> Mesh:
    """Cylinder standing on y = 0 with hard edges at the caps."""
    parts = [lathe([(radius, 0.0), (radius, height)], segments)]
    if caps:
        for cap in (disc(radius, segments, 0.0, facing_up=False), disc(radius, segments, height)):
            # caps brushed around the axis too: tangent = d/d(angle)
            tan = np.c_[-cap.positions[:, 2], np.zeros(len(cap.positions)), cap.positions[:, 0]]
            tan[0] = (1, 0, 0)
            tan /= np.linalg.norm(tan, axis=1, keepdims=True)
            cap.tangents = np.c_[tan, np.ones(len(tan))]
            parts.append(cap)
    return merge(*parts)


def drop_degenerate(mesh: Mesh) -> Mesh:
    """Remove zero-area triangles (poles of a lathe) and unused vertices."""
    p = mesh.positions[mesh.indices]
    area = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    idx = mesh.indices[area > 1e-12]
    used = np.unique(idx)
    remap = np.full(len(mesh.positions), -1)
    remap[used] = np.arange(len(used))
    pick = lambda a: None if a is None else a[used]  # noqa: E731
    return Mesh(mesh.positions[used], mesh.normals[used], remap[idx], pick(mesh.uvs),
                pick(mesh.tangents))


def orient(mesh: Mesh) -> Mesh:
    """Wind every triangle counter-clockwise around the side its vertex normals face."""
    p = mesh.positions[mesh.indices]
    fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    flip = (fn * mesh.normals[mesh.indices].sum(axis=1)).sum(axis=1) < 0
    idx = mesh.indices.copy()
    idx[flip] = idx[flip][:, ::-1]
    return Mesh(mesh.positions, mesh.normals, idx, mesh.uvs, mesh.tangents)


# -- transforms ------------------------------------------------------------------------------
def rotation(axis, degrees: float) -> np.ndarray:
    """3x3 right-handed rotation (Rodrigues), as Mitsuba's Transform4f.rotate builds it."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    th = math.radians(degrees)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(th) * k + (1 - math.cos(th)) * (k @ k)


def trs(translate=(0, 0, 0), rotate=None, scale=(1, 1, 1)) -> np.ndarray:
    """translate @ rotate(axis, degrees) @ scale, as Mitsuba composes them."""
    m = np.eye(4)
    r = np.eye(3) if rotate is None else rotation(*rotate)
    m[:3, :3] = r @ np.diag(np.broadcast_to(np.asarray(scale, float), (3,)))
    m[:3, 3] = translate
    return m


def quat_y(degrees: float) -> tuple[float, float, float, float]:
    """xyzw quaternion for a rotation about +Y."""
    h = math.radians(degrees) / 2
    return (0.0, round(math.sin(h), 9), 0.0, round(math.cos(h), 9))


def quat_from_matrix(r: np.ndarray) -> tuple[float, float, float, float]:
    """xyzw unit quaternion of a 3x3 rotation (Shepperd's method, w >= 0)."""
    tr = np.trace(r)
    if tr > 0:
        s = 2 * math.sqrt(1 + tr)
        q = ((r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, s / 4)
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2 * math.sqrt(1 + r[i, i] - r[j, j] - r[k, k])
        q = [0.0, 0.0, 0.0, (r[k, j] - r[j, k]) / s]
        q[i] = s / 4
        q[j] = (r[j, i] + r[i, j]) / s
        q[k] = (r[k, i] + r[i, k]) / s
        if q[3] < 0:
            q = [-x for x in q]
    return tuple(round(float(x), 9) for x in q)


def look_at_quat(eye, target, up=(0, 1, 0)):
    """Rotation of a glTF camera/light node (looks along its -Z, +Y up) at `target`."""
    f = np.asarray(target, float) - np.asarray(eye, float)
    f /= np.linalg.norm(f)
    right = np.cross(f, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, f)
    return quat_from_matrix(np.stack([right, true_up, -f], axis=1))


def add_mesh(w: GltfWriter, name: str, mesh: Mesh, material: int) -> int:
    """Round to 1e-6 first so float32 conversion gives the same bytes on any machine."""
    r = lambda a: None if a is None else np.round(a, 6)  # noqa: E731
    return w.add_mesh(name, r(mesh.positions), mesh.indices, material, normals=r(mesh.normals),
                      uvs=r(mesh.uvs), tangents=r(mesh.tangents))


# -- cornell-box -----------------------------------------------------------------------------
# Transcribed from Mitsuba 3's mitsuba.cornell_box() (mitsuba/python/util.py, v3.9):
# rectangles are [-1,1]^2 in their local xy plane facing +z, cubes are [-1,1]^3;
# to_world is translate @ rotate(axis, degrees) @ scale.
CORNELL_REFLECTANCE = {
    "white": (0.885809, 0.698859, 0.666422),
    "green": (0.105421, 0.37798, 0.076425),
    "red": (0.570068, 0.0430135, 0.0443706),
}
CORNELL_RADIANCE = (18.387, 13.9873, 6.75357)  # the light's area emitter, W/(m^2 sr)
CORNELL_SHAPES = [  # (name, type, material, to_world)
    ("light", "rectangle", "light", trs((0.0, 0.99, 0.01), ((1, 0, 0), 90), (0.23, 0.19, 0.19))),
    ("floor", "rectangle", "white", trs((0.0, -1.0, 0.0), ((1, 0, 0), -90))),
    ("ceiling", "rectangle", "white", trs((0.0, 1.0, 0.0), ((1, 0, 0), 90))),
    ("back", "rectangle", "white", trs((0.0, 0.0, -1.0))),
    ("green-wall", "rectangle", "green", trs((1.0, 0.0, 0.0), ((0, 1, 0), -90))),
    ("red-wall", "rectangle", "red", trs((-1.0, 0.0, 0.0), ((0, 1, 0), 90))),
    ("small-box", "cube", "white", trs((0.335, -0.7, 0.38), ((0, 1, 0), -17), 0.3)),
    ("large-box", "cube", "white", trs((-0.33, -0.4, -0.28), ((0, 1, 0), 18.25), (0.3, 0.61, 0.3))),
]
# sensor: perspective, fov 39.3077 deg on the smaller image axis, look_at from
# (0, 0, 3.9) to the origin with up +y: a glTF camera at (0, 0, 3.9) with no rotation.
CORNELL_FOV_DEG = 39.3077
CORNELL_EYE = (0.0, 0.0, 3.9)
CORNELL_NEAR, CORNELL_FAR = 0.001, 100.0

# Mitsuba's `cube` mesh (src/shapes/cube.cpp): 24 vertices, 4 per face, outward normals.
_CUBE_FACES = [  # (normal, 4 corners counter-clockwise seen from outside)
    ((0, -1, 0), [(1, -1, -1), (1, -1, 1), (-1, -1, 1), (-1, -1, -1)]),
    ((0, 1, 0), [(1, 1, -1), (-1, 1, -1), (-1, 1, 1), (1, 1, 1)]),
    ((1, 0, 0), [(1, -1, -1), (1, 1, -1), (1, 1, 1), (1, -1, 1)]),
    ((0, 0, 1), [(1, -1, 1), (1, 1, 1), (-1, 1, 1), (-1, -1, 1)]),
    ((-1, 0, 0), [(-1, -1, 1), (-1, 1, 1), (-1, 1, -1), (-1, -1, -1)]),
    ((0, 0, -1), [(1, 1, -1), (1, -1, -1), (-1, -1, -1), (-1, 1, -1)]),
]


def mitsuba_rectangle() -> Mesh:
    # Mitsuba's rectangle: z = 0, x, y in [-1, 1], one-sided, normal +z.
    return quad((-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0))


def mitsuba_cube() -> Mesh:
    p = np.array([c for _, cs in _CUBE_FACES for c in cs], float)
    n = np.array([nn for nn, _ in _CUBE_FACES for _ in range(4)], float)
    # cube.cpp's triangles per face: (0, 1, 2), (3, 0, 2)
    idx = np.array([[4 * f, 4 * f + 1, 4 * f + 2] for f in range(6)]
                   + [[4 * f + 3, 4 * f, 4 * f + 2] for f in range(6)])
    idx = idx.reshape(2, 6, 3).transpose(1, 0, 2).reshape(-1, 3)
    return Mesh(p, n, idx)


# glTF's way to write a Lambertian surface: no specular layer (KHR_materials_specular's factor 0), so
# the BRDF is baseColor / pi (the extension's fresnel_mix with F = 0). Without it a glTF dielectric
# reflects a white specular layer of 4 % and more towards grazing angles, which Mitsuba's Cornell
# box, whose materials are `diffuse`, does not have.
LAMBERT = {"KHR_materials_specular": {"specularFactor": 0.0}}


def cornell_box() -> GltfWriter:
    w = GltfWriter(GENERATOR, png_level=0)
    mats = {name: w.add_material(name, base_color=(*rgb, 1.0), metallic=0.0, roughness=1.0, extensions=LAMBERT)
            for name, rgb in CORNELL_REFLECTANCE.items()}
    peak = max(CORNELL_RADIANCE)
    # The light is Mitsuba's 'white' bsdf plus the area emitter. glTF clamps
    # emissiveFactor to [0, 1], so the scale goes into KHR_materials_emissive_strength.
    mats["light"] = w.add_material("light", base_color=(*CORNELL_REFLECTANCE["white"], 1.0),
                                   metallic=0.0, roughness=1.0, extensions=LAMBERT,
                                   emissive=[c / peak for c in CORNELL_RADIANCE],
                                   emissive_strength=peak)
    for name, kind, material, to_world in CORNELL_SHAPES:
        # World-space vertices in identity nodes: exactly Mitsuba's to_world applied.
        local = mitsuba_rectangle() if kind == "rectangle" else mitsuba_cube()
        mesh = add_mesh(w, name, local.transformed(to_world), mats[material])
        w.add_node(name, mesh=mesh)
    cam = w.add_camera("sensor", yfov=math.radians(CORNELL_FOV_DEG), znear=CORNELL_NEAR,
                       zfar=CORNELL_FAR, aspect_ratio=1.0)
    w.add_node("sensor", camera=cam, translation=CORNELL_EYE)
    return w


# -- living-room -----------------------------------------------------------------------------
# A 5 m x 4 m x 2.7 m room, metres, Y up: x from -2.5 (west) to 2.5 (east), z from
# -2 (north, window wall) to 2 (south, door wall). The shell is single-sided
# quads facing inwards, edges meeting exactly, so the only way out is the window.
ROOM_X, ROOM_Z, ROOM_H = 2.5, 2.0, 2.7
WINDOW_X, WINDOW_Y = (-0.5, 1.1), (0.9, 2.2)  # opening in the north wall
WALL_DEPTH = 0.2  # depth of the window reveal (the wall's thickness)


def wall_with_window(room_x: float = ROOM_X, room_z: float = ROOM_Z, room_h: float = ROOM_H,
                     window_x=WINDOW_X, window_y=WINDOW_Y, depth: float = WALL_DEPTH) -> Mesh:
    """North wall (z = -room_z, facing +z) with a real hole, and the opening's four reveals
    (the defaults: living-room's)."""
    xs = [-room_x, window_x[0], window_x[1], room_x]
    ys = [0.0, window_y[0], window_y[1], room_h]
    z = -room_z
    # A 3x3 grid of panels without the centre one: no T-junctions for rays to slip through.
    panels = [quad((xs[i], ys[j], z), (xs[i + 1], ys[j], z), (xs[i + 1], ys[j + 1], z),
                   (xs[i], ys[j + 1], z), uv_size=(xs[i + 1] - xs[i], ys[j + 1] - ys[j]))
              for j in range(3) for i in range(3) if (i, j) != (1, 1)]
    (x0, x1), (y0, y1), zo = window_x, window_y, z - depth
    reveals = [
        quad((x0, y0, z), (x1, y0, z), (x1, y0, zo), (x0, y0, zo)),  # sill, faces up
        quad((x0, y1, zo), (x1, y1, zo), (x1, y1, z), (x0, y1, z)),  # head, faces down
        quad((x0, y0, zo), (x0, y1, zo), (x0, y1, z), (x0, y0, z)),  # west jamb, faces +x
        quad((x1, y0, z), (x1, y1, z), (x1, y1, zo), (x1, y0, zo)),  # east jamb, faces -x
    ]
    return merge(*panels, *reveals)


def room_shell(X: float = ROOM_X, Z: float = ROOM_Z, H: float = ROOM_H, window_x=WINDOW_X,
               window_y=WINDOW_Y) -> dict[str, Mesh]:
    """Floor, ceiling and four walls of a room x in [-X, X], z in [-Z, Z], y in [0, H], all facing
    inwards, the window in the north wall (the defaults: living-room's)."""
    return {
        "Floor": quad((-X, 0, Z), (X, 0, Z), (X, 0, -Z), (-X, 0, -Z), uv_size=(2 * X, 2 * Z)),
        "Ceiling": quad((-X, H, -Z), (X, H, -Z), (X, H, Z), (-X, H, Z), uv_size=(2 * X, 2 * Z)),
        "Wall north": wall_with_window(X, Z, H, window_x, window_y),
        "Wall south": quad((X, 0, Z), (-X, 0, Z), (-X, H, Z), (X, H, Z), uv_size=(2 * X, H)),
        "Wall east": quad((X, 0, -Z), (X, 0, Z), (X, H, Z), (X, H, -Z), uv_size=(2 * Z, H)),
        "Wall west": quad((-X, 0, Z), (-X, 0, -Z), (-X, H, -Z), (-X, H, Z), uv_size=(2 * Z, H)),
    }


def wood_texture(size: int = 64) -> np.ndarray:
    """Oak planks: 4 planks across, a grain of sines, darker joints (sRGB uint8)."""
    v, u = np.mgrid[0:size, 0:size] / size
    plank = np.floor(u * 4)
    grain = 0.5 + 0.5 * np.sin(2 * np.pi * (v * 3 + 0.35 * plank) * 4
                               + 2.0 * np.sin(2 * np.pi * (u * 4 + 0.3 * plank)))
    tone = 0.85 + 0.1 * np.sin(plank * 2.3) + 0.08 * grain
    joint = (np.abs((u * 4) - np.round(u * 4)) < 0.02) | (np.abs(((v + 0.25 * plank) % 1)) < 0.015)
    tone = np.where(joint, 0.45, tone)
    base = np.array([176, 124, 76], float)
    return np.clip(base * tone[..., None], 0, 255).astype(np.uint8)


def rug_texture(size: int = 64) -> np.ndarray:
    """A bordered rug with a diamond lattice (sRGB uint8)."""
    v, u = np.mgrid[0:size, 0:size] / (size - 1)
    edge = np.minimum(np.minimum(u, 1 - u), np.minimum(v, 1 - v))
    diamond = (np.abs(((u * 6) % 1) - 0.5) + np.abs(((v * 4) % 1) - 0.5)) < 0.3
    img = np.empty((size, size, 3), float)
    img[:] = (150, 40, 38)  # madder red field
    img[diamond] = (214, 180, 120)  # sand lattice
    img[edge < 0.1] = (40, 50, 90)  # indigo border
    img[(edge > 0.05) & (edge < 0.065)] = (214, 180, 120)
    return img.astype(np.uint8)


def canvas_texture(size: int = 32) -> np.ndarray:
    """An abstract painting: soft colour fields (sRGB uint8)."""
    v, u = np.mgrid[0:size, 0:size] / (size - 1)
    r = 0.55 + 0.35 * np.sin(3 * u + 1) * np.cos(2 * v)
    g = 0.45 + 0.3 * np.sin(2 * v + 2 * u)
    b = 0.5 + 0.4 * np.cos(4 * u - 1.5 * v)
    return np.clip(np.stack([r, g, b], -1) * 255, 0, 255).astype(np.uint8)


def vase_profile() -> list[tuple[float, float]]:
    """(r, y) outline of a 30 cm vase: base, belly, neck, flared lip, then the inside back down."""
    height, wall = 0.30, 0.006
    t = np.linspace(0, 1, 25)
    r = 0.045 + 0.055 * np.exp(-((t - 0.35) / 0.22) ** 2) + 0.012 * np.exp(-((t - 1) / 0.08) ** 2)
    outside = list(zip(r, t * height))
    ti = np.linspace(1, 0.04, 17)
    ri = 0.045 + 0.055 * np.exp(-((ti - 0.35) / 0.22) ** 2) + 0.012 * np.exp(-((ti - 1) / 0.08) ** 2)
    inside = list(zip(ri - wall, ti * height))
    return [(0.0, 0.0)] + outside + inside + [(0.0, 0.04 * height)]


def teapot_mesh() -> Mesh:
    p, n, idx, _ = teapot.tessellate(segments=8)
    return Mesh(p, n, idx)


def bookshelf() -> Mesh:
    """1.2 m wide (x), 1.9 m tall, 0.35 m deep (z), back panel at -z, open towards +z."""
    w, h, d, t = 1.2, 1.9, 0.35, 0.025
    parts = [box((t, h, d), (-w / 2 + t / 2, h / 2, 0)), box((t, h, d), (w / 2 - t / 2, h / 2, 0)),
             box((w, t, d), (0, h - t / 2, 0)), box((w, 0.08, d), (0, 0.04, 0)),
             box((w, h, 0.01), (0, h / 2, -d / 2 + 0.005))]
    for y in (0.5, 0.95, 1.4):
        parts.append(box((w - 2 * t, t, d - 0.01), (0, y, 0.005)))
    return merge(*parts)


def books(shelf_ys, colour: int, colours: int = 3) -> Mesh:
    """Every `colours`-th book of a fixed row of books on each shelf (sizes vary by position)."""
    parts = []
    for k, y in enumerate(shelf_ys):
        x = -0.56 + 0.03 * (k % 3)
        for j in range(14):
            h = 0.2 + 0.012 * ((j * 5 + k * 3) % 7)
            wdt = 0.025 + 0.005 * ((j * 3 + k) % 4)
            if (j + k) % colours == colour:
                parts.append(box((wdt, h, 0.2), (x + wdt / 2, y + h / 2, 0.03)))
            x += wdt + 0.004
    return merge(*parts)


def frame(width: float, height: float, border: float, depth: float) -> Mesh:
    """A picture/screen frame of four bars in the xy plane, centred on the origin."""
    w, h, b = width, height, border
    return merge(box((w, b, depth), (0, h / 2 - b / 2, 0)), box((w, b, depth), (0, -h / 2 + b / 2, 0)),
                 box((b, h - 2 * b, depth), (w / 2 - b / 2, 0, 0)),
                 box((b, h - 2 * b, depth), (-w / 2 + b / 2, 0, 0)))


# Daylight through the window and three ceiling downlights of similar total
# power (~10 W of radiant flux each way), so neither dominates the light maps.
LIGHT_RADIANCE = 16.0  # W/(m^2 sr), peak channel of the ceiling diffusers
LIGHT_COLOUR = (1.0, 0.87, 0.70)  # ~3000 K warm white, linear RGB


def living_room() -> GltfWriter:
    w = GltfWriter(GENERATOR, png_level=0)
    M = {}  # material name -> index
    # Shell: rough paint (roughness >= 0.5: purely diffuse in glint's mapping).
    M["Floor"] = w.add_material("Floor", base_color=(1, 1, 1, 1), roughness=0.2,
                                base_color_texture=wood_texture())
    M["Wall paint"] = w.add_material("Wall paint", base_color=(0.78, 0.76, 0.72, 1), roughness=0.9)
    M["Ceiling paint"] = w.add_material("Ceiling paint", base_color=(0.85, 0.85, 0.84, 1),
                                        roughness=0.95)
    M["Light diffuser"] = w.add_material("Light diffuser", base_color=(0.9, 0.9, 0.9, 1),
                                         roughness=1.0, emissive=LIGHT_COLOUR,
                                         emissive_strength=LIGHT_RADIANCE)
    M["Stone sill"] = w.add_material("Stone sill", base_color=(0.62, 0.6, 0.56, 1), roughness=0.6)
    M["Sofa fabric"] = w.add_material("Sofa fabric", base_color=(0.16, 0.24, 0.36, 1), roughness=0.95)
    M["Cushion fabric"] = w.add_material("Cushion fabric", base_color=(0.55, 0.42, 0.26, 1),
                                         roughness=0.95)
    M["Dark wood"] = w.add_material("Dark wood", base_color=(0.10, 0.06, 0.035, 1), roughness=0.6)
    M["Table lacquer"] = w.add_material("Table lacquer", base_color=(0.12, 0.07, 0.04, 1),
                                        roughness=0.08)
    M["Oak"] = w.add_material("Oak", base_color=(0.55, 0.40, 0.25, 1), roughness=0.7)
    M["White lacquer"] = w.add_material("White lacquer", base_color=(0.80, 0.80, 0.78, 1),
                                        roughness=0.6)
    M["Rug wool"] = w.add_material("Rug wool", base_color=(1, 1, 1, 1), roughness=1.0,
                                   base_color_texture=rug_texture())
    M["Canvas"] = w.add_material("Canvas", base_color=(1, 1, 1, 1), roughness=0.9,
                                 base_color_texture=canvas_texture())
    M["Black powder coat"] = w.add_material("Black powder coat", base_color=(0.03, 0.03, 0.03, 1),
                                            roughness=0.7)
    M["Lamp shade"] = w.add_material("Lamp shade", base_color=(0.85, 0.80, 0.68, 1), roughness=1.0,
                                     double_sided=True)
    for name, rgb in (("Book red", (0.45, 0.06, 0.05)), ("Book blue", (0.06, 0.12, 0.35)),
                      ("Book cream", (0.75, 0.68, 0.52))):
        M[name] = w.add_material(name, base_color=(*rgb, 1), roughness=0.8)
    # Metals: F0 colours from the usual measured tables (copper, chromium, brass).
    M["Copper"] = w.add_material("Copper", base_color=(0.955, 0.638, 0.538, 1), metallic=1.0,
                                 roughness=0.18)
    M["Chrome"] = w.add_material("Chrome", base_color=(0.549, 0.556, 0.554, 1), metallic=1.0,
                                 roughness=0.05)
    M["Brass"] = w.add_material("Brass", base_color=(0.91, 0.78, 0.42, 1), metallic=1.0,
                                roughness=0.25)
    # Anisotropic brushed aluminium. glTF side: KHR_materials_anisotropy (brushed
    # along the TANGENT, i.e. around the cylinder). Full model in extras.glint:
    # the thesis' two-lobe fit to the Miro 5 brushed aluminium (its Table 3.3).
    M["Brushed aluminium"] = w.add_material(
        "Brushed aluminium", base_color=(0.91, 0.92, 0.92, 1), metallic=1.0, roughness=0.3,
        extensions={"KHR_materials_anisotropy": {"anisotropyStrength": 0.8,
                                                 "anisotropyRotation": 0.0}},
        extras={"glint": {"kd": [0.003, 0.003, 0.003], "lobes": [
            {"kind": "reflect", "ks": [0.57, 0.57, 0.57], "mx": 0.0046, "my": 0.0267,
             "r0": 0.94, "alpha": 0.5},
            {"kind": "reflect", "ks": [0.54, 0.54, 0.54], "mx": 0.013, "my": 0.1199,
             "r0": 0.84, "alpha": 0.38}]}})
    # Thin frosted glass: transmission 0.9, roughness 0.3 blurs what is behind it.
    M["Frosted glass"] = w.add_material(
        "Frosted glass", base_color=(0.96, 0.98, 0.98, 1), metallic=0.0, roughness=0.3,
        double_sided=True, extensions={"KHR_materials_transmission": {"transmissionFactor": 0.9}})

    def node(name, mesh, material, **kw):
        return w.add_node(name, mesh=add_mesh(w, name, mesh, M[material]), **kw)

    # Shell, in world coordinates (as an architect's model usually is).
    shell_material = {"Floor": "Floor", "Ceiling": "Ceiling paint"}
    for name, mesh in room_shell().items():
        if name == "Floor":
            mesh.uvs = mesh.uvs / 1.2  # one texture tile (4 planks) per 1.2 m
        node(name, mesh, shell_material.get(name, "Wall paint"))
    node("Window sill", box((WINDOW_X[1] - WINDOW_X[0] + 0.2, 0.03, 0.16),
                            (sum(WINDOW_X) / 2, WINDOW_Y[0] - 0.015, -ROOM_Z + 0.08)), "Stone sill")

    # Ceiling downlights: one mesh, three instances (Blender's linked duplicates).
    light_mesh = add_mesh(w, "Ceiling light", disc(0.15, 24, 0.0, facing_up=False),
                          M["Light diffuser"])
    for k, (x, z) in enumerate(((-0.9, 0.1), (1.0, -1.0), (1.0, 1.0)), start=1):
        w.add_node(f"Ceiling light {k}", mesh=light_mesh, translation=(x, ROOM_H - 0.01, z))

    # Sofa: a parent node (against the west wall, facing east) with parts in its frame,
    # where the sofa faces +z and its length runs along x.
    sofa_parts = [
        node("Sofa base", box((1.7, 0.32, 0.7), (0, 0.26, 0.1)), "Sofa fabric"),
        node("Sofa back", box((2.0, 0.75, 0.2), (0, 0.475, -0.35)), "Sofa fabric"),
        node("Sofa arm left", box((0.15, 0.52, 0.7), (-0.925, 0.36, 0.1)), "Sofa fabric"),
        node("Sofa arm right", box((0.15, 0.52, 0.7), (0.925, 0.36, 0.1)), "Sofa fabric"),
        node("Sofa cushions", merge(box((0.83, 0.1, 0.66), (-0.425, 0.47, 0.11)),
                                    box((0.83, 0.1, 0.66), (0.425, 0.47, 0.11))), "Cushion fabric"),
        node("Sofa feet", merge(*[box((0.06, 0.1, 0.06), (x, 0.05, z))
                                  for x in (-0.95, 0.95) for z in (-0.4, 0.4)]), "Dark wood"),
    ]
    w.add_node("Sofa", translation=(-2.05, 0.0, 0.1), rotation=quat_y(90.0), children=sofa_parts)

    # Coffee table: top 0.6 x 1.1 m at 0.45 m, glossy lacquer, a planar reflector.
    table_parts = [
        node("Table top", box((0.6, 0.04, 1.1)), "Table lacquer", translation=(0, 0.43, 0)),
        node("Table legs", merge(*[box((0.04, 0.41, 0.04), (x, 0.205, z))
                                   for x in (-0.25, 0.25) for z in (-0.5, 0.5)]), "Dark wood"),
    ]
    w.add_node("Coffee table", translation=(-0.75, 0.0, 0.1), children=table_parts)
    node("Rug", box((1.5, 0.012, 2.0), (0, 0.006, 0)), "Rug wool", translation=(-0.7, 0.0, 0.1))

    # Curved glossy metal: the Utah teapot (Newell's units -> 0.17 m tall), a brass vase.
    node("Teapot", teapot_mesh(), "Copper", translation=(-0.78, 0.45, 0.35),
         rotation=quat_y(-30.0), scale=(0.055, 0.055, 0.055))
    node("Vase", lathe(vase_profile(), 40), "Brass", translation=(-0.72, 0.45, -0.25))

    # Sideboard on the south wall with a chrome ball on it.
    node("Sideboard", box((1.8, 0.75, 0.42), (0, 0.375, 0)), "White lacquer",
         translation=(-0.7, 0.0, ROOM_Z - 0.21))
    node("Chrome sphere", uv_sphere(0.1, 32, 16), "Chrome", translation=(-0.3, 0.85, ROOM_Z - 0.22))

    # Brushed-aluminium side table (a cylinder) beside the sofa.
    node("Side table", cylinder(0.2, 0.5, 48), "Brushed aluminium", translation=(-2.1, 0.0, -1.3))

    # Frosted-glass screen in the north-east corner, partly in front of the bookshelf:
    # one thin double-sided pane (glint's thin-surface model) in a black frame.
    pane = quad((-0.45, -0.85, 0), (0.45, -0.85, 0), (0.45, 0.85, 0), (-0.45, 0.85, 0))
    screen_at = dict(translation=(1.75, 0.95, -1.5), rotation=quat_y(-50.0))
    node("Glass screen", pane, "Frosted glass", **screen_at)
    node("Glass screen frame", merge(frame(0.96, 1.76, 0.03, 0.03),
                                     box((0.05, 0.1, 0.3), (-0.43, -0.9, 0)),
                                     box((0.05, 0.1, 0.3), (0.43, -0.9, 0))),
         "Black powder coat", **screen_at)

    # Bookshelf on the east wall, open side facing west (-x), books on three shelves.
    shelf_at = dict(translation=(ROOM_X - 0.175, 0.0, -1.0), rotation=quat_y(-90.0))
    node("Bookshelf", bookshelf(), "Oak", **shelf_at)
    shelf_tops = (0.08, 0.5125, 0.9625, 1.4125)
    for k, colour in enumerate(("Book red", "Book blue", "Book cream")):
        node(f"Books {colour.split()[1]}", books(shelf_tops, k), colour, **shelf_at)

    # Floor lamp in the sofa's south corner.
    lamp_at = dict(translation=(-2.15, 0.0, 1.55))
    node("Floor lamp base", cylinder(0.15, 0.02, 32), "Black powder coat", **lamp_at)
    node("Floor lamp pole", cylinder(0.012, 1.4, 12, caps=False), "Black powder coat", **lamp_at)
    node("Floor lamp shade", lathe([(0.2, 1.35), (0.14, 1.65)], 32), "Lamp shade",
         **lamp_at)

    # Pictures: on the east wall (lit by a spot) and above the sideboard.
    east_at = dict(translation=(ROOM_X - 0.02, 1.5, 0.8), rotation=quat_y(-90.0))
    node("Picture frame east", frame(0.9, 0.7, 0.05, 0.04), "Black powder coat", **east_at)
    node("Painting east", quad((-0.4, -0.3, 0), (0.4, -0.3, 0), (0.4, 0.3, 0), (-0.4, 0.3, 0)),
         "Canvas", **east_at)
    south_at = dict(translation=(-0.7, 1.55, ROOM_Z - 0.02), rotation=quat_y(180.0))
    node("Picture frame south", frame(0.7, 0.5, 0.04, 0.04), "Oak", **south_at)
    node("Painting south", quad((-0.31, -0.21, 0), (0.31, -0.21, 0), (0.31, 0.21, 0),
                                (-0.31, 0.21, 0), uv_size=(0.5, 0.5)), "Canvas", **south_at)

    # Door (closed) in the south wall, with a handle.
    node("Door", box((0.9, 2.05, 0.04), (0, 1.025, 0)), "White lacquer",
         translation=(1.6, 0.0, ROOM_Z - 0.02))
    node("Door handle", box((0.12, 0.02, 0.05), (0, 0, 0)), "Black powder coat",
         translation=(1.25, 1.0, ROOM_Z - 0.065))

    # A picture spot: 800 cd halogen on the ceiling aimed at the east painting.
    spot_eye, spot_target = (1.3, ROOM_H - 0.05, 0.8), (ROOM_X, 1.5, 0.8)
    spot = w.add_light("Picture spot", "spot", color=(1.0, 0.9, 0.75), intensity=800.0,
                       inner_cone_angle=0.2, outer_cone_angle=0.35)
    w.add_node("Picture spot", light=spot, translation=spot_eye,
               rotation=look_at_quat(spot_eye, spot_target))

    # Cameras (glTF cameras look along their node's -Z).
    for name, eye, target, fov in (("entrance", (1.6, 1.6, 1.6), (-1.0, 1.0, -0.8), 55.0),
                                   ("sofa", (-1.85, 1.15, 0.0), (1.0, 1.0, -0.6), 60.0)):
        cam = w.add_camera(name, yfov=math.radians(fov), znear=0.05, zfar=50.0,
                           aspect_ratio=16 / 9)
        w.add_node(name, camera=cam, translation=eye, rotation=look_at_quat(eye, target))
    return w


# -- material-classes ------------------------------------------------------------------------
# One sphere per material class of the thesis (sharp insulator, chrome-like glossy metal,
# anisotropic brushed aluminium, frosted glass) on diffuse plinths in a small closed room with
# structure to reflect: coloured walls, a striped wall behind the camera, a chequered floor, a
# window onto the sky behind the glass, a ceiling light. For the accuracy and speed tables of
# `glint bench` (docs/BENCHMARKS.md); one camera sees all four.
MC_X, MC_Z, MC_H = 2.0, 1.7, 2.6  # room half-width (x), half-depth (z), height, metres
MC_WINDOW_X, MC_WINDOW_Y = (0.3, 1.85), (0.3, 2.0)  # in the north wall: seen through the glass sphere
MC_RADIUS, MC_PLINTH = 0.22, 0.55  # sphere radius, plinth height
MC_SPHERES = (  # (object name, material, x); all at z = MC_SPHERE_Z
    ("Ceramic sphere", "Glazed ceramic", -1.05),
    ("Chrome sphere", "Chrome", -0.35),
    ("Brushed sphere", "Brushed aluminium", 0.35),
    ("Frosted sphere", "Frosted glass", 1.05),
)
MC_SPHERE_Z = -0.4
MC_CAMERA = ("front", (0.0, 1.2, 1.45), (0.0, 0.72, MC_SPHERE_Z), 50.0)  # name, eye, target, yfov


def checker_texture(size: int = 64, squares: int = 2) -> np.ndarray:
    """squares x squares light and dark tiles with thin grout lines (sRGB uint8)."""
    v, u = np.mgrid[0:size, 0:size] / size
    tile = (np.floor(u * squares) + np.floor(v * squares)) % 2
    img = np.where(tile[..., None] > 0, [[[70, 72, 80]]], [[[215, 212, 200]]]).astype(float)
    grout = (np.abs(u * squares - np.round(u * squares)) < 0.02) | (np.abs(v * squares - np.round(v * squares)) < 0.02)
    img[grout] = (120, 118, 112)
    return img.astype(np.uint8)


def stripes_texture(size: int = 64) -> np.ndarray:
    """Vertical bands of four colours with white gaps (sRGB uint8): structure to reflect."""
    u = np.arange(size) / size
    band = np.floor(u * 8).astype(int)
    colours = np.array([(230, 190, 40), (240, 240, 235), (40, 80, 170), (240, 240, 235),
                        (200, 60, 40), (240, 240, 235), (40, 140, 90), (240, 240, 235)], float)
    row = colours[band]
    return np.repeat(row[None], size, axis=0).astype(np.uint8)


PAINTS = {"Red paint": (0.62, 0.12, 0.09), "Green paint": (0.12, 0.45, 0.16), "Blue paint": (0.10, 0.20, 0.55),
          "Yellow paint": (0.75, 0.60, 0.10), "Grey paint": (0.6, 0.62, 0.66)}
CEILING_LIGHT = quad((-0.5, 0, -0.25), (0.5, 0, -0.25), (0.5, 0, 0.25), (-0.5, 0, 0.25))  # faces down


def add_class_room_materials(w: GltfWriter, M: dict, paints: tuple[str, ...]) -> None:
    """The diffuse materials the two class rooms share, `paints` first (glTF material order)."""
    for name in paints:
        M[name] = w.add_material(name, base_color=(*PAINTS[name], 1), roughness=0.9)
    M["Striped paper"] = w.add_material("Striped paper", base_color=(1, 1, 1, 1), roughness=0.9,
                                        base_color_texture=stripes_texture())
    M["Ceiling paint"] = w.add_material("Ceiling paint", base_color=(0.85, 0.85, 0.84, 1), roughness=0.95)
    M["Light diffuser"] = w.add_material("Light diffuser", base_color=(0.9, 0.9, 0.9, 1), roughness=1.0,
                                         emissive=LIGHT_COLOUR, emissive_strength=12.0)
    M["Plinth"] = w.add_material("Plinth", base_color=(0.25, 0.25, 0.27, 1), roughness=0.8)


def add_class_room_camera(w: GltfWriter, name: str, eye, target, fov: float) -> None:
    cam = w.add_camera(name, yfov=math.radians(fov), znear=0.05, zfar=50.0, aspect_ratio=16 / 9)
    w.add_node(name, camera=cam, translation=eye, rotation=look_at_quat(eye, target))


def material_classes() -> GltfWriter:
    w = GltfWriter(GENERATOR, png_level=0)
    M = {}
    M["Floor tiles"] = w.add_material("Floor tiles", base_color=(1, 1, 1, 1), roughness=0.9,
                                      base_color_texture=checker_texture())
    add_class_room_materials(w, M, ("Red paint", "Green paint", "Grey paint"))
    # The four classes; exact lobes in the sidecar (material-classes.glint.toml), these are the glTF fallbacks.
    M["Glazed ceramic"] = w.add_material("Glazed ceramic", base_color=(0.55, 0.07, 0.05, 1), roughness=0.2)
    M["Chrome"] = w.add_material("Chrome", base_color=(0.95, 0.95, 0.95, 1), metallic=1.0, roughness=0.17)
    M["Brushed aluminium"] = w.add_material(
        "Brushed aluminium", base_color=(0.91, 0.92, 0.92, 1), metallic=1.0, roughness=0.3,
        extensions={"KHR_materials_anisotropy": {"anisotropyStrength": 0.8, "anisotropyRotation": 0.0}})
    M["Frosted glass"] = w.add_material(
        "Frosted glass", base_color=(0.96, 0.98, 0.98, 1), metallic=0.0, roughness=0.32, double_sided=True,
        extensions={"KHR_materials_transmission": {"transmissionFactor": 0.9}})

    def node(name, mesh, material, **kw):
        return w.add_node(name, mesh=add_mesh(w, name, mesh, M[material]), **kw)

    walls = {"Floor": "Floor tiles", "Ceiling": "Ceiling paint", "Wall north": "Grey paint",
             "Wall south": "Striped paper", "Wall east": "Green paint", "Wall west": "Red paint"}
    for name, mesh in room_shell(MC_X, MC_Z, MC_H, MC_WINDOW_X, MC_WINDOW_Y).items():
        if name == "Wall south":  # (the floor: one texture tile, 2 x 2 squares, per metre)
            mesh.uvs = mesh.uvs / (2 * MC_X)  # the stripes once across the wall
        node(name, mesh, walls[name])
    node("Ceiling light", CEILING_LIGHT, "Light diffuser", translation=(0.0, MC_H - 0.01, -0.1))
    for name, material, x in MC_SPHERES:
        node(f"{name.split()[0]} plinth", box((0.36, MC_PLINTH, 0.36), (0, MC_PLINTH / 2, 0)), "Plinth",
             translation=(x, 0.0, MC_SPHERE_Z))
        node(name, uv_sphere(MC_RADIUS, 48, 24), material, translation=(x, MC_PLINTH + MC_RADIUS, MC_SPHERE_Z))
    add_class_room_camera(w, *MC_CAMERA)
    return w


# -- planar-classes --------------------------------------------------------------------------
# The planar counterpart of material-classes: four planar reflectors, each in its own plane
# (so each gets a mirror pass within the default budget of 4), one per planar material class --
# polished stone (the floor), varnished wood (a platform top), glossy tiles and blurry aluminium
# (panels on the west and east walls) -- in the material-classes room with coloured blocks, a
# window and a ceiling light to reflect. One camera sees all four at moderate angles.
PC_PLATFORM = ((-0.55, 0.55), 0.45, (-1.15, -0.45))  # x range, top height, z range
PC_PANEL_Y, PC_PANEL_Z = (0.35, 1.75), (-1.4, 0.2)  # wall panels: height and depth range
PC_PANEL_GAP = 0.02  # the panels stand this far off their walls
PC_CAMERA = ("front", (0.0, 1.55, 1.55), (0.0, 0.45, -0.6), 62.0)  # name, eye, target, yfov


def planar_classes() -> GltfWriter:
    w = GltfWriter(GENERATOR, png_level=0)
    M = {}
    add_class_room_materials(w, M, ("Red paint", "Green paint", "Blue paint", "Yellow paint", "Grey paint"))
    # The four planar classes; exact lobes in the sidecar (planar-classes.glint.toml), these are the glTF fallbacks.
    M["Polished stone"] = w.add_material("Polished stone", base_color=(0.42, 0.40, 0.37, 1), roughness=0.12)
    M["Varnished wood"] = w.add_material("Varnished wood", base_color=(1, 1, 1, 1), roughness=0.2,
                                         base_color_texture=wood_texture())
    M["Glossy tiles"] = w.add_material("Glossy tiles", base_color=(1, 1, 1, 1), roughness=0.3,
                                       base_color_texture=checker_texture())
    M["Blurry aluminium"] = w.add_material("Blurry aluminium", base_color=(0.91, 0.92, 0.92, 1), metallic=1.0,
                                           roughness=0.45)

    def node(name, mesh, material, **kw):
        return w.add_node(name, mesh=add_mesh(w, name, mesh, M[material]), **kw)

    walls = {"Ceiling": "Ceiling paint", "Wall north": "Grey paint", "Wall south": "Striped paper",
             "Wall east": "Green paint", "Wall west": "Red paint"}
    for name, mesh in room_shell(MC_X, MC_Z, MC_H, MC_WINDOW_X, MC_WINDOW_Y).items():
        if name == "Wall south":
            mesh.uvs = mesh.uvs / (2 * MC_X)  # the stripes once across the wall
        node("Stone floor" if name == "Floor" else name, mesh,
             "Polished stone" if name == "Floor" else walls[name])
    node("Ceiling light", CEILING_LIGHT, "Light diffuser", translation=(0.0, MC_H - 0.01, -0.1))
    # Varnished wood: the top of a low platform (the base is diffuse, just below the top).
    (x0, x1), h, (z0, z1) = PC_PLATFORM
    node("Wood platform top", quad((x0, h, z1), (x1, h, z1), (x1, h, z0), (x0, h, z0), uv_size=(x1 - x0, z1 - z0)),
         "Varnished wood")
    node("Platform base", box((x1 - x0, h - 0.005, z1 - z0), ((x0 + x1) / 2, (h - 0.005) / 2, (z0 + z1) / 2)),
         "Plinth")
    # Glossy tiles on the west wall (facing +x), blurry aluminium on the east wall (facing -x).
    (ya, yb), (za, zb) = PC_PANEL_Y, PC_PANEL_Z
    x = -MC_X + PC_PANEL_GAP
    node("Tile panel", quad((x, ya, zb), (x, ya, za), (x, yb, za), (x, yb, zb), uv_size=(zb - za, yb - ya)),
         "Glossy tiles")
    x = MC_X - PC_PANEL_GAP
    node("Aluminium panel", quad((x, ya, za), (x, ya, zb), (x, yb, zb), (x, yb, za)), "Blurry aluminium")
    # Coloured things to reflect: blocks on the floor and the platform, a ball.
    node("Blue block", box((0.3, 0.5, 0.3), (0, 0.25, 0)), "Blue paint", translation=(-1.2, 0.0, 0.5))
    node("Yellow block", box((0.25, 0.7, 0.25), (0, 0.35, 0)), "Yellow paint", translation=(1.25, 0.0, -0.9))
    node("Red block", box((0.2, 0.3, 0.2), (0, 0.15, 0)), "Red paint", translation=(-0.25, h, -0.8))
    node("Green ball", uv_sphere(0.14, 32, 16), "Green paint", translation=(0.25, h + 0.14, -0.75))
    add_class_room_camera(w, *PC_CAMERA)
    return w


# -- metal-floor-room, glossy-floor-room -------------------------------------------------------
# A closed 4 m x 2.6 m x 4 m room (x, z in [-2, 2]) lit by one ceiling light, red west and green
# east walls, a pedestal with a ball, and a glossy floor: polished metal (glTF metallic 1,
# roughness 0.05, base 0.9: m = 0.0025, ks 0.9, kd 0) or a glossy dielectric (metallic 0,
# roughness 0.1, base 0.4: m = 0.01, r0 0.04, kd 0.4). Made to be compared with Mitsuba 3 end to
# end (bench/measure_glossy_floors.py): everything the floor reflects is diffuse or the light.
GF_X, GF_Z, GF_H = 2.0, 2.0, 2.6
GF_FLOORS = {"metal": dict(base_color=(0.9, 0.9, 0.9, 1), metallic=1.0, roughness=0.05),
             "dielectric": dict(base_color=(0.4, 0.4, 0.4, 1), metallic=0.0, roughness=0.1)}
GF_CAMERA = ("Camera", (0.0, 1.5, 1.9), (0.0, 0.55, -0.7), 60.0)


def glossy_floor_room(floor: str | dict, camera=GF_CAMERA) -> GltfWriter:
    """The room above with the `floor` of GF_FLOORS ("metal" or "dielectric"), or a floor of these glTF
    factors (GltfWriter.add_material's keywords), seen from `camera` (name, eye, target, fov)."""
    w = GltfWriter(GENERATOR, png_level=0)
    M = {}
    add_class_room_materials(w, M, ("Red paint", "Green paint", "Blue paint", "Grey paint"))
    factors = GF_FLOORS[floor] if isinstance(floor, str) else floor
    M["Floor"] = w.add_material("Polished metal" if factors["metallic"] > 0.5 else "Glossy floor", **factors)

    def node(name, mesh, material, **kw):
        return w.add_node(name, mesh=add_mesh(w, name, mesh, M[material]), **kw)

    X, Z, H = GF_X, GF_Z, GF_H
    shell = {
        "Floor": (quad((-X, 0, Z), (X, 0, Z), (X, 0, -Z), (-X, 0, -Z), uv_size=(2 * X, 2 * Z)), "Floor"),
        "Ceiling": (quad((-X, H, -Z), (X, H, -Z), (X, H, Z), (-X, H, Z), uv_size=(2 * X, 2 * Z)), "Ceiling paint"),
        "Wall north": (quad((-X, 0, -Z), (X, 0, -Z), (X, H, -Z), (-X, H, -Z), uv_size=(2 * X, H)), "Grey paint"),
        "Wall south": (quad((X, 0, Z), (-X, 0, Z), (-X, H, Z), (X, H, Z), uv_size=(2 * X, H)), "Grey paint"),
        "Wall east": (quad((X, 0, -Z), (X, 0, Z), (X, H, Z), (X, H, -Z), uv_size=(2 * Z, H)), "Green paint"),
        "Wall west": (quad((-X, 0, Z), (-X, 0, -Z), (-X, H, -Z), (-X, H, Z), uv_size=(2 * Z, H)), "Red paint"),
    }
    for name, (mesh, material) in shell.items():
        node(name, mesh, material)
    node("Ceiling light", CEILING_LIGHT, "Light diffuser", translation=(0.0, H - 0.01, 0.0))
    node("Pedestal", box((0.4, 0.8, 0.4), (0, 0.4, 0)), "Plinth", translation=(0.0, 0.0, -0.7))
    node("Ball", uv_sphere(0.2, 32, 16), "Blue paint", translation=(0.0, 1.0, -0.7))
    add_class_room_camera(w, *camera)
    return w


def generate(out_dir: Path | str = HERE) -> list[Path]:
    """Write all built-in scene files into out_dir; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = [cornell_box().write(out / "cornell-box.glb"),
               living_room().write(out / "living-room.glb"),
               material_classes().write(out / "material-classes.glb"),
               planar_classes().write(out / "planar-classes.glb"),
               glossy_floor_room("metal").write(out / "metal-floor-room.glb"),
               glossy_floor_room("dielectric").write(out / "glossy-floor-room.glb")]
    return written


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    for path in generate(argv[0] if argv else HERE):
        print(f"wrote {path} ({path.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
