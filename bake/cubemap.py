"""Cube maps of curved and transmissive objects: their incident light (section 4.4.1).

One cubic environment map (a probe) stands for the light arriving anywhere on an object, or on a
few small objects close together (see Probes below): the light-mapped scene rendered from the
object's bounding-box centre without the object itself,
six 90-degree faces, HDR, with the distance from the centre to the visible surface in alpha
(for the bounding-plane and parallax look-ups). Only `curved` and `transmissive` objects get
one; `diffuse` objects need none and `planar` ones use mirror passes (section 4.5).

Rendering (glint/cubemap_stage.py, above both the bake and the viewer, which the pipeline is
handed): the viewer's own renderer (viewer/renderer.py) on a headless EGL context, reading
the bake directory written so far (meshes and light maps), so a cube map shows exactly what
the viewer would. It renders the scene *diffuse*: kd/pi E (Eq. 4.1) plus emission, every lobe
left out, as the thesis renders "the light-mapped scene". No cube map then depends on another
(no order, no chains of re-renders). Left out of each map: the object itself, and every
transmissive object (thin glass): rendered diffuse, clear glass (kd = 0) would be an opaque
black sheet, whereas from most directions it shows what lies behind it. And every object whose
closed surface holds the probe's centre (`holding`; for shared probes `enclosing`): from inside, its
back faces would fill the whole map.

Faces follow the OpenGL cube-map convention, so `texture(samplerCube, dir)` returns the
radiance seen along dir: face k = GL_TEXTURE_CUBE_MAP_POSITIVE_X + k, in the order
+X, -X, +Y, -Y, +Z, -Z, is rendered by a 90-degree camera looking along the face's axis with
the up vector of `FACES`; its right (forward x up) is the direction of increasing s and its up
that of increasing t (the spec's sc/tc table), and the frame read back bottom row first is the
face in glTexImage2D's order (row 0 at t = 0).

File: `cubemaps/<i>.exr` (i: the manifest index of the probe's first object), RGBA, width S, height 6 S: the six faces stacked
vertically in the GL order above, each S x S with its first row at t = 0 and first column at
s = 0 (viewer/cubemaps.py reads it). RGB is radiance W/(m^2 sr); A is the distance in metres
from the centre along the texel's direction to the visible surface (the mean over its 2 x 2
supersamples; one sample on faces over SUPERSAMPLED_FACE_MAX), `SKY_DISTANCE` where only sky shows. Half float unless a value does not fit,
then float32 (glint.core.image_io); never Inf.

Face size S (`automatic_size`), a power of two in `AUTO_SIZE_RANGE`, the smaller of two needs:
- the narrowest lobe: Eq. 4.10 with xi1_border = 0.01 bounds the half vector within
  theta_thresh of its centre, so the reflected lobe (Eq. 4.8 doubles angles) has an angular
  radius of about 2 theta_thresh; a face spans pi/2 over S texels, and the lobe's radius
  should cover `TEXELS_PER_LOBE_RADIUS` = 4 of them: S >= 4 (pi/2) / (2 theta_thresh)
  = pi / theta_thresh. Sharper lobes show finer detail of the environment.
- the object's size: a convex mirror shows a whole face within about a third of its diameter,
  so bigger objects show each texel over more screen pixels. From 1 m away on a 1080-line
  screen with a 50-degree field of view that is about 400 pixels per metre of diameter:
  S >= `FACE_TEXELS_PER_METRE` (400) x the bounding-box diagonal.
In the living-room: the 20 cm chrome sphere (m = 0.0025) gets 256, its size limits it; the
1.9 m frosted-glass screen (m = 0.09) 32, its lobe does; the brushed side table (my = 0.0046,
0.75 m) 512. The sidecar's `[objects."NAME"] cubemap_size` replaces the rule.

Probes (section 4.4.1 extended): one cube map may serve several objects. A probe is one cube map
rendered from one centre with its objects hidden, plus the bounding planes of its box; each object
it serves looks it up from that centre through those planes (viewer/cubemaps.py loads each probe
once, shaders/cubemaps.glsl). Objects the sidecar gives a `cubemap_size` or its own
`bounding_planes` (false or a list), and objects with `shared_probe = false` keep a probe of their
own at their own box centre, as the thesis has it. The other curved and transmissive objects are
clustered (`cluster`): the box of a cluster, of radius r (half its diagonal), is served by one
probe at its centre when for every member

    r <= probe_sharing x max(min(tan(2 theta_thresh(m)), PROBE_RADIUS_MAX), tan((pi / 2) / S)) x D

(`sharing_slope`) with m its narrowest lobe, S the face size its own map would have
(`automatic_size`) and D its clearance (`clearance`): the distance from its box centre to
the nearest of its bounding planes and of the faces of the scene's bounding box (`box_walls`) that
its box does not touch (the walls and ceiling around it, not the floor it stands on), or half the
scene's diagonal where there is none. Why: looked up
from the cluster's centre instead of from the member, a surface at distance D is off by at most
about r / D radians. The planes undo that for the enclosure; for what stands inside it (taken to
be no nearer than D: the rule's approximation) the error stays within the angular radius of the
member's narrowest reflected lobe, 2 theta_thresh (Eq. 4.10, doubled by Eq. 4.8), which blurs
over as much anyway, or within one texel of the member's own map, (pi / 2) / S, which its own map
could not show either (what lets a small glass bead, m = 1e-4 but S = 32, share with its
neighbours). So a large chrome ball (m = 0.0025: 0.011 rad, S = 256) practically never shares, while
rough metal (m = 0.09: 0.38 rad) shares up to `PROBE_RADIUS_MAX` = 0.25 of its clearance, the cap
for wide lobes: it keeps a cluster in the inner half of its enclosure, where one centre still
sees the room much as each member does. An object whose own radius is over its limit cannot
share: large curved objects keep their own probe. A probe's face size is the largest of its
members' (`automatic_size`). What a shared probe gets wrong: its members do not see each other,
and nearby objects are seen from the cluster's centre; an object of the cluster's size or smaller
whose box holds that centre is left out of the probe too (`enclosing`: its inside would fill the
view). A part of an object (bake/probe_parts.py: a mesh spread through rooms, split
where its surface cannot see its probe centre) is an object here; its probe hides all the object's
parts, as an object's own probe hides the object.

The budget ([bake] `cubemap_budget` probes and `cubemap_budget_mib` MiB, counted as RGBA16F with
the MIP chain): with more probes planned, the sharing factor is doubled (at most
`BUDGET_MERGE_STEPS` times) until the count fits; with more MiB, the largest automatic face sizes
are halved (not below `AUTO_SIZE_RANGE`'s smallest) until they fit. Either prints one warning.
Sizes and own probes that the sidecar sets are never changed. Defaults: 2048 probes (six
cube-map arrays at GL 4.3's minimum of 2048 layers; viewer/cubemaps.py splits classes at the
GL limit) and 512 MiB, an eighth of a common 4 GiB graphics card.

A probe's inputs hash (bake/hashing.py `cubemap_hash`) is the light maps' hash plus its first
object, its face size and centre, the hidden objects (its members and thin glass) and the render
settings here: a re-bake renders only the probes whose hash changed and carries the others over
(an object's own probe hashes as its cube map did before probes were shared).

The probes are rendered by glint/cubemap_stage.py, not on the executor's forked workers (a GL
context does not survive fork): on one GL context where there is a GPU, on --jobs spawned
processes with a context each on a software renderer; in batches read back at once. Objects under
SMALL_OBJECT_TEXELS of a face are left out of it; the others are drawn at the coarsest level of
detail that keeps LOD_TRIANGLES_PER_PIXEL.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from glint.bake import hashing
from glint.bake.raytrace import RayTracer
from glint.bake.bounding_planes import (
    ENCLOSE_RELATIVE,
    BoundingPlane,
    box_planes,
    candidate_surfaces,
    choose_planes,
    override_planes,
)
from glint.core.bsdf import M_MIN, theta_thresh
from glint.core.constants import HALF_MAX
from glint.core.errors import warn
from glint.core.scene import Material, Object, Scene

CUBEMAP_ROLES = ("curved", "transmissive")
# GL_TEXTURE_CUBE_MAP_POSITIVE_X + k: (name, camera forward, camera up)
FACES = (("+x", (1, 0, 0), (0, -1, 0)), ("-x", (-1, 0, 0), (0, -1, 0)),
         ("+y", (0, 1, 0), (0, 0, 1)), ("-y", (0, -1, 0), (0, 0, -1)),
         ("+z", (0, 0, 1), (0, -1, 0)), ("-z", (0, 0, -1), (0, -1, 0)))
AUTO_SIZE_RANGE = (32, 512)
TEXELS_PER_LOBE_RADIUS = 4
FACE_TEXELS_PER_METRE = 400.0
SUPERSAMPLE = 2  # per axis: a texel is the mean of 2 x 2 samples ...
# ... on faces up to this size; larger faces take one sample per texel: their texels (under 0.18
# degrees at 512) are finer than any lobe but a near-mirror's, whose look-ups read them through the
# MIP chain anyway, and 2 x 2 samples would make a 512 face a 1024^2 render, 4x the pixel work.
SUPERSAMPLED_FACE_MAX = 256
# Objects (not emitters) whose bounding sphere projects to a radius under this many face texels are
# left out of a face (viewer/draw_list.py): they would cover under a texel, and their triangles are
# most of a probe's cost on a software renderer.
SMALL_OBJECT_TEXELS = 0.5
# The faces draw each object at the coarsest level of detail (viewer/lod.py: halvings of its mesh)
# that keeps this many triangles per rendered pixel (supersamples) of the disc it covers seen from
# the probe: near objects whole, far detail (turned balusters, leaves) coarse, at a sub-pixel error.
LOD_TRIANGLES_PER_PIXEL = 1.0
# Clip planes of the faces, from the distance `far` to the scene's farthest corner (so a 1 mm and
# a 10 km scene get the same picture): zfar = FAR_MARGIN x far, znear = NEAR_PER_FAR x far.
# 24-bit depth then resolves d^2 / (znear 2^24), 6e-4 of far at far; 1 mm at 6 m on a room
# (a fixed 1 mm znear clipped a 1 mm scene and let a 10 km one z-fight: glint bench --stress).
NEAR_PER_FAR = 1e-4
FAR_MARGIN = 1.02
SKY_DISTANCE = HALF_MAX  # alpha where only sky shows: far but finite
PROBE_RADIUS_MAX = 0.25  # a shared probe's radius per clearance, however wide the lobes (docstring)
BUDGET_MERGE_STEPS = 8  # doublings of the sharing factor tried to bring the probes within the budget
MIB_PER_TEXEL = 8 * 4 / 3 / 2 ** 20  # RGBA16F (8 bytes) with its MIP chain (a third more), viewer/cubemaps.py


def supersample(size: int) -> int:
    """Samples per texel side when rendering a face of `size` texels (SUPERSAMPLED_FACE_MAX)."""
    return SUPERSAMPLE if size <= SUPERSAMPLED_FACE_MAX else 1


def narrowest_lobe(material: Material) -> float | None:
    """m of the material's narrowest lobe (min(mx, my), at least M_MIN); None without lobes."""
    widths = [max(min(lobe.mx, lobe.my), M_MIN) for lobe in material.lobes]
    return min(widths) if widths else None


