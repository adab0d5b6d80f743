"""Numpy reference of the mirror-buffer sample projection (sections 4.5.2, 4.5.3).

The GLSL of the shading pass is to be tested against these functions. Everything
is float64 and vectorised: leading dimensions of points and directions broadcast.

Geometry
--------
The mirror buffer of a reflector plane is rendered with the mirrored camera's
view-projection `VP_m = G P V R` (`viewer.reflectors.MirrorPass.view_projection`: the
mirrored camera's P V R of `viewer.mirror_camera.MirrorCamera.view_projection`, and G
the guard band, x and y divided by its scale s >= 1): R is already inside, so *world* points of the (unmirrored) scene are projected
with `VP_m` directly -- do not reflect them again. The buffer's position and
normal images hold those world points and their world normals.

Why this is right: the ray from P along w reaches the scene at P_I = P + t w.
The mirrored camera sees the unmirrored scene through the plane as through a
window (its view matrix is V R: a point X is drawn where the real camera would
see R X), so P_I is looked up at `VP_m P_I`, with no further reflection. For the
mirror direction w_r = R_lin (P - E) / |P - E| (E the real eye), the mirrored eye
R E, P and P_R are collinear, and since R P = P, `P V R P = VP P`: the centre
(mirror) sample of a reflector pixel reads the mirror buffer at that pixel's own
screen position when s = 1; with a guard band the buffer shows a field s times
wider at the same pixel count, so it reads at (uv - 1/2) / s + 1/2 of it, s times
coarser.

Two-step projection of a lobe sample w at reflector point P (section 4.5.2):
0. centre: look up the buffer at P's projection -> P_R, n_R (the scene point hit
   by the mirror direction and its normal);
1. intersect P + t w with the tangent plane (P_R, n_R) -> P_I1, project -> uv1;
2. look up position and normal at uv1, intersect P + t w with that plane ->
   P_I2, project -> uv2: the final look-up position.

Texture conventions (OpenGL)
----------------------------
uv = ndc * 0.5 + 0.5; uv (0, 0) is the outer corner of texel (row 0, column 0),
the first texel row/column of the GL texture (ndc y = -1, the bottom of the
image). Images are numpy (H, W, C) arrays indexed [row, column] in that same order
(row 0 first, as `glReadPixels` / moderngl's `fbo.read` return them: no flip).
Texel (col, row) has its centre at ((col + 0.5) / W, (row + 0.5) / H). Look-ups of
position and normal are nearest-texel (`texelFetch(ivec2(floor(uv * size)))`)
with clamp-to-edge. A background texel (nothing drawn) has normal (0, 0, 0): any
normal shorter than 0.5 counts as background. Step 2 meeting background takes the
ray to infinity (its direction is projected, w = 0) where step 1 hit no plane or the
direction's own uv is background too (the sky along w); else step 1's look-up (the
background there) stands, so the ray does not pick up what its direction meets beyond the
plane it already passed.

Failure handling (what the GLSL must mirror, no NaN/Inf anywhere):
* the ray parallel to a tangent plane (|w . n| <= 1e-8) or the plane behind P
  (t <= 0) -> that step has no hit: step 1 falls back to the direction at
  infinity, step 2 keeps step 1's result;
* a point or direction that projects behind the mirror camera (clip w <= 1e-9)
  -> `valid` False and uv falls back to the centre sample's uv.
Samples below the reflector's horizon (w . n_reflector <= 0) are the caller's to
drop before projecting.

MIP level (section 4.5.3)
-------------------------
`lobe_mip_level`: project the lobe's four extreme directions (both ends of its two
axes) with the same two steps; they are taken as the end points of two conjugate
diameters of an ellipse in the buffer, area pi |a x b| in pixels (a, b the
semi-diameter vectors; the thesis' pi a b when they are perpendicular), divided
by the sample count: level = log4(area / n), clamped to [0, max level].

Per sample (`sample_mip_level`, what the shading pass uses): one level for a
whole lobe over-blurs where the projection stretches unevenly across it (the
buffer's texels per steradian change with the distance and slant of what each
sample sees, and with the guard band's coarser texels). So each sample's level
is its share of the lobe's solid angle (A / n, Eq. 4.14-4.15, or 1 / (n p) for
filtered importance sampling) times the texels per steradian at its own look-up
(`texels_per_steradian`, the planar counterpart of Eq. 4.16's d^2 / cos beta):
the Jacobian of the two-step map w -> uv, taken in the plane that the final step
hit (X = P + t w moves by t (dw - (dw . n) / (w . n) w)) or, at infinity, of the
projected direction itself.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

BACKGROUND_NORMAL = 0.5  # normals shorter than this mark background texels
PARALLEL_EPS = 1e-8  # |w . n| below this: the ray is parallel to the plane
W_EPS = 1e-9  # clip w below this: behind the mirror camera


def _f64(x) -> np.ndarray:
    return np.asarray(x, np.float64)


def project(view_proj, x, homogeneous_w: float | np.ndarray = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """World points (w = 1) or directions (w = 0) (..., 3) -> (uv (..., 2), ok (...)).

    ok is False where the clip-space w is not positive (behind the camera); uv is
    then finite but meaningless (0.5, 0.5)."""
    x = _f64(x)
    hw = np.broadcast_to(_f64(homogeneous_w), x.shape[:-1])[..., None]
    clip = np.concatenate([x, hw], axis=-1) @ _f64(view_proj).T
    w = clip[..., 3]
    ok = w > W_EPS
    safe = np.where(ok, w, 1.0)[..., None]
    ndc = np.where(ok[..., None], clip[..., :2] / safe, 0.0)
    return ndc * 0.5 + 0.5, ok


def texel_index(uv, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """uv (..., 2) -> (row, col) int arrays of the nearest texel, clamped to the image.
    size is (H, W)."""
    h, w = size
    uv = _f64(uv)
    col = np.clip(np.floor(uv[..., 0] * w), 0, w - 1).astype(np.int64)
    row = np.clip(np.floor(uv[..., 1] * h), 0, h - 1).astype(np.int64)
    return row, col


def fetch(image: np.ndarray, uv) -> np.ndarray:
    """Nearest-texel, clamp-to-edge look-up of an (H, W, C) image at uv (..., 2) -> (..., C)."""
    row, col = texel_index(uv, image.shape[:2])
    return _f64(image[row, col])


def texel_centres(size: tuple[int, int]) -> np.ndarray:
    """(H, W, 2) uv of every texel centre."""
    h, w = size
    u = (np.arange(w) + 0.5) / w
    v = (np.arange(h) + 0.5) / h
    uu, vv = np.meshgrid(u, v)
    return np.stack([uu, vv], axis=-1)


def unproject_rays(view_proj, uv) -> tuple[np.ndarray, np.ndarray]:
    """Rays through uv (..., 2) of a camera with this view-projection -> (origin on the
    near plane, unit direction), world space. For building reference mirror buffers."""
    inv = np.linalg.inv(_f64(view_proj))
    ndc = _f64(uv) * 2.0 - 1.0
    ones = np.ones(ndc.shape[:-1] + (1,))
    near = np.concatenate([ndc, -ones, ones], axis=-1) @ inv.T
    far = np.concatenate([ndc, ones, ones], axis=-1) @ inv.T
    near = near[..., :3] / near[..., 3:]
    far = far[..., :3] / far[..., 3:]
    d = far - near
    return near, d / np.linalg.norm(d, axis=-1, keepdims=True)


def intersect_plane(origin, direction, plane_point, plane_normal) -> tuple[np.ndarray, np.ndarray]:
    """Ray origin + t direction against the plane -> (t, hit); hit needs a non-background
    normal, |direction . n| > PARALLEL_EPS and t > 0. t is 0 where there is no hit."""
    o, d, p, n = map(_f64, (origin, direction, plane_point, plane_normal))
    nn = np.linalg.norm(n, axis=-1)
    denom = np.sum(d * n, axis=-1)
    usable = (nn >= BACKGROUND_NORMAL) & (np.abs(denom) > PARALLEL_EPS * np.maximum(nn, 1.0))
    t = np.where(usable, np.sum((p - o) * n, axis=-1) / np.where(usable, denom, 1.0), 0.0)
    hit = usable & (t > 0) & np.isfinite(t)
    return np.where(hit, t, 0.0), hit


@dataclass
class SampleProjection:
    """Result of `project_sample` (arrays broadcast over the inputs' leading dimensions)."""

    uv: np.ndarray  # (..., 2) final mirror-buffer look-up position (after step 2 when asked)
    valid: np.ndarray  # (...) the final position is in front of the mirror camera
    point: np.ndarray  # (..., 3) estimate of P_I behind uv (P + t w; undefined where at infinity)
    at_infinity: np.ndarray  # (...) uv is the projected direction (no plane hit)
    uv_first: np.ndarray  # (..., 2) after step 1
    point_first: np.ndarray  # (..., 3)
    hit_first: np.ndarray  # (...) step 1 hit the tangent plane of P_R
    hit_second: np.ndarray  # (...) step 2 hit the plane looked up at uv_first
    uv_centre: np.ndarray  # (..., 2) P projected: where P_R was read
    t: np.ndarray  # (...) uv's point is P + t w (0: at infinity) ...
    normal: np.ndarray  # (..., 3) ... in the plane with this normal (the one its step hit)


def _step(P, w, plane_p, plane_n, vp):
    t, hit = intersect_plane(P, w, plane_p, plane_n)
    x = P + t[..., None] * w
    uv_pt, ok_pt = project(vp, x, 1.0)
    uv_dir, ok_dir = project(vp, w, 0.0)
    uv = np.where(hit[..., None], uv_pt, uv_dir)
    ok = np.where(hit, ok_pt, ok_dir)
    return uv, ok, x, hit, t


def project_sample(P, w, mirror_view_proj, positions: np.ndarray, normals: np.ndarray, *,
                   second_step: bool = True, third_step: bool = False, centre_position=None,
                   centre_normal=None) -> SampleProjection:
    """Map lobe sample directions w (..., 3, unit, world) at reflector points P (..., 3)
    to mirror-buffer uv by the two-step tangent-plane scheme (module docstring); `third_step`:
    where step 2 hit a drawn plane, once more in the plane seen at step 2's uv, taken where it hits
    a drawn plane (shaders/mirror_buffer.glsl: the still camera's look-ups).

    mirror_view_proj: the mirror camera's world -> clip matrix (reflection included).
    positions, normals: the mirror buffer's (H, W, 3) world position and normal images.
    centre_position / centre_normal: P_R and its normal when the caller already has
    them; by default they are read at P's projection.
    """
    vp = _f64(mirror_view_proj)
    P, w = np.broadcast_arrays(_f64(P), _f64(w))
    uv_c, ok_c = project(vp, P, 1.0)
    p_r = fetch(positions, uv_c) if centre_position is None else np.broadcast_to(_f64(centre_position), P.shape)
    n_r = fetch(normals, uv_c) if centre_normal is None else np.broadcast_to(_f64(centre_normal), P.shape)

    uv1, ok1, x1, hit1, t1 = _step(P, w, p_r, n_r, vp)
    if second_step:
        p2, n2 = fetch(positions, uv1), fetch(normals, uv1)
        uv2, ok2, x2, hit2, t2 = _step(P, w, p2, n2, vp)
        background = np.linalg.norm(n2, axis=-1) < BACKGROUND_NORMAL
        # Background at step 1's point: the ray passes that plane where nothing was drawn; step 1's
        # look-up (the sky there) stands unless the direction at infinity is background too.
        inf_background = np.linalg.norm(fetch(normals, uv2), axis=-1) < BACKGROUND_NORMAL
        background = background & (~hit1 | hit2 | inf_background)
        if third_step:
            p3, n3 = fetch(positions, uv2), fetch(normals, uv2)
            uv3, ok3, x3, hit3, t3 = _step(P, w, p3, n3, vp)
            step3 = hit2 & ~background & hit3 & (np.linalg.norm(n3, axis=-1) >= BACKGROUND_NORMAL)
            uv2 = np.where(step3[..., None], uv3, uv2)
            ok2 = np.where(step3, ok3, ok2)
            x2 = np.where(step3[..., None], x3, x2)
            t2 = np.where(step3, t3, t2)
            n2 = np.where(step3[..., None], n3, n2)
        take = hit2 | background  # a missed (parallel / behind) plane keeps step 1
        uv = np.where(take[..., None], uv2, uv1)
        ok = np.where(take, ok2, ok1)
        x = np.where(hit2[..., None], x2, x1)
        at_inf = np.where(take, ~hit2, ~hit1)
        t = np.where(take, t2, t1)
        normal = np.where(take[..., None], n2, n_r)
    else:
        uv, ok, x, hit2, at_inf, t, normal = uv1, ok1, x1, np.zeros_like(hit1), ~hit1, t1, n_r
    ok = ok & ok_c
    uv = np.where(ok[..., None], uv, uv_c)
    uv1 = np.where((ok1 & ok_c)[..., None], uv1, uv_c)
    return SampleProjection(uv=uv, valid=ok, point=x, at_infinity=at_inf, uv_first=uv1, point_first=x1,
                            hit_first=hit1, hit_second=hit2, uv_centre=uv_c, t=np.where(at_inf, 0.0, t),
                            normal=np.broadcast_to(normal, P.shape))


# -- MIP level (section 4.5.3) ---------------------------------------------------------------------
def max_mip_level(size: tuple[int, int]) -> int:
    """The last level of a full MIP chain of an (H, W) image."""
    return int(math.floor(math.log2(max(int(size[0]), int(size[1]), 1))))


def ellipse_mip_level(uv_extremes, n_samples: int, size: tuple[int, int], *, conjugate: bool = True,
                      max_level: float | None = None) -> np.ndarray:
    """MIP level from the projected lobe extremes.

    uv_extremes: (..., 4, 2) uv of the lobe's border samples in the order
    (+a, -a, +b, -b) (both ends of the lobe's two axes). The ellipse's semi-diameters
    are a = (uv[+a] - uv[-a]) / 2 and b likewise, in pixels of the (H, W) buffer;
    area = pi |a x b| (conjugate=True: exact for an affine image of a circle) or the
    thesis' pi |a| |b| (conjugate=False). level = log4(area / n_samples), clamped to
    [0, max_level] (default: the chain's last level). Finite for any finite input.
    """
    h, w = size
    e = _f64(uv_extremes) * np.array([w, h], np.float64)
    a = (e[..., 0, :] - e[..., 1, :]) / 2
    b = (e[..., 2, :] - e[..., 3, :]) / 2
    if conjugate:
        area = math.pi * np.abs(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])
    else:
        area = math.pi * np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1)
    per_sample = np.where(np.isfinite(area), area, 0.0) / max(int(n_samples), 1)
    level = 0.5 * np.log2(np.maximum(per_sample, 1.0))
    top = max_mip_level(size) if max_level is None else max_level
    return np.clip(level, 0.0, top)


