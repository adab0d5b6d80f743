"""Mirror passes of planar reflectors (section 4.5.1; docs/VIEWER.md, "Passes").

Per frame, before the G-buffer:

1. `plan(camera, aspect)`: which reflectors get a pass (viewer/reflectors.py: outside the
   frustum, seen from behind, occluded by last frame's query, over the budget; reflectors
   sharing a plane share a pass), after reading the occlusion queries of earlier frames
   that have finished (never waiting for one).
2. `run(plan)`: per pass the scene from the mirrored camera (viewer/mirror_camera.py: view
   V R, winding flipped, clipped at the plane with gl_ClipDistance), without that pass's
   reflectors and without objects wholly behind the plane, diffuse only (light map +
   emission: shaders/mirror.frag), and the sky behind it -- the clear colour for a constant
   sky, else shaders/mirror_sky.frag, one triangle at the far plane, which costs its whole
   area even where the scene covers everything (docs/BENCHMARKS.md, "The mirror pass's
   sky"); through a visibility buffer the classification writes the sky and the empty texels instead
   (viewer/passes/visibility.py) -- into layer k ("slot" k) of
   three texture arrays:

       radiance   RGBA16F  light towards the mirrored eye, or the sky's; a full MIP chain
                           (2 x 2 box per level, shaders/mirror_mips.comp, only over the
                           slots used this frame)
       position   RGBA32F  xyz world position of the unmirrored scene point (w = 1; 0 = nothing)
       normal     RGBA16F  xyz its unit normal, on the side the mirrored eye sees (0 = nothing)

   at the render size (supersampled), over the mirrored view widened by the pass's guard band
   (viewer/reflectors.py: x and y of the projection divided by s >= 1, from the reach of its
   widest lobe, so lobes near the border of the view still find what they see; with s = 1 the
   buffer lines up pixel for pixel with the main view). bench/mirror_projection.py states the
   conventions (texel row 0 = the bottom); the shaders project with the slot's matrix.
   The PassTimer sections are "mirror_passes" (the raster passes and their sky) and
   "mirror_mips" (the MIP chains).
3. After the G-buffer, `query_occlusion(...)`: one GL_ANY_SAMPLES_PASSED_CONSERVATIVE query
   per reflector of `plan.queries`, its triangles drawn against the G-buffer's depth ("<=",
   colour and depth writes off); results are read by a later frame's `plan`.
4. `bind()` for the shading passes: the arrays on fixed texture units, per slot its mirrored
   view-projection and plane, per object its slot this frame or -1 (shaders/mirror_buffer.glsl).

The arrays have as many layers as the budget allows and the scene can use (its reflectors'
distinct planes); 4 passes at 2560 x 1440 would be ~0.5 GB, so a scene with one floor pays
for one. Each layer has its own framebuffer (glFramebufferTextureLayer through ctypes, which
moderngl lacks) sharing one depth buffer.
"""
from __future__ import annotations

import ctypes
from dataclasses import replace

import moderngl
import numpy as np

from glint.core.geometry import fit_plane
from glint.core.manifest import Material
from glint.viewer.camera import ViewCamera, gl_bytes
from glint.viewer.draw_list import BatchPrograms
from glint.viewer.gl import (
    GL,
    GL_ANY_SAMPLES_PASSED_CONSERVATIVE,
    GL_CLIP_DISTANCE0,
    GL_COLOR,
    GL_COLOR_ATTACHMENT0,
    GL_DEPTH,
    GL_DEPTH_ATTACHMENT,
    GL_FRAMEBUFFER,
    GL_FRAMEBUFFER_COMPLETE,
    GL_QUERY_RESULT,
    GL_QUERY_RESULT_AVAILABLE,
    GL_RENDERBUFFER,
    GL_SCISSOR_TEST,
    release_framebuffer,
)
from glint.viewer.gl_bindings import (
    MIP_SOURCE_IMAGE,
    MIP_TARGET_IMAGE,
    MIRROR_NORMAL_IMAGE,
    MIRROR_NORMAL_LOCATION,
    MIRROR_OBJECT_BINDING,
    MIRROR_POSITION_IMAGE,
    MIRROR_POSITION_LOCATION,
    MIRROR_RADIANCE_IMAGE,
    MIRROR_RADIANCE_LOCATION,
    MIRROR_SLOT_BINDING,
    SKY_UNIT,
    mirror_units,
)
from glint.viewer.gpu_sky import SKY_MODES
from glint.viewer.mirror_camera import group_coplanar
from glint.viewer.passes.gbuffer import GBufferPass
from glint.viewer.passes.visibility import VisibilityResolve
from glint.viewer.reflectors import (
    DEFAULT_BUDGET,
    MirrorPlan,
    OcclusionResults,
    Reflector,
    lobe_reach,
    plan_mirror_passes,
    scissor_rect,
)
from glint.viewer.shader_source import LOCAL_SIZE, compute_program, raster_program, set_uniforms