def lobe_radius(material: Material) -> float:
    """Angular radius in radians of the material's narrowest reflected lobe: 2 theta_thresh
    (Eq. 4.10 with xi1_border = 0.01, doubled by the reflection, Eq. 4.8); pi / 2 without lobes.
    Eq. 4.10's phi factor peaks at 1/m^2 where m = min(mx, my), so that is where it is narrowest."""
    m = narrowest_lobe(material)
    return math.pi / 2 if m is None else min(2 * float(theta_thresh(0.0, m, m)), math.pi / 2)


def sharing_slope(material: Material, size: int) -> float:
    """A member's cluster radius per unit of clearance (see "Probes"): the larger of the lobe's
    bound, min(tan(2 theta_thresh(m)), PROBE_RADIUS_MAX), and the face's, tan of one texel of its
    own map ((pi / 2) / S: a direction error its own map of S texels could not show either)."""
    return max(min(math.tan(lobe_radius(material)), PROBE_RADIUS_MAX), math.tan((math.pi / 2) / size))


def automatic_size(obj: Object, material: Material) -> int:
    """Face size from the narrowest lobe and the object's size (see the module docstring)."""
    lo, hi = AUTO_SIZE_RANGE
    # the reflected lobe's radius spans TEXELS_PER_LOBE_RADIUS texels of pi/2 / S
    by_lobe = (TEXELS_PER_LOBE_RADIUS * (math.pi / 2) / lobe_radius(material)
               if narrowest_lobe(material) is not None else math.inf)
    by_size = FACE_TEXELS_PER_METRE * float(np.linalg.norm(obj.bounds[1] - obj.bounds[0]))
    need = min(by_lobe, by_size)
    return int(min(max(2 ** math.ceil(math.log2(max(need, 1.0))), lo), hi))


