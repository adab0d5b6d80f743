"""The viewing camera: a pinhole with a vertical field of view, in OpenGL conventions.

World space is the bake's: metres, Y up, right-handed. Eye space looks down -Z
with +Y up and +X to the right of the image (OpenGL), which is also the image
Mitsuba 3's `perspective` sensor makes from the same eye/target/up
(`look_at`), with `fov_axis` "y" -- or "smaller" when the image is not taller than
wide, as in `mitsuba.cornell_box()`. The field of view is always vertical here;
the image's aspect ratio (its size) decides the horizontal one.

Matrices are numpy float32 (4, 4) acting on column vectors (`M @ [x, y, z, 1]`);
upload them to GLSL with `gl_bytes` (column-major).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pyrr

from glint.core.errors import GlintError
from glint.core.manifest import Camera, CameraPath, Manifest

DEFAULT_YFOV = math.radians(50.0)  # bake/sidecar.py's default for cameras without one
WORLD_UP = np.array([0.0, 1.0, 0.0])


def _unit(v, fallback) -> np.ndarray:
    v = np.asarray(v, np.float64)
    n = float(np.linalg.norm(v))
    return v / n if np.isfinite(n) and n > 1e-12 else np.asarray(fallback, np.float64)


def _basis(forward, up) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orthonormal (forward, up, right); an `up` parallel to `forward` is replaced by another axis."""
    f = _unit(forward, (0.0, 0.0, -1.0))
    for candidate in (up, WORLD_UP, (0.0, 0.0, -1.0), (1.0, 0.0, 0.0)):
        c = np.asarray(candidate, np.float64)
        u = c - f * np.dot(c, f)
        if np.linalg.norm(u) > 1e-6 * max(np.linalg.norm(c), 1e-30):
            u = _unit(u, WORLD_UP)
            return f, u, np.cross(f, u)
    raise AssertionError("unreachable: three orthogonal axes cannot all be parallel to forward")