# The mirror buffers' size as a fraction of the render's (`Renderer(mirror_resolution=...)`): 1, the
# default, lines a buffer up with the view pixel for pixel (docs/VIEWER.md, "Mirror buffers at a
# lower resolution": what a lower one changes, what it saves).
MIRROR_RESOLUTIONS = (1.0, 0.5, 0.25)
SLOT_DTYPE = np.dtype([("view_proj", "<f4", (4, 4)), ("plane", "<f4", 4), ("info", "<f4", 4)])
TARGETS = ("radiance", "position", "normal")  # the order of mirror_units' texture units
# Each target's colour attachment = fragment-output location of mirror.frag and mirror_sky.frag.
LOCATIONS = {"radiance": MIRROR_RADIANCE_LOCATION, "position": MIRROR_POSITION_LOCATION,
             "normal": MIRROR_NORMAL_LOCATION}


def mirror_defines(first_unit: int) -> dict:
    """The units shaders/mirror_buffer.glsl takes: its three array textures on units
    first_unit .. first_unit + 2 (its buffer bindings every program gets: viewer/gl_bindings.py)."""
    return mirror_units(first_unit)


def mirror_reach(material: Material) -> float | None:
    """How far the widest reflection lobe of a manifest material turns from the mirror direction
    (viewer/reflectors.py `lobe_reach`: the guard band); None without reflection lobes."""
    lobes = [lobe for lobe in material.lobes if lobe.kind == "reflect"]
    return max(lobe_reach(lobe.mx, lobe.my) for lobe in lobes) if lobes else None


def manifest_reflectors(bake) -> list[tuple[int, Reflector]]:
    """(object index, Reflector) of every `planar` object of the bake with a reflection lobe (the
    others have nothing to read a mirror buffer for: the cube-map bake renders without lobes):
    its `plane` entry (bake/pipeline.py), or the best-fit plane of its mesh for a manifest
    without one. Names are made unique (the occlusion results are kept by name)."""
    out, seen = [], set()
    materials = bake.model.materials
    for i, entry in enumerate(bake.model.objects):
        if entry.role != "planar" or not entry.triangles:
            continue
        reach = mirror_reach(materials[int(entry.material)])  # the guard band
        if reach is None:
            continue
        plane = entry.plane
        if plane:
            point, normal = np.asarray(plane.point, np.float64), np.asarray(plane.normal, np.float64)
        else:
            mesh = bake.meshes[i]
            point, normal = fit_plane(np.asarray(mesh["positions"], np.float64).reshape(-1, 3),
                                      np.asarray(mesh["indices"], np.int64).reshape(-1, 3))
        if not (np.all(np.isfinite(point)) and np.all(np.isfinite(normal)) and np.linalg.norm(normal) > 1e-12):
            continue
        name = entry.name if entry.name not in seen else f"{entry.name} #{i}"
        seen.add(name)
        out.append((i, Reflector(name, point, normal, np.asarray(entry.bounds, np.float64), reach=reach)))
    return out