def clearance(lo: np.ndarray, hi: np.ndarray, planes: list[BoundingPlane], fallback: float) -> float:
    """Distance from the centre of the box lo..hi to the nearest of `planes` that the box does not
    touch (within bounding_planes.py's relative enclosure slack: no absolute length, so that a
    scene's plan does not depend on its scale); `fallback` where no plane is left."""
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    slack = ENCLOSE_RELATIVE * float(np.linalg.norm(hi - lo))
    gaps = [float(np.dot(centre - p.point, p.normal)) for p in planes
            if float(np.dot(centre - p.point, p.normal)) - float(np.abs(p.normal) @ half) > slack]
    return min(gaps) if gaps else float(fallback)


def enclosing(bounds: np.ndarray, centre: np.ndarray, diagonal: float) -> list[int]:
    """Objects (bounds (n, 2, 3)) whose box holds `centre` and is no larger than `diagonal` (a
    shared probe's cluster box): a shared probe's centre may fall inside an object standing among
    its members, whose inside would fill the probe's whole view (black back faces); such objects
    are left out of the probe too. Larger ones (the room around it) are seen from inside as they
    should be."""
    inside = np.all((bounds[:, 0] <= centre) & (centre <= bounds[:, 1]), axis=1)
    small = np.linalg.norm(bounds[:, 1] - bounds[:, 0], axis=1) <= diagonal
    return [int(k) for k in np.flatnonzero(inside & small)]


