"""Cube maps of curved and transmissive objects: their incident light (section 4.4.1).

One cubic environment map per object stands for the light arriving anywhere on it: the
light-mapped scene rendered from the object's bounding-box centre without the object itself,
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
black sheet, whereas from most directions it shows what lies behind it.

Faces follow the OpenGL cube-map convention, so `texture(samplerCube, dir)` returns the
radiance seen along dir: face k = GL_TEXTURE_CUBE_MAP_POSITIVE_X + k, in the order
+X, -X, +Y, -Y, +Z, -Z, is rendered by a 90-degree camera looking along the face's axis with
the up vector of `FACES`; its right (forward x up) is the direction of increasing s and its up
that of increasing t (the spec's sc/tc table), and the frame read back bottom row first is the
face in glTexImage2D's order (row 0 at t = 0).

File: `cubemaps/<object index>.exr`, RGBA, width S, height 6 S: the six faces stacked
vertically in the GL order above, each S x S with its first row at t = 0 and first column at
s = 0 (viewer/cubemaps.py reads it). RGB is radiance W/(m^2 sr); A is the distance in metres
from the centre along the texel's direction to the visible surface (the mean over its 2 x 2
supersamples), `SKY_DISTANCE` where only sky shows. Half float unless a value does not fit,
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

A cube map's inputs hash (bake/hashing.py `cubemap_hash`) is the light maps' hash plus the
object, its face size and centre, the hidden objects and the render settings here: a re-bake
renders only the cube maps whose hash changed and carries the others over.

The maps are rendered one after another on one GL context in the bake's own process, not on
the executor's worker processes: a GL context does not survive fork, the GPU is one device
anyway, and a map takes from a few hundredths of a second (32) to a few seconds (512) even on
llvmpipe.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from glint.bake import hashing
from glint.bake.bounding_planes import BoundingPlane, candidate_surfaces, choose_planes, override_planes
from glint.core.bsdf import M_MIN, theta_thresh
from glint.core.constants import HALF_MAX
from glint.core.scene import Material, Object, Scene

CUBEMAP_ROLES = ("curved", "transmissive")
# GL_TEXTURE_CUBE_MAP_POSITIVE_X + k: (name, camera forward, camera up)
FACES = (("+x", (1, 0, 0), (0, -1, 0)), ("-x", (-1, 0, 0), (0, -1, 0)),
         ("+y", (0, 1, 0), (0, 0, 1)), ("-y", (0, -1, 0), (0, 0, -1)),
         ("+z", (0, 0, 1), (0, -1, 0)), ("-z", (0, 0, -1), (0, -1, 0)))
AUTO_SIZE_RANGE = (32, 512)
TEXELS_PER_LOBE_RADIUS = 4
FACE_TEXELS_PER_METRE = 400.0
SUPERSAMPLE = 2  # per axis: a texel is the mean of 2 x 2 samples
# Clip planes of the faces, from the distance `far` to the scene's farthest corner (so a 1 mm and
# a 10 km scene get the same picture): zfar = FAR_MARGIN x far, znear = NEAR_PER_FAR x far.
# 24-bit depth then resolves d^2 / (znear 2^24), 6e-4 of far at far; 1 mm at 6 m on a room
# (a fixed 1 mm znear clipped a 1 mm scene and let a 10 km one z-fight: glint bench --stress).
NEAR_PER_FAR = 1e-4
FAR_MARGIN = 1.02
SKY_DISTANCE = HALF_MAX  # alpha where only sky shows: far but finite


def automatic_size(obj: Object, material: Material) -> int:
    """Face size from the narrowest lobe and the object's size (see the module docstring)."""
    lo, hi = AUTO_SIZE_RANGE
    widths = [max(min(lobe.mx, lobe.my), M_MIN) for lobe in material.lobes]
    # Eq. 4.10 where the lobe is narrowest: its phi factor peaks at 1/m^2 with m = min(mx, my);
    # the reflected lobe's radius 2 theta_thresh spans TEXELS_PER_LOBE_RADIUS texels of pi/2 / S
    m = min(widths) if widths else None
    by_lobe = TEXELS_PER_LOBE_RADIUS * (math.pi / 2) / (2 * float(theta_thresh(0.0, m, m))) if widths else math.inf
    by_size = FACE_TEXELS_PER_METRE * float(np.linalg.norm(obj.bounds[1] - obj.bounds[0]))
    need = min(by_lobe, by_size)
    return int(min(max(2 ** math.ceil(math.log2(max(need, 1.0))), lo), hi))


@dataclass
class CubeMapPlan:
    """One object's cube map: what to render and what the manifest says about it."""
    index: int  # the object's index in the manifest
    name: str
    size: int
    centre: np.ndarray
    hidden: tuple[int, ...]  # objects left out (itself and thin glass)
    planes: list[BoundingPlane] = field(default_factory=list)
    hash: str = ""

    @property
    def file(self) -> str:
        return f"cubemaps/{self.index}.exr"

    def manifest_entry(self) -> dict:
        return {"file": self.file, "size": self.size, "centre": [float(x) for x in self.centre],
                "bounding_planes": [p.to_dict() for p in self.planes]}


def plan_cubemaps(scene: Scene, transport: str) -> list[CubeMapPlan]:
    """A plan per curved or transmissive object, none for any other; `Object.options` holds the
    sidecar's per-object settings (bake/sidecar.py)."""
    glass = [i for i, o in enumerate(scene.objects) if o.role == "transmissive"]
    surfaces = None
    plans = []
    for i, obj in enumerate(scene.objects):
        if obj.role not in CUBEMAP_ROLES:
            continue
        given = obj.options
        size = given.get("cubemap_size") or automatic_size(obj, scene.material_of(obj))
        planes = override_planes(given.get("bounding_planes"))
        if planes is None:
            surfaces = candidate_surfaces(scene) if surfaces is None else surfaces
            planes = choose_planes(obj, surfaces)
        plan = CubeMapPlan(i, obj.name, int(size), obj.bounds.mean(axis=0), tuple(sorted({i, *glass})), planes)
        plan.hash = hashing.cubemap_hash(transport, {
            "object": [i, obj.name], "size": plan.size, "centre": plan.centre,
            "hidden": [[k, scene.objects[k].name] for k in plan.hidden],
            "render": {"supersample": SUPERSAMPLE, "near_per_far": NEAR_PER_FAR, "far_margin": FAR_MARGIN,
                       "sky_distance": SKY_DISTANCE}})
        plans.append(plan)
    return plans
