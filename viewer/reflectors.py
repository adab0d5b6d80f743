"""Which planar reflectors get a mirror pass this frame (section 4.5.1; docs/VIEWER.md, "Passes").

`plan_mirror_passes(reflectors, camera, aspect, ...)` decides, per frame, on the
CPU and in this order:

1. outside the view frustum (the reflector's world bounds against the six planes
   of the real camera's view-projection; behind the camera counts as outside)
   -> skipped, `SkipReason.OUTSIDE_FRUSTUM`;
2. seen from behind or edge-on (the eye not strictly on the normal's side of the
   plane) -> `SkipReason.BACK_FACING`;
3. hidden according to the latest occlusion-query result the renderer recorded
   in an `OcclusionResults` -> `SkipReason.OCCLUDED`;
4. the survivors are grouped by plane (`viewer.mirror_camera.group_coplanar`):
   one pass per group, ordered largest projected screen area first (the
   members' bounds, clipped to the screen, summed, capped at the full screen),
   then nearest (eye-to-bounds distance); the first `budget` groups run, the
   members of the rest are skipped with `SkipReason.OVER_BUDGET`.

The result is a `MirrorPlan`: `passes` (plane, members, mirrored camera) and
`skipped` (reflector, reason); `stats()` / `summary()` give "passes run and
skipped" per reason for `--stats`.

Guard band
----------
A lobe sample of a reflector pixel near the border of the view looks past the
border of a mirror buffer that shows the view's own field: with the buffer
clamped to its edge, a wide lobe there would read the edge texels instead of what
its directions see. So each pass widens its frustum by the reach of its widest
lobe (`lobe_reach`: twice the half-vector angle of the lobe border, Eq. 4.10,
the angle a reflected direction turns by at normal view), `guard_scale`: the
projection's x and y are divided by s >= 1, the buffer keeps its pixel count
(coarser by s; wide lobes read coarse MIP levels anyway).
`MirrorPass.view_projection` is what the pass renders and the shaders project with.

s is capped at GUARD_MAX_SCALE = 2: a wider band makes the buffer coarser for
every lobe of the pass, and past 2 that cost the glossy lobes more than it gained
the widest ones (measured on planar-classes: docs/BENCHMARKS.md, "The mirror
buffers' guard band").

Occlusion queries (the GL side is the renderer's)
-------------------------------------------------
The mirror passes run before the G-buffer, so this frame's depth is not there
yet: the planner uses the results of the previous frame. Each frame the renderer
issues one query per reflector in `MirrorPlan.queries` (every reflector in the
frustum and facing the eye, including those skipped as occluded, so they can
come back): after the G-buffer, draw the reflector's own triangles with depth
test on and colour/depth writes off inside a
`GL_ANY_SAMPLES_PASSED_CONSERVATIVE` (or `GL_SAMPLES_PASSED`) query. At the
start of the next frame, for each query whose result is available (never wait),
call `OcclusionResults.record(name, samples, frame)`; unavailable results keep
the older value. A reflector is treated as occluded only with a recorded zero no
older than `max_age` frames; unknown means visible. A reflector that becomes
visible after being hidden misses its reflection for one frame (the usual cost
of reading queries a frame late instead of stalling).
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np

from glint.core.bsdf import theta_thresh
from glint.core.geometry import plane_of
from glint.viewer.camera import ViewCamera, boxes_in_frustum
from glint.viewer.mirror_camera import GROUP_ANGLE_DEG, GROUP_OFFSET, MIN_EYE_HEIGHT, MirrorCamera, group_coplanar

DEFAULT_BUDGET = 4  # mirror passes per frame
GUARD_MAX_HALF_ANGLE = np.radians(80.0)  # the widened half field of view at most (tan 80 deg = 5.7)
GUARD_MAX_SCALE = 2.0  # and the scale at most (module doc, "Guard band")


class SkipReason(str, enum.Enum):
    OUTSIDE_FRUSTUM = "outside frustum"
    BACK_FACING = "seen from behind"
    OCCLUDED = "occluded"
    OVER_BUDGET = "over budget"


@dataclass(frozen=True, eq=False)
class Reflector:
    """A planar reflector: its plane (point, unit normal on its reflecting side),
    world bounds (2, 3) [lo, hi] and area (m^2, informational)."""

    name: str
    point: np.ndarray
    normal: np.ndarray
    bounds: np.ndarray
    area: float = 0.0
    reach: float = 0.0  # radians: how far its widest lobe turns from the mirror direction (`lobe_reach`)

    def __post_init__(self):
        n = np.asarray(self.normal, np.float64).reshape(3)
        object.__setattr__(self, "point", np.asarray(self.point, np.float64).reshape(3))
        object.__setattr__(self, "normal", n / np.linalg.norm(n))
        object.__setattr__(self, "bounds", np.asarray(self.bounds, np.float64).reshape(2, 3))

    @classmethod
    def from_object(cls, obj) -> "Reflector":
        """From a `glint.core.scene.Object` whose role is `planar` (plane by `glint.core.geometry.plane_of`)."""
        point, normal = plane_of(obj)
        return cls(obj.name, point, normal, obj.bounds, obj.area)


# -- occlusion -------------------------------------------------------------------------------------
@dataclass
class OcclusionResults:
    """Latest occlusion-query result per reflector name (see the module docstring)."""

    max_age: int = 2  # frames a zero result is trusted
    _latest: dict[str, tuple[int, int]] = field(default_factory=dict)  # name -> (samples, frame)

    def record(self, name: str, samples_passed: int | bool, frame: int) -> None:
        self._latest[name] = (int(samples_passed), int(frame))

    def forget(self, name: str | None = None) -> None:
        """Drop one result, or all (e.g. after a scene reload)."""
        if name is None:
            self._latest.clear()
        else:
            self._latest.pop(name, None)

    def occluded(self, name: str, frame: int) -> bool:
        entry = self._latest.get(name)
        return entry is not None and entry[0] == 0 and frame - entry[1] <= self.max_age


# -- the plan ----------------------------------------------------------------------------------------
@dataclass
class MirrorPass:
    """One mirror pass: the plane (normal towards the eye), the reflectors sharing it,
    the mirrored camera, and the numbers it was ordered by."""

    point: np.ndarray
    normal: np.ndarray
    members: list[Reflector]
    camera: MirrorCamera
    screen_area: float  # fraction of the screen, [0, 1]
    distance: float  # m, eye to the nearest member's bounds
    guard: float = 1.0  # the guard band's scale s (module doc, `guard_scale`)

    @property
    def names(self) -> list[str]:
        return [r.name for r in self.members]

    def view_projection(self, aspect: float) -> np.ndarray:
        """float32 world -> clip of the pass: the mirrored camera's P V R with x and y divided by
        the guard scale (a wider frustum, the same depth)."""
        guard = np.diag([1.0 / self.guard, 1.0 / self.guard, 1.0, 1.0])
        return (guard @ self.camera.view_projection(aspect).astype(np.float64)).astype(np.float32)


def lobe_reach(mx: float, my: float) -> float:
    """Radians a reflection lobe's directions turn from its mirror direction at most, at normal
    view: twice theta_thresh of Eq. 4.10 along its wider axis, atan(sqrt(-ln xi1_border) m)."""
    m = max(float(mx), float(my), 0.0)
    return 2.0 * float(theta_thresh(0.0, m, m)) if m > 0 else 0.0


def guard_scale(camera: ViewCamera, aspect: float, reach: float) -> float:
    """The guard band's scale s >= 1 (module doc): the half fields of view, each widened by
    `reach` up to GUARD_MAX_HALF_ANGLE, over the view's, the larger of x and y (s keeps the
    buffer's pixels square), at most GUARD_MAX_SCALE."""
    ty = float(np.tan(camera.yfov / 2.0))
    scale = 1.0
    for t in (ty, ty * float(aspect)):
        wide = min(float(np.arctan(t)) + max(float(reach), 0.0), GUARD_MAX_HALF_ANGLE)
        scale = max(scale, float(np.tan(wide)) / t)
    return min(scale, GUARD_MAX_SCALE)