def holding(scene: Scene, bounds: np.ndarray, centre: np.ndarray, member: int,
            tracers: dict[int, RayTracer] | None = None) -> list[int]:
    """Objects other than `member` whose closed surface holds `centre` (an object's own probe centre):
    of those whose box holds it, the ones that most of 26 rays from it (to the corners, edges and faces
    of a cube around it) meet from behind first (the brass rod through the middle of the wooden
    staircase's glass lamp, whose probe saw only the rod's inside, black). Left out of the probe like a
    shared probe's `enclosing` objects; an object that merely stands inside the box, as the lamp's
    candles, stays in view. `tracers`: each object's own tracer, built once for all probes (the walls
    of a room hold every centre)."""
    tracers = {} if tracers is None else tracers
    dirs = np.array([d for d in np.ndindex(3, 3, 3) if d != (1, 1, 1)], float) - 1.0
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    out = []
    for k in enclosing(bounds, centre, math.inf):
        if k == member or scene.objects[k].role == "transmissive":
            continue
        if k not in tracers:
            tracers[k] = RayTracer(replace(scene, objects=[scene.objects[k]]))
        tracer = tracers[k]
        prim, _, _, _ = tracer.intersect_raw(np.repeat(centre[None], len(dirs), axis=0), dirs)
        if 2 * tracer.from_behind(prim, dirs).sum() > len(dirs):
            out.append(k)
    return out


