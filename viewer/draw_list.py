"""GPU-driven drawing of the static scene: every raster pass draws all objects with one
multi-draw per texture batch, culled on the GPU.

    draws = DrawList(ctx, scene)
    programs = BatchPrograms(ctx, "gbuffer.vert", "gbuffer.frag", defines)
    draws.draw(programs, view_proj, region=0, hidden={3})          # the G-buffer
    draws.draw(programs, mirror_vp, region=1, clip_plane=plane)    # a mirror pass
    draws.record(0)     # what region 0's last draw drew and left out, and why (reads the GPU)

The scene's meshes lie in one vertex and one index buffer (viewer/gpu_meshes.py), each object a
range of the indices, and its material and light-map layer in a storage buffer indexed by the
object id every vertex carries (shaders/scene_objects.glsl). So a draw needs no per-object
uniform: `draw` runs shaders/cull.comp, which writes one glDrawElementsIndirect command per
object (instance count 0 for objects culled), then issues glMultiDrawElementsIndirect
(moderngl's `render_indirect`) once per *batch*: the objects whose materials bind the same
textures (all untextured materials form one batch). The CPU work per draw is a fixed handful of
GL calls, whatever the object count; it grows only with the textured materials. Each batch is
drawn by its own variant of the pass's program (`BatchPrograms`), which holds the texture code of
the batch's kinds only (an untextured batch's: none).

Draws the driver never sees: where the driver offers glMultiDrawElementsIndirectCount (GL 4.6 or
ARB_indirect_parameters; `indirect_count`), shaders/compact.comp packs each batch's drawn commands,
in order, to the front of its range and writes their number to a buffer, and the multi-draw reads
that number on the GPU (viewer/gl.py `multi_draw_indirect_count`): the driver walks the draws that
survived culling, not one command per object (at 10,000 objects a multi-draw of mostly empty
commands cost the driver about 3 ms a frame on an H200: issue 27). The same pixels either way.
Without the entry point, the multi-draw of every command as before; so on a software renderer
(llvmpipe), where the packing pass cost 2-3 % of the frame at 1,000-10,000 objects and saved
nothing (docs/VIEWER.md), unless asked for.

Reads: the scene's object table, vertex and index buffers. Writes: the framebuffer bound by the
caller, and per region (with `indirect_count` also its packed commands and per-batch counts) (a draw that must not overwrite another's commands in the same frame: the
G-buffer, each mirror pass) its commands and the reason each object was or was not drawn
(`DRAWN`, `HIDDEN`, `EMPTY`, `OUTSIDE_VIEW`, `BEHIND_PLANE`, shaders/cull.comp), which `record`
reads back only when asked (the stats), never per frame.

Culling: an object is left out when its world box lies wholly outside one frustum plane (the
test of viewer/camera.py `in_frustum`, which this pass replaces: the box corner farthest along
the plane's normal), wholly behind the clip plane (mirror passes), or its id is hidden.

Levels of detail: in a scene uploaded with them (viewer/gpu_scene.py `lod`, viewer/gpu_meshes.py, viewer/lod.py) a draw
given `detail` draws each object at the coarsest level that still has about the triangles its
pixels can show (the bake's cube-map renders); the others draw every object whole.
"""
from __future__ import annotations

from contextlib import contextmanager

import moderngl
import numpy as np

from glint.viewer.camera import frustum_planes, gl_bytes
from glint.viewer.gl import DRAW_ELEMENTS_INDIRECT_COMMAND_BYTES, GL, software_renderer
from glint.viewer.gl_bindings import (
    ANISOTROPY_TEXTURE_UNIT,
    DRAW_BATCH_BINDING,
    DRAW_COMMAND_BINDING,
    DRAW_COMPACT_BINDING,
    DRAW_COUNT_BINDING,
    DRAW_HIDDEN_BINDING,
    DRAW_ORDER_BINDING,
    DRAW_STATE_BINDING,
    EMISSION_TEXTURE_UNIT,
    KD_TEXTURE_UNIT,
    LIGHTMAP_UNIT,
    METALLIC_ROUGHNESS_TEXTURE_UNIT,
    NORMAL_TEXTURE_UNIT,
    OBJECT_LOD_BINDING,
)
from glint.viewer.lod import LOD_LEVELS
from glint.viewer.shader_source import compute_program, raster_program, set_uniforms