# Pixels added on every side of a scissored mirror pass's rectangle (`scissor_rect`) beyond its members'
# lobe reach: the bilinear look-up and a few MIP levels' texels.
SCISSOR_MARGIN = 8


def scissor_rect(p: MirrorPass, aspect: float, size: tuple[int, int], yfov: float) -> tuple[int, int, int, int] | None:
    """(x, y, width, height) in the pass's mirror-buffer pixels (GL: y from the bottom) that the pass's
    look-ups are estimated to reach: its members' bounds projected with the pass's view-projection, each
    axis's extent widened by their widest lobe's reach as an angle seen from the mirrored eye (a ray
    leaving a reflector point at an angle theta to its mirror direction is seen at less than theta
    from that point), plus SCISSOR_MARGIN pixels; None where that is the whole buffer or a corner lies
    behind the mirrored eye. An estimate, not a bound: a look-up's MIP level can read beyond it
    (docs/VIEWER.md, "Mirror passes in a rectangle")."""
    w, h = int(size[0]), int(size[1])
    lo = np.min([np.asarray(r.bounds, np.float64)[0] for r in p.members], axis=0)
    hi = np.max([np.asarray(r.bounds, np.float64)[1] for r in p.members], axis=0)
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    clip = corners @ np.asarray(p.view_projection(aspect), np.float64).T
    if not np.all(clip[:, 3] > 1e-6):
        return None
    ndc = clip[:, :2] / clip[:, 3:4]
    reach = min(max(r.reach for r in p.members), GUARD_MAX_HALF_ANGLE)
    limit = np.radians(89.0)
    out = []
    for axis, pixels, half in ((0, w, np.tan(yfov / 2.0) * aspect * p.guard), (1, h, np.tan(yfov / 2.0) * p.guard)):
        a0 = max(np.arctan(ndc[:, axis].min() * half) - reach, -limit)  # angles from the axis, widened
        a1 = min(np.arctan(ndc[:, axis].max() * half) + reach, limit)
        n0, n1 = np.tan(a0) / half, np.tan(a1) / half
        out.append((max(int(np.floor((n0 + 1.0) / 2.0 * pixels)) - SCISSOR_MARGIN, 0),
                    min(int(np.ceil((n1 + 1.0) / 2.0 * pixels)) + SCISSOR_MARGIN, pixels)))
    (x0, x1), (y0, y1) = out
    if x1 <= x0 or y1 <= y0 or (x0, y0, x1, y1) == (0, 0, w, h):
        return None
    return x0, y0, x1 - x0, y1 - y0