def lobe_mip_level(P, extremes, n_samples: int, mirror_view_proj, positions: np.ndarray, normals: np.ndarray,
                   *, second_step: bool = True, conjugate: bool = True) -> np.ndarray:
    """Per-pixel MIP level: the lobe's extreme directions (..., 4, 3) at P (..., 3),
    ordered (+a, -a, +b, -b), projected by `project_sample` -> `ellipse_mip_level`."""
    P = _f64(P)[..., None, :]
    proj = project_sample(P, _f64(extremes), mirror_view_proj, positions, normals, second_step=second_step)
    return ellipse_mip_level(proj.uv, n_samples, positions.shape[:2], conjugate=conjugate)


def texels_per_steradian(P, w, proj: SampleProjection, mirror_view_proj, size: tuple[int, int]) -> np.ndarray:
    """Buffer texels per steradian of sample direction at each look-up of `project_sample`
    (module docstring, "per sample"): |det| of the map from the directions around unit w (...,
    3) at P to the pixels of the (H, W) buffer; 0 where the look-up is not valid."""
    vp = _f64(mirror_view_proj)
    P, w = np.broadcast_arrays(_f64(P), _f64(w))
    t = proj.t[..., None]
    finite = t > 0
    x = np.where(finite, P + t * w, w)
    clip = np.concatenate([x, finite.astype(np.float64)], axis=-1) @ vp.T
    cw = clip[..., 3:]
    ok = proj.valid & (cw[..., 0] > W_EPS)
    cw = np.where(ok[..., None], cw, 1.0)
    h, wd = size
    # d(clip_r / clip_w) / dX = (clip_w A_r - clip_r A_w) / clip_w^2, A: vp's xyz columns
    g = [(cw * vp[r, :3] - clip[..., r:r + 1] * vp[3, :3]) * (0.5 * s / cw**2) for r, s in ((0, wd), (1, h))]
    n = proj.normal
    wn = np.sum(w * n, axis=-1, keepdims=True)
    wn = np.where(finite & (wn != 0), wn, 1.0)
    # a point in a plane: dX = t (I - w n^T / (w . n)) dw
    g = [np.where(finite, t * (gr - np.sum(gr * w, axis=-1, keepdims=True) / wn * n), gr) for gr in g]
    det = np.abs(np.sum(np.cross(g[0], g[1]) * w, axis=-1))
    return np.where(ok, det, 0.0)