@dataclass
class ViewCamera:
    eye: np.ndarray
    forward: np.ndarray
    up: np.ndarray = field(default_factory=lambda: WORLD_UP.copy())
    yfov: float = DEFAULT_YFOV  # vertical field of view, radians
    znear: float = 0.01
    zfar: float = 1000.0
    name: str = ""

    def __post_init__(self):
        self.eye = np.asarray(self.eye, np.float64).reshape(3)
        self.forward, self.up, _ = _basis(self.forward, self.up)
        self.yfov = float(min(max(self.yfov, 1e-4), math.pi - 1e-4))
        self.znear = float(max(self.znear, 1e-6))
        self.zfar = float(max(self.zfar, self.znear * (1 + 1e-3)))

    @property
    def right(self) -> np.ndarray:
        # forward x up written out: np.cross costs a dozen Python calls, and a frame asks several times
        (fx, fy, fz), (ux, uy, uz) = self.forward, self.up
        return np.array([fy * uz - fz * uy, fz * ux - fx * uz, fx * uy - fy * ux])

    # -- construction ----------------------------------------------------------------------------
    @classmethod
    def look_at(cls, eye, target, up=WORLD_UP, yfov: float = DEFAULT_YFOV, *, znear: float = 0.01,
                zfar: float = 1000.0, name: str = "") -> "ViewCamera":
        """From `eye` towards `target`; yfov in radians. ValueError when eye == target."""
        d = np.asarray(target, np.float64) - np.asarray(eye, np.float64)
        if not np.linalg.norm(d) > 1e-9:
            raise ValueError("eye and target are the same point")
        return cls(eye=eye, forward=d, up=up, yfov=yfov, znear=znear, zfar=zfar, name=name)

    @classmethod
    def from_manifest(cls, entry: Camera) -> "ViewCamera":
        """A camera of the bake manifest (`Bake.model.cameras`, core/manifest.py); its aspect is not used."""
        return cls(eye=entry.eye, forward=entry.forward, up=entry.up, yfov=entry.yfov, znear=entry.znear,
                   zfar=entry.zfar, name=entry.name)

    @classmethod
    def framing(cls, lo, hi, aspect: float = 16 / 9, yfov: float = DEFAULT_YFOV) -> "ViewCamera":
        """A view of the box [lo, hi] from the front (+Z), a little above and to the right,
        far enough that its bounding sphere fits both fields of view."""
        lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
        centre = (lo + hi) / 2
        radius = max(float(np.linalg.norm(hi - lo)) / 2, 1e-3)
        half = min(yfov / 2, math.atan(math.tan(yfov / 2) * aspect))
        distance = radius / math.sin(half)
        direction = _unit((0.35, 0.3, 1.0), (0.0, 0.0, 1.0))
        return cls.look_at(centre + direction * distance, centre, WORLD_UP, yfov,
                           znear=max((distance - radius) * 0.5, distance * 1e-4),
                           zfar=(distance + radius) * 2, name="scene bounds")

    # -- matrices --------------------------------------------------------------------------------
    def view_matrix(self) -> np.ndarray:
        """World -> eye space (camera at the origin looking down -Z)."""
        # Not pyrr's create_look_at: it re-normalises the axes in another order, an ulp off for most cameras.
        f, u, r = self.forward, self.up, self.right
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = r, u, -f
        m[:3, 3] = -m[:3, :3] @ self.eye
        return m.astype(np.float32)

    def projection_matrix(self, aspect: float) -> np.ndarray:
        """Eye -> clip space: the OpenGL perspective matrix (gluPerspective), depth in [-1, 1]."""
        m = pyrr.matrix44.create_perspective_projection(math.degrees(self.yfov), aspect, self.znear, self.zfar,
                                                        dtype=np.float64)
        return m.T.astype(np.float32)  # pyrr's matrices act on row vectors: the transpose of ours

    def view_projection(self, aspect: float) -> np.ndarray:
        return (self.projection_matrix(aspect).astype(np.float64)
                @ self.view_matrix().astype(np.float64)).astype(np.float32)

    def ray_basis(self, aspect: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(forward, right x tan(xfov/2), up x tan(yfov/2)): the ray through NDC (x, y) is
        forward + x right' + y up' -- what the shading pass uses for sky directions."""
        ty = math.tan(self.yfov / 2)
        return self.forward, self.right * ty * aspect, self.up * ty


def gl_bytes(m: np.ndarray) -> bytes:
    """A numpy (4, 4) matrix as GLSL's column-major mat4."""
    return np.ascontiguousarray(np.asarray(m, np.float32).T).tobytes()


def depth_distances(depth: np.ndarray, camera: "ViewCamera", aspect: float, k: int, empty: float) -> np.ndarray:
    """(H / k, W / k) float64 distances in metres from the eye, of an (H, W) window-space depth
    buffer of `camera` (GL rows: row 0 at the bottom, kept), each the mean over the k x k pixels of
    its block that hit a surface (depth < 1), `empty` where none did. A pixel's distance is the
    eye-space depth of camera.glsl's `eye_depth` times the length of its ray per unit of depth,
    |forward + x right' + y up'| (the three orthogonal, |forward| = 1; `ray_basis`)."""
    d = np.asarray(depth, np.float64)
    h, w = d.shape
    n, f = camera.znear, camera.zfar
    z_eye = 2.0 * n * f / np.maximum(f + n - (2.0 * d - 1.0) * (f - n), 1e-30)
    _, right, up = camera.ray_basis(aspect)
    x = (np.arange(w) + 0.5) / w * 2.0 - 1.0
    y = (np.arange(h) + 0.5) / h * 2.0 - 1.0
    per_depth = np.hypot(1.0, np.hypot(y[:, None] * np.linalg.norm(up), x[None, :] * np.linalg.norm(right)))
    hit = (d < 1.0).reshape(h // k, k, w // k, k)
    total = np.where(hit, (z_eye * per_depth).reshape(hit.shape), 0.0).sum(axis=(1, 3))
    count = hit.sum(axis=(1, 3))
    return np.divide(total, count, out=np.full(count.shape, float(empty)), where=count > 0)


# -- frustum culling ----------------------------------------------------------------------------------
def frustum_planes(view_proj: np.ndarray) -> np.ndarray:
    """The six planes (6, 4) of an OpenGL view-projection (Gribb & Hartmann), inside where
    dot(plane, (x, 1)) >= 0: -w <= x, y, z <= w in clip space; order left, right, bottom, top,
    near, far. Not normalised."""
    r0, r1, r2, r3 = np.asarray(view_proj, np.float64)
    return np.array([r3 + r0, r3 - r0, r3 + r1, r3 - r1, r3 + r2, r3 - r2])


def in_frustum(bounds: np.ndarray, view_proj: np.ndarray) -> bool:
    """False only when the box [lo, hi] certainly lies outside the view of `view_proj`: wholly
    beyond one of its planes (`frustum_planes`), tested with the box corner farthest along the
    plane's normal. Conservative: a box off a frustum edge or corner may count as inside. A box
    behind the eye is beyond the near plane."""
    return bool(boxes_in_frustum(np.asarray(bounds, np.float64)[None], view_proj)[0])


def boxes_in_frustum(bounds: np.ndarray, view_proj: np.ndarray) -> np.ndarray:
    """`in_frustum` of (N, 2, 3) boxes [lo, hi] at once: (N,) bool."""
    planes = frustum_planes(view_proj)
    boxes = np.asarray(bounds, np.float64).reshape(-1, 2, 3)
    farthest = np.where(planes[None, :, :3] >= 0, boxes[:, None, 1], boxes[:, None, 0])  # (N, 6, 3)
    return ~np.any(np.einsum("pj,npj->np", planes[:, :3], farthest) + planes[:, 3] < 0, axis=1)


# -- camera paths ---------------------------------------------------------------------------------
def path_span(path: CameraPath) -> tuple[float, float]:
    return float(path.keys[0].time), float(path.keys[-1].time)


def camera_path_at(path: CameraPath, t: float, *, yfov: float = DEFAULT_YFOV, znear: float = 0.01,
                   zfar: float = 1000.0) -> ViewCamera:
    """The camera of a manifest camera path (core/manifest.py `CameraPath`: keys of time, eye, target[, yfov]) at time t.

    Eye and target each follow a Catmull-Rom spline through the keys, in the form
    for uneven key times: a cubic Hermite segment per pair of keys with tangents
    m_i = (p_{i+1} - p_{i-1}) / (t_{i+1} - t_{i-1}), so the path passes through every
    key with a continuous velocity. At the ends the tangent is the one-sided
    difference, unless the path is closed (its last key repeats the first), where
    it wraps around so a looping tour has no kink. The field of view is
    interpolated linearly (keys without one use `yfov`); up is world +Y. t is
    clamped to the keys' time span.
    """
    keys = path.keys
    times = np.array([k.time for k in keys], np.float64)
    eyes = np.array([k.eye for k in keys], np.float64)
    targets = np.array([k.target for k in keys], np.float64)
    fovs = np.array([yfov if k.yfov is None else k.yfov for k in keys], np.float64)
    name = path.name
    if len(keys) == 1:
        return ViewCamera(eyes[0], targets[0] - eyes[0], WORLD_UP, fovs[0], znear, zfar, name)
    t = float(np.clip(t, times[0], times[-1]))
    i = int(np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(keys) - 2))
    closed = (len(keys) > 2 and np.allclose(eyes[0], eyes[-1]) and np.allclose(targets[0], targets[-1]))
    h = times[i + 1] - times[i]
    s = (t - times[i]) / h
    eye = _hermite(eyes, times, i, s, closed)
    target = _hermite(targets, times, i, s, closed)
    fov = (1 - s) * fovs[i] + s * fovs[i + 1]
    fallback = _unit(targets[i] - eyes[i], _unit(targets[i + 1] - eyes[i + 1], (0.0, 0.0, -1.0)))
    return ViewCamera(eye, _unit(target - eye, fallback), WORLD_UP, fov, znear, zfar, name)


def _tangent(p: np.ndarray, times: np.ndarray, i: int, closed: bool) -> np.ndarray:
    n = len(p) - 1
    if 0 < i < n:
        return (p[i + 1] - p[i - 1]) / (times[i + 1] - times[i - 1])
    if closed:  # keys 0 and n are the same point: difference across the seam
        return (p[1] - p[n - 1]) / ((times[1] - times[0]) + (times[n] - times[n - 1]))
    return (p[1] - p[0]) / (times[1] - times[0]) if i == 0 else (p[n] - p[n - 1]) / (times[n] - times[n - 1])


def _hermite(p: np.ndarray, times: np.ndarray, i: int, s: float, closed: bool) -> np.ndarray:
    h = times[i + 1] - times[i]
    m0, m1 = _tangent(p, times, i, closed) * h, _tangent(p, times, i + 1, closed) * h
    s2, s3 = s * s, s * s * s
    return ((2 * s3 - 3 * s2 + 1) * p[i] + (s3 - 2 * s2 + s) * m0
            + (-2 * s3 + 3 * s2) * p[i + 1] + (s3 - s2) * m1)


def find_named(entries: list, name: str, what: str = "camera", none: str = "the scene has no cameras"):
    """The entry called `name` (anything with a `.name`: a manifest or a scene camera or camera path),
    or a one-line GlintError listing the names there are."""
    entry = next((e for e in entries if e.name == name), None)
    if entry is None:
        have = ", ".join(e.name for e in entries)
        raise GlintError(f"unknown {what} '{name}'; " + (f"the scene has: {have}" if have else none))
    return entry


def scene_bounds(manifest: Manifest) -> tuple[np.ndarray, np.ndarray]:
    """The box round every object with triangles in a bake manifest (a unit cube round the origin
    when there is none)."""
    boxes = np.array([o.bounds for o in manifest.objects if o.triangles], np.float64)
    if not len(boxes):
        return np.full(3, -1.0), np.full(3, 1.0)
    return boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)


def clip_range(manifest: Manifest, eye=None) -> tuple[float, float]:
    """Near and far planes for views the scene does not define: far enough to hold the whole
    scene from wherever the eye is (at least 1 km); near 1 cm, less in a scene under 2 m across
    (1 % of its radius: a 1 mm model still shows) and 2e-5 of its reach in one over about 1 km (so
    24-bit depth still separates its surfaces: glint bench --stress, the 10 km room)."""
    lo, hi = scene_bounds(manifest)
    centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
    reach = radius * 2 + (float(np.linalg.norm(np.asarray(eye) - centre)) if eye is not None else 0.0)
    return max(min(0.01, 0.01 * radius), 2e-5 * reach), max(1000.0, 2 * reach)