@dataclass
class Skipped:
    reflector: Reflector
    reason: SkipReason


@dataclass
class MirrorPlan:
    passes: list[MirrorPass]
    skipped: list[Skipped]
    queries: list[Reflector]  # issue an occlusion query for each this frame
    budget: int
    passes_over_budget: int = 0  # groups (would-be passes) left out by the budget

    def pass_for(self, name: str) -> int | None:
        """Index of the pass whose mirror buffer reflector `name` samples, or None."""
        for i, p in enumerate(self.passes):
            if name in p.names:
                return i
        return None

    def skipped_by_reason(self) -> dict[SkipReason, list[str]]:
        out: dict[SkipReason, list[str]] = {r: [] for r in SkipReason}
        for s in self.skipped:
            out[s.reason].append(s.reflector.name)
        return out

    def stats(self) -> dict:
        """For `--stats`: passes run, reflectors they cover, reflectors skipped per reason
        (over-budget counts reflectors; `passes_over_budget` counts the passes)."""
        by = self.skipped_by_reason()
        return {
            "passes_run": len(self.passes),
            "reflectors_in_passes": sum(len(p.members) for p in self.passes),
            "skipped": {r.value: len(names) for r, names in by.items()},
            "passes_over_budget": self.passes_over_budget,
            "budget": self.budget,
        }

    def summary(self) -> str:
        s = self.stats()
        parts = ", ".join(f"{n} {reason}" for reason, n in s["skipped"].items())
        return f"mirror passes: {s['passes_run']} run ({s['reflectors_in_passes']} reflectors); skipped: {parts}"


# -- geometry helpers --------------------------------------------------------------------------------
_CORNERS = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
_EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]


def box_distance(bounds: np.ndarray, x: np.ndarray) -> float:
    lo, hi = np.asarray(bounds, np.float64)
    return float(np.linalg.norm(np.maximum(0.0, np.maximum(lo - x, x - hi))))