class MirrorPasses:
    name = "mirror"

    def __init__(self, ctx: moderngl.Context, scene, bake, draws, defines: dict, budget: int = DEFAULT_BUDGET,
                 visibility: bool = False, scissor: bool = False, resolution: float = 1.0):
        """draws: the scene's viewer/draw_list.py DrawList (pass k draws into its region
        GBufferPass.REGION + 1 + k); visibility: each pass through a visibility buffer
        (viewer/passes/visibility.py: ids and depth rasterised, then the targets resolved per pixel in
        compute), as the G-buffer on a GPU; scissor: each pass rasterises only the rectangle its
        reflectors' look-ups are estimated to reach (viewer/reflectors.py `scissor_rect`; an
        experiment, off by default: docs/VIEWER.md, "Mirror passes in a rectangle")."""
        if not (isinstance(budget, (int, np.integer)) and budget >= 0):
            raise ValueError(f"the mirror-pass budget must be a whole number of at least 0 (got {budget!r})")
        if resolution not in MIRROR_RESOLUTIONS:
            raise ValueError(f"the mirror buffers' resolution must be one of {MIRROR_RESOLUTIONS} (got {resolution!r})")
        self.resolution = float(resolution)
        self.ctx = ctx
        self.scene = scene
        self.draws = draws
        self.budget = int(budget)
        self.objects = manifest_reflectors(bake)  # (object index, Reflector)
        self.reflectors = [r for _, r in self.objects]
        self.object_of = {r.name: i for i, r in self.objects}
        planes = group_coplanar([(r.name, r.point, r.normal) for r in self.reflectors]) if self.reflectors else []
        self.layers = min(self.budget, len(planes))  # passes one frame can ever need
        self.scissor = bool(scissor)
        draws.reserve(GBufferPass.REGION + 1 + self.layers)  # pass k draws into region 1 + k
        self.occlusion = OcclusionResults()
        self.frame = 0
        self.plan_: MirrorPlan | None = None
        self.size: tuple[int, int] | None = None
        self.targets: dict[str, moderngl.TextureArray] = {}
        self.depth: moderngl.Renderbuffer | None = None
        self._fbos: list[int] = []  # per layer its framebuffer's GL name (bound with gl.BindFramebuffer)
        self._queries: dict[str, int] = {}   # reflector name -> GL query object
        self._pending: set[str] = set()      # queries issued and not yet read
        self._drawn: list[dict] = []
        self._gl = GL(ctx)
        self.ids = (VisibilityResolve(ctx, scene, draws, {**defines, "MIRROR_CLIP": 1}, "RESOLVE_MIRROR")
                    if visibility and self.layers else None)
        self.raster = self.ids.program if self.ids else BatchPrograms(ctx, "gbuffer.vert", "mirror.frag",
                                                                      {**defines, "MIRROR_CLIP": 1})
        self._ids_fbo: moderngl.Framebuffer | None = None  # the visibility buffer's: ids + the shared depth
        self.occluder = raster_program(ctx, "gbuffer.vert", "occlusion.frag", defines)
        self.sky = raster_program(ctx, "blit.vert", "mirror_sky.frag", {**defines, "FAR_PLANE": 1})
        self.sky_vao = ctx.vertex_array(self.sky, [])
        self.mips = compute_program(ctx, "mirror_mips.comp", defines)
        self.slot_buffer = ctx.buffer(reserve=max(self.layers, 1) * SLOT_DTYPE.itemsize)
        self.object_slots = np.full(max(len(scene.objects), 1), -1, np.int32)
        self.object_buffer = ctx.buffer(self.object_slots.tobytes())
        self._dummy = self._arrays((1, 1), 1)  # bound while there are no real ones

    @property
    def active(self) -> bool:
        """Whether the scene has planar reflectors that can get a pass at all."""
        return self.layers > 0

    # -- targets -----------------------------------------------------------------------------------
    def _arrays(self, size: tuple[int, int], layers: int) -> dict:
        ctx = self.ctx
        t = {"radiance": ctx.texture_array((*size, layers), 4, dtype="f2"),
             "position": ctx.texture_array((*size, layers), 4, dtype="f4"),
             "normal": ctx.texture_array((*size, layers), 4, dtype="f2")}
        t["radiance"].build_mipmaps()  # allocates the chain; mirror_mips.comp fills it
        t["radiance"].filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        for name in ("position", "normal"):
            t[name].filter = (moderngl.NEAREST, moderngl.NEAREST)
        for tex in t.values():
            tex.repeat_x = tex.repeat_y = False  # clamp to edge: a sample leaving the buffer reads its edge
        return t

    def set_material(self, material: int, entry: dict) -> None:
        """A material edit (Renderer.set_material): the reflectors made of `material` widen or narrow
        their guard band to its lobes' reach (one that lost every reflection lobe keeps its last)."""
        reach = mirror_reach(Material.from_json(entry))  # an edit's dict (the material schema piece types it)
        if reach is None:
            return
        self.objects = [(i, replace(r, reach=reach) if self.scene.objects[i].material == material else r)
                        for i, r in self.objects]
        self.reflectors = [r for _, r in self.objects]

    def buffer_size(self, size: tuple[int, int]) -> tuple[int, int]:
        """The mirror buffers' size for a render of `size` (the G-buffer's): times the resolution."""
        return tuple(max(1, int(round(x * self.resolution))) for x in size)

    def resize(self, size: tuple[int, int]) -> None:
        """The buffers for a render of `size` (the G-buffer's; the buffers are `buffer_size(size)`)."""
        size = self.buffer_size(size)
        if size == self.size or not self.active:
            return
        self._release_targets()
        gl = self._gl
        with gl.checked(f"allocate {self.layers} mirror buffers of {size[0]} x {size[1]}"):
            self.targets = self._arrays(size, self.layers)
            # a visibility buffer's classification reads the depth: a texture then
            self.depth = self.ctx.depth_texture(size) if self.ids else self.ctx.depth_renderbuffer(size)
            if self.ids:
                self.depth.compare_func = ""
                self.ids.resize(size)
                self._ids_fbo = self.ids.framebuffer(self.depth)
        for layer in range(self.layers):
            name = ctypes.c_uint(0)
            with gl.checked(f"make the framebuffer of mirror-buffer layer {layer} ({size[0]} x {size[1]})"):
                gl.GenFramebuffers(1, ctypes.byref(name))
                gl.BindFramebuffer(GL_FRAMEBUFFER, name.value)
                for target, location in LOCATIONS.items():
                    gl.FramebufferTextureLayer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0 + location,
                                               self.targets[target].glo, 0, layer)
                if self.ids:
                    gl.FramebufferTexture(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, self.depth.glo, 0)
                else:
                    gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, self.depth.glo)
                buffers = (ctypes.c_uint * len(LOCATIONS))(*(GL_COLOR_ATTACHMENT0 + k for k in range(len(LOCATIONS))))
                gl.DrawBuffers(len(LOCATIONS), buffers)
                status = gl.CheckFramebufferStatus(GL_FRAMEBUFFER)
            if status != GL_FRAMEBUFFER_COMPLETE:
                raise RuntimeError(f"mirror-buffer framebuffer incomplete (status 0x{status:x})")
            self._fbos.append(name.value)
        self.size = size

    # -- per frame ---------------------------------------------------------------------------------
    def plan(self, camera: ViewCamera, aspect: float, hidden=()) -> MirrorPlan:
        """This frame's passes; reads the occlusion queries that have finished."""
        self.frame += 1
        self._collect_queries()
        hidden = set(hidden)
        reflectors = [r for i, r in self.objects if i not in hidden]
        plan = plan_mirror_passes(reflectors, camera, aspect, budget=self.layers, occlusion=self.occlusion,
                                  frame=self.frame)
        self.plan_ = plan
        return plan

    def run(self, plan: MirrorPlan, camera: ViewCamera, aspect: float, hidden=(), timer=None) -> None:
        """Render the passes of `plan` (slot k = pass k), then the sky and the MIP chains; writes
        the slot and object tables. `timer` (a PassTimer) times "mirror" and "mirror_mips"."""
        self.object_slots[:] = -1
        slots = np.zeros(max(self.layers, 1), SLOT_DTYPE)
        self._drawn = []
        if not plan.passes or not self.active:
            self._upload(slots)
            return
        levels = max_level(self.size)
        for k, p in enumerate(plan.passes):
            for r in p.members:
                self.object_slots[self.object_of[r.name]] = k
            slots[k]["view_proj"] = p.view_projection(aspect).T  # column-major; with its guard band
            n = np.asarray(p.camera.normal, np.float64)
            slots[k]["plane"] = (*n, -float(n @ p.camera.point))
            slots[k]["info"] = (levels, *self.size, 0.0)
        self._upload(slots)
        with _timed(timer, "mirror_passes"):
            for k, p in enumerate(plan.passes):
                self._drawn.append(self._draw_pass(k, p, camera, aspect, set(hidden)))
        with _timed(timer, "mirror_mips"):
            self._build_mips(len(plan.passes))

    def _upload(self, slots: np.ndarray) -> None:
        self.slot_buffer.write(slots.tobytes())
        self.object_buffer.write(self.object_slots.tobytes())

    def _draw_pass(self, k: int, p, camera: ViewCamera, aspect: float, hidden: set) -> dict:
        ctx, gl = self.ctx, self._gl
        glo = self._fbos[k]
        self._bind_layer(glo)
        sky_map = self.scene.sky_mode == SKY_MODES["SKY_MAP"]
        if not self.ids:  # through a visibility buffer, the classification writes the empty texels
            # A constant sky (or none) is the clear colour; a sky map is drawn after the scene.
            constant = self.scene.sky_mode == SKY_MODES["SKY_CONSTANT"]
            sky = tuple(map(float, self.scene.sky_uniforms()["sky_scale"])) if constant else (0.0, 0.0, 0.0)
            gl.ClearBufferfv(GL_COLOR, LOCATIONS["radiance"], (ctypes.c_float * 4)(*sky, 1.0))
            for target in ("position", "normal"):
                gl.ClearBufferfv(GL_COLOR, LOCATIONS[target], (ctypes.c_float * 4)(0.0, 0.0, 0.0, 0.0))
        gl.ClearBufferfv(GL_DEPTH, 0, (ctypes.c_float * 1)(1.0))
        ctx.enable_only(moderngl.DEPTH_TEST)
        ctx.depth_func = "<"
        ctx.front_face = p.camera.front_face  # V R mirrors: counter-clockwise faces come out clockwise
        gl.Enable(GL_CLIP_DISTANCE0)
        mirror = p.camera
        view_proj = p.view_projection(aspect)  # the guard band's wider frustum (viewer/reflectors.py)
        self.raster.set(eye=tuple(map(float, mirror.eye)), clip_plane=tuple(map(float, mirror.clip_plane())))
        members = {self.object_of[r.name] for r in p.members}
        region = GBufferPass.REGION + 1 + k
        if self.ids:  # the raster pass writes ids and depth
            self._ids_fbo.viewport = (0, 0, *self.size)
            self._ids_fbo.use()
        rect = scissor_rect(p, aspect, self.size, camera.yfov) if self.scissor else None
        if rect is not None:  # after the clears: outside it the buffer holds the empty texels (the sky, below)
            gl.Enable(GL_SCISSOR_TEST)
            gl.Scissor(*rect)
        try:
            # geometry wholly behind the mirror is culled (it would be clipped anyway), the reflectors
            # of this plane left out
            self.draws.draw(self.raster, view_proj, region=region, hidden=members | hidden,
                            clip_plane=mirror.clip_plane())
        finally:
            gl.Disable(GL_CLIP_DISTANCE0)
            gl.Disable(GL_SCISSOR_TEST)
            ctx.front_face = "ccw"
        if self.ids:  # mirror.frag's targets from the ids, at layer k, and the sky (viewer/passes/visibility.py)
            for target, unit in (("radiance", MIRROR_RADIANCE_IMAGE), ("position", MIRROR_POSITION_IMAGE),
                                 ("normal", MIRROR_NORMAL_IMAGE)):
                self.targets[target].bind_to_image(unit, read=False, write=True, level=0)
            self.scene.sky_map.use(SKY_UNIT)
            self.ids.run(self.depth, view_proj, mirror.eye, layer=k, sky=self._sky_uniforms(mirror, camera, aspect, p.guard))
            self._bind_layer(glo)
        elif sky_map:
            self._draw_sky(mirror, camera, aspect, p.guard)
        return {"reflectors": p.names, "region": region, "scissor": rect}

    def _bind_layer(self, glo: int) -> None:
        """A layer's framebuffer and viewport, by their GL names: moderngl's handle of a framebuffer it did
        not make (detect_framebuffer) queries attachments no layer has (GL_INVALID_OPERATION), and one
        left bound in moderngl's state after its deletion breaks moderngl's next framebuffer."""
        self._gl.BindFramebuffer(GL_FRAMEBUFFER, glo)
        self._gl.Viewport(0, 0, *self.size)
        self._gl.DepthMask(1)  # what moderngl's use() would set: the clears obey it
        self._gl.ColorMask(1, 1, 1, 1)

    def _sky_uniforms(self, mirror, camera: ViewCamera, aspect: float, guard: float) -> dict:
        """What the sky of a pass's empty texels is drawn from (mirror_sky.frag; the visibility buffer's
        classification): the main camera's rays over the guard band's `guard` times wider frustum, the
        pass's plane, the scene's sky."""
        forward, right, up = camera.ray_basis(aspect)
        vec = lambda v: tuple(map(float, v))  # noqa: E731
        return {"eye": vec(camera.eye), "cam_forward": vec(forward), "cam_right": vec(right * guard),
                "cam_up": vec(up * guard), "mirror_normal_world": vec(mirror.normal), **self.scene.sky_uniforms()}

    def _draw_sky(self, mirror, camera: ViewCamera, aspect: float, guard: float = 1.0) -> None:
        """The sky on the texels the scene left at the clear depth (the pass's framebuffer is bound)."""
        ctx, gl = self.ctx, self._gl
        set_uniforms(self.sky, buffer_size=tuple(self.size), **self._sky_uniforms(mirror, camera, aspect, guard))
        self.scene.sky_map.use(SKY_UNIT)
        ctx.depth_func = "<="
        gl.DepthMask(0)
        try:
            self.sky_vao.render(moderngl.TRIANGLES, vertices=3)
        finally:
            gl.DepthMask(1)
            ctx.depth_func = "<"

    def _build_mips(self, count: int) -> None:
        """The radiance MIP chain of slots 0 .. count - 1, level by level."""
        ctx = self.ctx
        radiance = self.targets["radiance"]
        w, h = self.size
        for level in range(1, max_level(self.size) + 1):
            lw, lh = max(w >> level, 1), max(h >> level, 1)
            radiance.bind_to_image(MIP_SOURCE_IMAGE, read=True, write=False, level=level - 1)
            radiance.bind_to_image(MIP_TARGET_IMAGE, read=False, write=True, level=level)
            self.mips.run(-(-lw // LOCAL_SIZE), -(-lh // LOCAL_SIZE), count)
            ctx.memory_barrier(moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT)
        ctx.memory_barrier(moderngl.TEXTURE_FETCH_BARRIER_BIT)

    def query_occlusion(self, plan: MirrorPlan, gbuffer_fbo: moderngl.Framebuffer, camera: ViewCamera,
                        aspect: float) -> int:
        """Issue this frame's occlusion queries against the G-buffer's depth (bound fbo); returns
        how many. A reflector whose last query is still running is not asked again."""
        ctx, gl = self.ctx, self._gl
        todo = [r for r in plan.queries if r.name not in self._pending]
        if not todo:
            return 0
        gbuffer_fbo.use()
        ctx.enable_only(moderngl.DEPTH_TEST)
        ctx.depth_func = "<="
        gl.ColorMask(0, 0, 0, 0)
        gl.DepthMask(0)
        self.occluder["view_proj"].write(gl_bytes(camera.view_projection(aspect)))
        try:
            for r in todo:
                query = self._queries.get(r.name)
                if query is None:
                    name = ctypes.c_uint(0)
                    gl.GenQueries(1, ctypes.byref(name))
                    query = self._queries[r.name] = name.value
                gl.BeginQuery(GL_ANY_SAMPLES_PASSED_CONSERVATIVE, query)
                self.scene.draw_object(self.occluder, self.object_of[r.name])
                gl.EndQuery(GL_ANY_SAMPLES_PASSED_CONSERVATIVE)
                self._pending.add(r.name)
        finally:
            gl.ColorMask(1, 1, 1, 1)
            gl.DepthMask(1)
            ctx.depth_func = "<"
        return len(todo)

    def _collect_queries(self) -> None:
        gl = self._gl
        for name in sorted(self._pending):
            query = self._queries[name]
            available = ctypes.c_uint(0)
            gl.GetQueryObjectuiv(query, GL_QUERY_RESULT_AVAILABLE, ctypes.byref(available))
            if not available.value:
                continue  # never wait: the older result stands
            result = ctypes.c_uint(0)
            gl.GetQueryObjectuiv(query, GL_QUERY_RESULT, ctypes.byref(result))
            self.occlusion.record(name, int(result.value), self.frame - 1)
            self._pending.discard(name)

    # -- for the shading passes --------------------------------------------------------------------
    def set_units(self, first_unit: int) -> None:
        """Texture units of the arrays (as `mirror_defines(first_unit)` told the shaders)."""
        self._units = tuple(mirror_defines(first_unit).values())

    def bind_buffers(self) -> None:
        self.slot_buffer.bind_to_storage_buffer(MIRROR_SLOT_BINDING)
        self.object_buffer.bind_to_storage_buffer(MIRROR_OBJECT_BINDING)

    def bind(self) -> None:
        """The arrays on their units and the slot and object tables (before a shading dispatch)."""
        targets = self.targets or self._dummy
        for unit, name in zip(self._units, TARGETS):
            targets[name].use(unit)
        self.bind_buffers()

    def read(self, slot: int, target: str = "radiance") -> np.ndarray:
        """(H, W, 4) float32 of one slot's target at level 0, GL orientation (row 0 = bottom),
        as bench/mirror_projection.py indexes images. For tests and debugging (waits for the GPU)."""
        tex = self.targets[target]
        w, h, layers = tex.width, tex.height, tex.layers
        dtype = np.float32 if target == "position" else np.float16
        data = np.frombuffer(tex.read(), dtype).reshape(layers, h, w, 4)
        return data[slot].astype(np.float32)

    def stats(self, lobed_objects: dict[int, str] | None = None, cube_mapped=()) -> dict:
        """Passes run and skipped (viewer/reflectors.py `MirrorPlan.stats`) with names, and the
        planar objects with lobes that got no pass this frame and what they show instead."""
        plan = self.plan_ if self.active else None
        out = {"budget": self.budget, "layers": self.layers, "reflectors": len(self.reflectors)}
        if plan is None:
            plan = MirrorPlan(passes=[], skipped=[], queries=[], budget=self.budget)
            self._drawn = []
        out.update({**plan.stats(), "budget": self.budget})
        out["passes"] = [{**self._pass_record(d), "screen_area": round(p.screen_area, 4),
                          "distance_m": round(p.distance, 3), "guard_scale": round(p.guard, 3)}
                         for d, p in zip(self._drawn, plan.passes)]
        out["skipped_reflectors"] = {reason.value: names for reason, names in plan.skipped_by_reason().items()
                                     if names}
        out["occlusion_queries_pending"] = len(self._pending)
        lobed = lobed_objects or {}
        in_pass = {self.object_of[name] for p in plan.passes for name in p.names}
        missing = {i: name for i, name in lobed.items() if i in dict(self.objects) and i not in in_pass}
        out["planar_without_pass"] = {
            "cube_map": [name for i, name in missing.items() if i in cube_mapped],
            "no_specular": [name for i, name in missing.items() if i not in cube_mapped],
        }
        return out

    def _pass_record(self, drawn: dict) -> dict:
        """What a pass drew (reads its draw states back from the GPU)."""
        r = self.draws.record(drawn["region"])
        return {"reflectors": drawn["reflectors"], "scissor": drawn["scissor"],
                "objects_drawn": r["objects_drawn"], "triangles": r["triangles"],
                "objects_behind_plane": len(r["objects_behind_plane"]), "objects_outside_view": len(r["objects_culled"])}

    # -- cleaning up -------------------------------------------------------------------------------
    def _release_targets(self) -> None:
        gl = self._gl
        release_framebuffer(self.ctx, self._ids_fbo)
        self._ids_fbo = None
        for glo in self._fbos:
            gl.DeleteFramebuffers(1, ctypes.byref(ctypes.c_uint(glo)))
        self._fbos = []
        for tex in self.targets.values():
            tex.release()
        self.targets = {}
        if self.depth is not None:
            self.depth.release()
            self.depth = None
        self.size = None

    def release(self) -> None:
        self._release_targets()
        gl = self._gl
        for query in self._queries.values():
            gl.DeleteQueries(1, ctypes.byref(ctypes.c_uint(query)))
        self._queries.clear()
        for tex in self._dummy.values():
            tex.release()
        for obj in (self.sky_vao, self.ids or self.raster, self.occluder, self.sky, self.mips, self.slot_buffer,
                    self.object_buffer):
            obj.release()


def max_level(size: tuple[int, int]) -> int:
    """The last level of the radiance chain (bench/mirror_projection.py max_mip_level)."""
    return int(np.floor(np.log2(max(int(size[0]), int(size[1]), 1))))


class _timed:
    """`with _timed(timer, name)`: a PassTimer section, or nothing without a timer."""

    def __init__(self, timer, name: str):
        self.cm = timer(name) if timer is not None else None

    def __enter__(self):
        if self.cm is not None:
            self.cm.__enter__()

    def __exit__(self, *exc):
        if self.cm is not None:
            return self.cm.__exit__(*exc)
        return False