def sample_mip_level(solid_angle, P, w, proj: SampleProjection, mirror_view_proj, size: tuple[int, int],
                     max_level: float | None = None) -> np.ndarray:
    """Per-sample MIP level: log4(solid_angle * texels_per_steradian), clamped to [0, max_level]
    (default: the chain's last level); that last level where the look-up is not valid or the
    product is not finite."""
    with np.errstate(over="ignore", invalid="ignore"):
        texels = _f64(solid_angle) * texels_per_steradian(P, w, proj, mirror_view_proj, size)
        level = 0.5 * np.log2(np.maximum(np.where(np.isfinite(texels), texels, 1.0), 1.0))
    top = max_mip_level(size) if max_level is None else max_level
    return np.where(proj.valid & np.isfinite(texels), np.clip(level, 0.0, top), top)


def lobe_extremes(centre, axis_a, axis_b, angle_a, angle_b) -> np.ndarray:
    """The four border directions (..., 4, 3) of a lobe around unit `centre`: rotated
    by +-angle_a towards unit `axis_a` and +-angle_b towards `axis_b` (both
    perpendicular to centre), ordered (+a, -a, +b, -b)."""
    c, ua, ub = _f64(centre), _f64(axis_a), _f64(axis_b)
    a = _f64(angle_a)[..., None]
    b = _f64(angle_b)[..., None]
    return np.stack([c * np.cos(a) + ua * np.sin(a), c * np.cos(a) - ua * np.sin(a),
                     c * np.cos(b) + ub * np.sin(b), c * np.cos(b) - ub * np.sin(b)], axis=-2)