# Why an object was or was not drawn (shaders/cull.comp writes one per object and region).
DRAW_STATES = {"DRAWN": 0, "HIDDEN": 1, "EMPTY": 2, "OUTSIDE_VIEW": 3, "BEHIND_PLANE": 4, "TOO_SMALL": 5}
COMMAND_BYTES = DRAW_ELEMENTS_INDIRECT_COMMAND_BYTES  # one indirect draw command (viewer/gl.py)
CULL_GROUP = 64     # cull.comp's local size
COMPACT_GROUP = 256  # compact.comp's local size: the commands one step of its scan packs
TEXTURE_UNITS = (KD_TEXTURE_UNIT, EMISSION_TEXTURE_UNIT, METALLIC_ROUGHNESS_TEXTURE_UNIT, NORMAL_TEXTURE_UNIT,
                 ANISOTROPY_TEXTURE_UNIT)


def draw_defines() -> dict:
    return {**DRAW_STATES, "CULL_GROUP": CULL_GROUP, "COMPACT_GROUP": COMPACT_GROUP, "LOD_LEVELS": LOD_LEVELS}


def batches(textures_of_material: list[tuple], materials: np.ndarray) -> tuple[np.ndarray, list]:
    """Objects grouped by the textures their material binds: -> (order: object ids, batch after
    batch, each in id order; [(first, count, textures)] per batch, `first` an index into order)."""
    keys: dict[tuple, int] = {}
    batch_of = np.array([keys.setdefault(tuple(id(t) for t in textures_of_material[m]), len(keys))
                         for m in materials], np.int64)
    order = np.argsort(batch_of, kind="stable")
    firsts = np.searchsorted(batch_of[order], np.arange(len(keys)))
    counts = np.bincount(batch_of, minlength=len(keys))
    example = {b: textures_of_material[m] for m, b in zip(materials, batch_of)}
    return order.astype(np.int32), [(int(f), int(c), example[b]) for b, (f, c) in enumerate(zip(firsts, counts))]


class BatchPrograms:
    """A raster pass's program (shaders/raster_surface.glsl's surface) in one variant per set of texture
    kinds a batch binds: TEXTURE_KINDS, the MAT_*_TEXTURE flags its materials have, leaves the other
    kinds' code out. On llvmpipe, which runs both sides of every branch, an untextured batch paid for
    every kind's look-up per fragment (docs/VIEWER.md, "Raster programs per texture batch"). Variants
    are compiled on first use; uniforms given to `set` reach every variant, later ones too."""

    def __init__(self, ctx: moderngl.Context, vertex: str, fragment: str, defines: dict):
        self.ctx, self._shaders, self._defines = ctx, (vertex, fragment), dict(defines)
        self._variants: dict[int, moderngl.Program] = {}
        self._uniforms: dict = {}

    def __getitem__(self, kinds: int) -> moderngl.Program:
        """The variant for texture kinds `kinds` (a mask of MAT_*_TEXTURE flags)."""
        if kinds not in self._variants:
            program = raster_program(self.ctx, *self._shaders, {**self._defines, "TEXTURE_KINDS": int(kinds)})
            set_uniforms(program, **self._uniforms)
            self._variants[kinds] = program
        return self._variants[kinds]

    def set(self, **uniforms) -> None:
        """Uniforms by name for every variant (set_uniforms)."""
        self._uniforms.update(uniforms)
        for program in self._variants.values():
            set_uniforms(program, **uniforms)

    def release(self) -> None:
        for program in self._variants.values():
            program.release()
        self._variants.clear()