def projected_area(bounds: np.ndarray, view_proj: np.ndarray, w_min: float = 1e-6) -> float:
    """Fraction of the screen covered by the screen-space bounding rectangle of the box,
    after clipping the box's edges at w = w_min (in front of the eye); in [0, 1]."""
    lo, hi = np.asarray(bounds, np.float64)
    corners = np.where(_CORNERS, hi, lo)
    m = np.asarray(view_proj, np.float64)
    clip = corners @ m[:, :3].T + m[:, 3]
    pts = [clip[i] for i in range(8) if clip[i, 3] > w_min]
    for a, b in _EDGES:
        wa, wb = clip[a, 3], clip[b, 3]
        if (wa > w_min) != (wb > w_min):
            t = (w_min - wa) / (wb - wa)
            pts.append(clip[a] + t * (clip[b] - clip[a]))
    if not pts:
        return 0.0
    p = np.array(pts)
    ndc = np.clip(p[:, :2] / p[:, 3:4], -1.0, 1.0)
    ext = ndc.max(axis=0) - ndc.min(axis=0)
    return float(ext[0] * ext[1] / 4.0)


# -- the planner -------------------------------------------------------------------------------------
def plan_mirror_passes(reflectors: Sequence[Reflector], camera: ViewCamera, aspect: float, *,
                       budget: int = DEFAULT_BUDGET, occlusion: OcclusionResults | None = None,
                       frame: int = 0, angle_deg: float = GROUP_ANGLE_DEG,
                       offset: float = GROUP_OFFSET) -> MirrorPlan:
    """This frame's mirror passes; see the module docstring for the rules and their order."""
    vp = camera.view_projection(aspect).astype(np.float64)
    eye = camera.eye
    skipped: list[Skipped] = []
    queries: list[Reflector] = []
    alive: list[Reflector] = []
    visible = boxes_in_frustum([r.bounds for r in reflectors], vp) if reflectors else []
    for r, seen in zip(reflectors, visible):
        if not seen:
            skipped.append(Skipped(r, SkipReason.OUTSIDE_FRUSTUM))
            continue
        if not float((eye - r.point) @ r.normal) > MIN_EYE_HEIGHT:
            skipped.append(Skipped(r, SkipReason.BACK_FACING))
            continue
        queries.append(r)
        if occlusion is not None and occlusion.occluded(r.name, frame):
            skipped.append(Skipped(r, SkipReason.OCCLUDED))
            continue
        alive.append(r)

    area = {id(r): projected_area(r.bounds, vp) for r in alive}
    groups = group_coplanar([(i, r.point, r.normal) for i, r in enumerate(alive)],
                            [area[id(r)] for r in alive], angle_deg=angle_deg, offset=offset)
    candidates = []
    for g in groups:
        members = [alive[i] for i in sorted(g.keys)]
        screen = min(1.0, sum(area[id(r)] for r in members))
        dist = min(box_distance(r.bounds, eye) for r in members)
        candidates.append((screen, dist, g, members))
    candidates.sort(key=lambda c: (-c[0], c[1]))

    passes: list[MirrorPass] = []
    over = 0
    for screen, dist, g, members in candidates:
        if len(passes) >= max(int(budget), 0):
            skipped.extend(Skipped(r, SkipReason.OVER_BUDGET) for r in members)
            over += 1
            continue
        # The group's plane, oriented towards the eye (every member faces it).
        normal = g.normal if float((eye - g.point) @ g.normal) > 0 else -g.normal
        try:
            mirror = MirrorCamera(camera, g.point, normal)
        except ValueError:  # the averaged plane passes through the eye: edge-on
            skipped.extend(Skipped(r, SkipReason.BACK_FACING) for r in members)
            continue
        guard = guard_scale(camera, aspect, max(r.reach for r in members))
        passes.append(MirrorPass(mirror.point, mirror.normal, members, mirror, screen, dist, guard))
    return MirrorPlan(passes=passes, skipped=skipped, queries=queries, budget=int(budget),
                      passes_over_budget=over)


def reflectors_of(objects: Iterable) -> list[Reflector]:
    """`Reflector`s of the `planar` objects among `objects` (glint.core.scene.Object)."""
    return [Reflector.from_object(o) for o in objects if getattr(o, "role", None) == "planar"]