def box_walls(lo: np.ndarray, hi: np.ndarray) -> list[BoundingPlane]:
    """The six faces of the box lo..hi as planes facing in (the scene's bounding box: nothing of
    the scene lies beyond them, so they enclose every object as its bounding planes do)."""
    out = []
    for axis in range(3):
        for point, sign in ((lo, 1.0), (hi, -1.0)):
            normal = np.zeros(3)
            normal[axis] = sign
            out.append(BoundingPlane(np.asarray(point, float), normal))
    return out


def cluster(boxes: np.ndarray, limits: np.ndarray) -> list[list[int]]:
    """Greedy clusters of boxes (n, 2, 3) whose joint box has a radius (half diagonal) within every
    member's limit (n,); each box in exactly one cluster, a box over its own limit alone.

    Seeds are taken in order along x, then z, then y; each grows by the nearest boxes that keep the
    cluster within its members' limits (a box's centre within twice the seed's limit can qualify)."""
    n = len(boxes)
    if n == 0:
        return []
    centres = boxes.mean(axis=1)
    tree = cKDTree(centres)
    taken = np.zeros(n, bool)
    out = []
    for seed in np.lexsort((centres[:, 1], centres[:, 2], centres[:, 0])):
        if taken[seed]:
            continue
        taken[seed] = True
        members, (lo, hi), limit = [int(seed)], boxes[seed], float(limits[seed])
        if np.linalg.norm(hi - lo) / 2 < limit:
            near = np.array(tree.query_ball_point(centres[seed], 2 * limit), dtype=np.int64)
            near = near[np.argsort(np.linalg.norm(centres[near] - centres[seed], axis=1), kind="stable")]
            for k in near:
                if taken[k]:
                    continue
                new_lo, new_hi = np.minimum(lo, boxes[k, 0]), np.maximum(hi, boxes[k, 1])
                if np.linalg.norm(new_hi - new_lo) / 2 <= min(limit, float(limits[k])):
                    taken[k] = True
                    members.append(int(k))
                    lo, hi, limit = new_lo, new_hi, min(limit, float(limits[k]))
        out.append(sorted(members))
    return out


@dataclass(frozen=True)
class ProbeRules:
    """The bake settings that shape the probes (bake/settings.py: [bake] probe_sharing,
    cubemap_budget, cubemap_budget_mib)."""
    sharing: float = 1.0
    budget: int = 2048
    budget_mib: float = 512.0

    @classmethod
    def of(cls, settings) -> "ProbeRules":
        return cls(float(settings.probe_sharing), int(settings.cubemap_budget), float(settings.cubemap_budget_mib))


@dataclass
class CubeMapPlan:
    """One probe: a cube map, what to render and what the manifest says about it."""
    index: int  # the manifest index of its first object: names its file and its stages.cubemaps entry
    name: str   # that object's name
    size: int
    centre: np.ndarray
    hidden: tuple[int, ...]  # objects left out (its objects and thin glass)
    planes: list[BoundingPlane] = field(default_factory=list)
    hash: str = ""
    members: tuple[int, ...] = ()  # the objects it serves (its index alone: an object's own map)
    fixed_size: bool = False  # the sidecar set the size: the budget leaves it alone

    @property
    def file(self) -> str:
        return f"cubemaps/{self.index}.exr"

    @property
    def mib(self) -> float:
        return 6 * self.size ** 2 * MIB_PER_TEXEL

    def manifest_entry(self) -> dict:
        entry = {"file": self.file, "size": self.size, "centre": [float(x) for x in self.centre],
                 "bounding_planes": [p.to_dict() for p in self.planes]}
        if len(self.members) > 1:  # only then: an own map's entry stays as it was
            entry["shared_by"] = len(self.members)
        return entry