class DrawList:
    def __init__(self, ctx: moderngl.Context, scene, defines: dict | None = None, indirect_count: bool | None = None):
        """indirect_count: pack the drawn commands and let the GPU count them (`can_count`: where the
        driver can); None: unless the renderer is a software one (module docstring); False: every
        command goes to the driver. The attribute may be switched between frames where `can_count`."""
        self.ctx = ctx
        self.scene = scene
        self._gl = GL(ctx)
        self.count = len(scene.objects)
        self.lod = getattr(scene, "lod_buffer", None) is not None  # levels of detail to pick from (viewer/lod.py)
        self.cull_program = compute_program(ctx, "cull.comp", {**(defines or {}), **draw_defines(),
                                                               **({"DRAW_LOD": 1} if self.lod else {})})
        order, self.batches = batches([scene.material_textures(m) for m in range(scene.material_count)],
                                      np.array([o.material for o in scene.objects], np.int64))
        self.order = order
        # Per batch, the texture kinds of its materials (the same for all of them: a batch is the materials
        # that bind the same textures, and a material has a kind's flag where it has its texture).
        self.batch_kinds = [scene.material_texture_kinds(scene.objects[order[first]].material)
                            for first, _, _ in self.batches]
        with self._gl.checked(f"upload the draw order of {self.count} objects"):
            self.order_buffer = ctx.buffer(np.ascontiguousarray(order if len(order) else np.zeros(1, np.int32)).tobytes())
        self.can_count = bool(self.count and self._gl.MultiDrawElementsIndirectCount)
        wanted = not software_renderer(ctx) if indirect_count is None else indirect_count
        self.indirect_count = bool(wanted and self.can_count)
        self._defines = defines or {}
        self.compact_program = self.batch_buffer = None  # made by the first counted cull (`_counting`)
        self.regions = 0
        self.command_buffer = self.state_buffer = self.hidden_buffer = None
        self.compact_buffer = self.count_buffer = None
        self._batch_of_object = None  # made by the first `batch_of_object`
        self._checked: set = set()  # regions whose counted multi-draw has been checked for GL errors
        self._hidden: list = []   # per region: the hidden set its slice of hidden_buffer holds
        self._records: dict = {}  # region -> the record, once read back this frame
        self.reserve(1)

    def reserve(self, regions: int) -> None:
        """Room for `regions` regions' commands, states and hidden flags. Growing replaces the
        buffers, losing what earlier regions hold (their states for `record`), so the renderer
        reserves every pass's region before its first frame (viewer/passes/mirror.py)."""
        if regions <= self.regions:
            return
        n = max(self.count, 1)
        for buf in (self.command_buffer, self.state_buffer, self.hidden_buffer):
            if buf is not None:
                buf.release()
        with self._gl.checked(f"allocate the draw commands of {regions} passes x {n} objects"):
            self.command_buffer = self.ctx.buffer(reserve=regions * n * COMMAND_BYTES)
            self.state_buffer = self.ctx.buffer(reserve=regions * n * 4)
            self.hidden_buffer = self.ctx.buffer(np.zeros(regions * n, np.uint32).tobytes())
        self.regions = regions
        if self.compact_program is not None:
            self._allocate_packed()
        self._checked = set()
        self._hidden = [frozenset()] * regions

    def _set_hidden(self, region: int, hidden) -> None:
        hidden = frozenset(int(i) for i in hidden if 0 <= int(i) < self.count)
        if hidden == self._hidden[region]:
            return
        flags = np.zeros(max(self.count, 1), np.uint32)
        flags[list(hidden)] = 1
        self.hidden_buffer.write(flags.tobytes(), offset=region * max(self.count, 1) * 4)
        self._hidden[region] = hidden

    def cull(self, view_proj: np.ndarray, region: int = 0, hidden=(), clip_plane=None,
             min_radius_ndc: float = 0.0, detail: tuple | None = None) -> None:
        """Write region's draw commands and states (shaders/cull.comp): every object whose box may
        lie in the frustum of `view_proj` and, when `clip_plane` (a, b, c, d) is given, on its
        positive side, unless its index is in `hidden` or (min_radius_ndc > 0, non-emitters) its
        bounding sphere projects to a radius under min_radius_ndc. `detail` = (eye, scale), in a
        scene with levels of detail: each object at the coarsest level that keeps pi (asin(r / d)
        scale)^2 triangles for the disc its bounding sphere covers seen from the eye (scale: pixels
        per radian times the square root of the triangles wanted per pixel); None: all whole."""
        if self.count == 0:
            return
        self.reserve(region + 1)
        self._set_hidden(region, hidden)
        self._records.pop(region, None)
        n = self.count
        vp = np.asarray(view_proj, np.float64)
        planes = frustum_planes(vp)
        planes /= np.sqrt(np.maximum(np.einsum("ij,ij->i", planes[:, :3], planes[:, :3]), 1e-60))[:, None]
        clip = np.zeros(4) if clip_plane is None else np.asarray(clip_plane, np.float64)
        small = {}
        if min_radius_ndc > 0:  # the projection's larger axis scale (rows 0 and 1 of P V, V orthonormal)
            small = {"proj_scale": float(np.sqrt(max(vp[0, :3] @ vp[0, :3], vp[1, :3] @ vp[1, :3]))),
                     "view_row": tuple(map(float, vp[3]))}
        set_uniforms(self.cull_program, first_command=region * n, object_count=n,
                     use_clip=int(clip_plane is not None), clip_plane=tuple(map(float, clip)),
                     min_radius_ndc=float(min_radius_ndc), **small)
        self.cull_program["planes"].write(planes.astype(np.float32).tobytes())
        if self.lod:
            eye, scale = detail if detail is not None else ((0.0, 0.0, 0.0), 0.0)
            set_uniforms(self.cull_program, lod_eye=tuple(map(float, eye)), lod_scale=float(scale))
            self.scene.lod_buffer.bind_to_storage_buffer(OBJECT_LOD_BINDING)
        self.scene.object_buffer.bind_to_storage_buffer(self.scene.object_binding)
        self.order_buffer.bind_to_storage_buffer(DRAW_ORDER_BINDING)
        self.command_buffer.bind_to_storage_buffer(DRAW_COMMAND_BINDING)
        self.state_buffer.bind_to_storage_buffer(DRAW_STATE_BINDING)
        self.hidden_buffer.bind_to_storage_buffer(DRAW_HIDDEN_BINDING)
        self.cull_program.run(-(-n // CULL_GROUP))
        self.ctx.memory_barrier(moderngl.COMMAND_BARRIER_BIT | moderngl.SHADER_STORAGE_BARRIER_BIT)
        if self._counting():  # the drawn commands packed per batch, and counted (compact.comp)
            set_uniforms(self.compact_program, first_command=region * n, first_count=region * len(self.batches))
            self.batch_buffer.bind_to_storage_buffer(DRAW_BATCH_BINDING)
            self.compact_buffer.bind_to_storage_buffer(DRAW_COMPACT_BINDING)
            self.count_buffer.bind_to_storage_buffer(DRAW_COUNT_BINDING)
            self.compact_program.run(len(self.batches))
            self.ctx.memory_barrier(moderngl.COMMAND_BARRIER_BIT | moderngl.SHADER_STORAGE_BARRIER_BIT)

    def draw(self, programs: BatchPrograms, view_proj: np.ndarray, region: int = 0, hidden=(), clip_plane=None,
             min_radius_ndc: float = 0.0, detail: tuple | None = None) -> None:
        """Draw every object in view, each texture batch with its variant of `programs` (the framebuffer
        and state set by the caller): `cull`, then one multi-draw per texture batch."""
        if self.count == 0:
            return
        self.cull(view_proj, region, hidden, clip_plane, min_radius_ndc, detail)
        scene, first_command = self.scene, region * self.count
        programs.set(view_proj=gl_bytes(view_proj))
        scene.bind_materials()
        scene.lightmaps.use(LIGHTMAP_UNIT)
        counting = self._counting()
        first_count = region * len(self.batches)
        check = counting and region not in self._checked  # the first counted draw of each region, once per allocation
        with self._gl.checked("draw with glMultiDrawElementsIndirectCount") if check else _unchecked():
            for b, (first, count, textures) in enumerate(self.batches):
                program = programs[self.batch_kinds[b]]
                vao = scene.vertex_array(program)
                bind_textures(textures)
                if counting:
                    self._gl.multi_draw_indirect_count(program, vao, self.compact_buffer, first_command + first,
                                                       self.count_buffer, 4 * (first_count + b), count)
                else:
                    vao.render_indirect(self.command_buffer, moderngl.TRIANGLES, count=count,
                                        first=first_command + first)
        if counting:
            self._checked.add(region)

    def batch_of_object(self) -> moderngl.Buffer:
        """(objects,) int32 on the GPU: the texture batch of each object (`batches`), for passes that
        work batch by batch after the draw (shaders/visibility_resolve.comp). Made on first use."""
        if self._batch_of_object is None:
            table = np.zeros(max(self.count, 1), np.int32)
            for b, (first, count, _) in enumerate(self.batches):
                table[self.order[first:first + count]] = b
            with self._gl.checked(f"upload the texture batch of {self.count} objects"):
                self._batch_of_object = self.ctx.buffer(table.tobytes())
        return self._batch_of_object

    def _counting(self) -> bool:
        """Whether draws are packed and counted now; the first time, compact.comp, the batch table and
        the packed commands' buffers are made (not at all where the counted draw stays off)."""
        if not (self.indirect_count and self.can_count):
            return False
        if self.compact_program is None:
            self.compact_program = compute_program(self.ctx, "compact.comp", {**self._defines, **draw_defines()})
            table = np.array([(first, count) for first, count, _ in self.batches], np.int32)
            with self._gl.checked(f"upload the {len(table)} draw batches"):
                self.batch_buffer = self.ctx.buffer(table.tobytes())
            self._allocate_packed()
        return True

    def _allocate_packed(self) -> None:
        """The packed commands and per-batch counts of `regions` passes (compact.comp writes them),
        replacing those of fewer."""
        for buf in (self.compact_buffer, self.count_buffer):
            if buf is not None:
                buf.release()
        n = max(self.count, 1)
        with self._gl.checked(f"allocate the packed draw commands of {self.regions} passes x {n} objects"):
            self.compact_buffer = self.ctx.buffer(reserve=self.regions * n * COMMAND_BYTES)
            self.count_buffer = self.ctx.buffer(reserve=self.regions * len(self.batches) * 4)

    def draw_counts(self, region: int = 0) -> np.ndarray:
        """(batches,) how many commands of each batch region's last draw handed the GPU (reads the
        GPU); with `indirect_count` only."""
        B = len(self.batches)
        return np.frombuffer(self.count_buffer.read(size=4 * B, offset=4 * B * region), np.uint32)

    def states(self, region: int = 0) -> np.ndarray:
        """(objects,) the DRAW_STATES value of each object in region's last cull (reads the GPU)."""
        n = self.count
        if not n or region >= self.regions:
            return np.zeros(0, np.uint32)
        return np.frombuffer(self.state_buffer.read(size=4 * n, offset=4 * region * n), np.uint32)

    def record(self, region: int = 0) -> dict:
        """What region's last draw did (reads its states back from the GPU): objects_drawn,
        triangles, and the names of the objects left out by reason."""
        if region in self._records:
            return self._records[region]
        out = {"objects_drawn": 0, "triangles": 0, "objects_culled": [], "objects_empty": [],
               "objects_hidden": [], "objects_behind_plane": [], "objects_too_small": []}
        n = self.count
        if n and region < self.regions:
            states = self.states(region)
            objects = self.scene.objects
            drawn = states == DRAW_STATES["DRAWN"]
            out["objects_drawn"] = int(drawn.sum())
            # what the commands draw: an object's level of detail may have fewer than its triangles
            commands = np.frombuffer(self.command_buffer.read(size=COMMAND_BYTES * n, offset=COMMAND_BYTES * region * n),
                                     np.uint32).reshape(n, COMMAND_BYTES // 4)
            out["triangles"] = int((commands[:, 0].astype(np.int64) * commands[:, 1]).sum() // 3)
            for key, state in (("objects_culled", "OUTSIDE_VIEW"), ("objects_empty", "EMPTY"),
                               ("objects_hidden", "HIDDEN"), ("objects_behind_plane", "BEHIND_PLANE"),
                               ("objects_too_small", "TOO_SMALL")):
                out[key] = [objects[i].name for i in np.flatnonzero(states == DRAW_STATES[state])]
        self._records[region] = out
        return out

    def release(self) -> None:
        for buf in (self.command_buffer, self.state_buffer, self.hidden_buffer, self.order_buffer,
                    self.compact_buffer, self.count_buffer, self.batch_buffer, self._batch_of_object):
            if buf is not None:
                buf.release()
        self.cull_program.release()
        if self.compact_program is not None:
            self.compact_program.release()


def bind_textures(textures: tuple) -> None:
    """A batch's textures on the raster surface's units (shaders/raster_surface.glsl)."""
    for unit, texture in zip(TEXTURE_UNITS, textures):
        texture.use(unit)


@contextmanager
def _unchecked():
    """`GL.checked`'s stand-in where the call was checked before: glGetError may stall a pipeline."""
    yield