def own_probe(obj: Object) -> bool:
    """The sidecar fixed this object's probe (a `cubemap_size`, its own `bounding_planes`, or
    `shared_probe = false`): it keeps a probe of its own (see "Probes")."""
    given = obj.options
    return given.get("shared_probe") is False or "cubemap_size" in given or given.get("bounding_planes", True) is not True


def plan_cubemaps(scene: Scene, transport: str, rules: ProbeRules = ProbeRules()) -> list[CubeMapPlan]:
    """The probes of the scene's curved and transmissive objects (see the module docstring), none
    for any other; `Object.options` holds the sidecar's per-object settings (bake/sidecar.py)."""
    glass = [i for i, o in enumerate(scene.objects) if o.role == "transmissive"]
    surfaces = None
    own, shared = [], []  # (index, size, planes); shared also its box and limit
    for i, obj in enumerate(scene.objects):
        if obj.role not in CUBEMAP_ROLES:
            continue
        given = obj.options
        size = given.get("cubemap_size") or automatic_size(obj, scene.material_of(obj))
        planes = override_planes(given.get("bounding_planes"))
        if planes is None:
            surfaces = candidate_surfaces(scene) if surfaces is None else surfaces
            planes = choose_planes(obj, surfaces)
        if own_probe(obj):
            own.append((i, int(size), planes))
        else:
            shared.append((i, int(size), planes))
    if shared:
        lo, hi = scene.bounds
        fallback, walls = float(np.linalg.norm(hi - lo)) / 2, box_walls(lo, hi)
        boxes = np.array([scene.objects[i].bounds for i, _, _ in shared])
        limits = np.array([sharing_slope(scene.material_of(scene.objects[i]), size)
                           * clearance(*scene.objects[i].bounds, planes + walls, fallback)
                           for i, size, planes in shared])
    else:
        boxes, limits = np.zeros((0, 2, 3)), np.zeros(0)

    def plan(members: list[int], sizes: list[int], planes_of, fixed: bool) -> CubeMapPlan:
        first, around = scene.objects[members[0]], []
        if len(members) == 1:
            centre, planes = first.bounds.mean(axis=0), planes_of[0]
            around = holding(scene, all_bounds, centre, members[0], tracers)
        else:  # the cluster's box: its centre, and its own bounding planes
            box = np.array([scene.objects[k].bounds for k in members])
            lo, hi = box[:, 0].min(axis=0), box[:, 1].max(axis=0)
            centre, planes = (lo + hi) / 2, box_planes(lo, hi, candidate_surfaces(scene) if surfaces is None else surfaces)
            around = enclosing(all_bounds, centre, float(np.linalg.norm(hi - lo)))
        return CubeMapPlan(members[0], first.name, max(sizes), centre,
                           tuple(sorted({*members, *glass, *around, *siblings(members)})), planes,
                           members=tuple(members), fixed_size=fixed)

    parts_of: dict[str, list[int]] = {}  # object name -> its parts' indices (bake/probe_parts.py)
    for k, o in enumerate(scene.objects):
        if o.part_of:
            parts_of.setdefault(o.part_of, []).append(k)

    def siblings(members: list[int]) -> list[int]:  # a part's probe hides its whole object
        return [k for name in {scene.objects[m].part_of for m in members} for k in parts_of.get(name, ())]

    all_bounds = np.array([o.bounds for o in scene.objects])
    tracers: dict[int, RayTracer] = {}  # `holding`'s, per object
    owns = [plan([i], [size], [planes], True) for i, size, planes in own]
    sharing, steps = max(float(rules.sharing), 0.0), 0
    while True:
        groups = cluster(boxes, sharing * limits) if sharing > 0 else [[k] for k in range(len(shared))]
        if len(owns) + len(groups) <= rules.budget or sharing == 0 or steps == BUDGET_MERGE_STEPS:
            break
        sharing, steps = 2 * sharing, steps + 1
    plans = owns + [plan([shared[k][0] for k in g], [shared[k][1] for k in g], [shared[k][2] for k in g],
                         any("cubemap_size" in scene.objects[shared[k][0]].options for k in g)) for g in groups]
    plans.sort(key=lambda p: p.index)
    halved = _fit_memory(plans, rules.budget_mib)
    if steps or halved or len(plans) > rules.budget:
        _warn_budget(plans, rules, sharing if steps else None, halved)
    for p in plans:
        p.hash = hashing.cubemap_hash(transport, {
            "object": [p.index, p.name], "size": p.size, "centre": p.centre,
            "hidden": [[k, scene.objects[k].name] for k in p.hidden],
            "render": {"supersample": supersample(p.size), "near_per_far": NEAR_PER_FAR, "far_margin": FAR_MARGIN,
                       "sky_distance": SKY_DISTANCE, "small_object_texels": SMALL_OBJECT_TEXELS,
                       "lod_triangles_per_pixel": LOD_TRIANGLES_PER_PIXEL}})
    return plans


def _fit_memory(plans: list[CubeMapPlan], budget_mib: float) -> list[int]:
    """Halve the largest automatic face sizes until the probes fit in budget_mib (or every
    automatic size is AUTO_SIZE_RANGE's smallest); returns the sizes halved, largest first."""
    halved = []
    while sum(p.mib for p in plans) > budget_mib:
        free = [p for p in plans if not p.fixed_size and p.size > AUTO_SIZE_RANGE[0]]
        if not free:
            break
        top = max(p.size for p in free)
        for p in free:
            if p.size == top:
                p.size //= 2
        halved.append(top)
    return halved


def _warn_budget(plans: list[CubeMapPlan], rules: ProbeRules, sharing: float | None, halved: list[int]) -> None:
    done = []
    if sharing is not None:
        done.append(f"shared more (probe_sharing x{sharing:g})")
    if halved:
        done.append(f"halved faces of {', '.join(str(s) for s in halved)} texels")
    over = [f"{len(plans)} probes" if len(plans) > rules.budget else "",
            f"{sum(p.mib for p in plans):.0f} MiB" if sum(p.mib for p in plans) > rules.budget_mib else ""]
    over = [o for o in over if o]
    warn(f"cube maps over the budget of {rules.budget} probes and {rules.budget_mib:g} MiB ([bake] cubemap_budget, "
         f"cubemap_budget_mib): {'; '.join(done) or 'nothing left to merge or shrink'}"
         + (f"; still {' and '.join(over)}" if over else f"; now {len(plans)} probes, "
            f"{sum(p.mib for p in plans):.0f} MiB"))


def budget_statistics(plans: list[CubeMapPlan], rules: ProbeRules) -> dict:
    """The probes' count, objects served, MiB and face sizes, for the manifest's statistics."""
    sizes: dict[str, int] = {}
    for p in sorted(plans, key=lambda p: p.size):
        sizes[str(p.size)] = sizes.get(str(p.size), 0) + 1
    return {"probes": len(plans), "objects": int(sum(len(p.members) for p in plans)),
            "shared_probes": sum(len(p.members) > 1 for p in plans),
            "mib": round(sum(p.mib for p in plans), 3), "face_sizes": sizes,
            "budget": {"probes": rules.budget, "mib": rules.budget_mib, "probe_sharing": rules.sharing}}
