"""The meshes on the GPU: every object's vertices in one vertex buffer, interleaved as `VERTEX_DTYPE`,
and its triangles in one index buffer of global vertex indices (an object is a range of it:
`GpuObject.first_index`, 3 x `triangles`), and with levels of detail (viewer/lod.py) each object's
coarser levels after them and their ranges in one storage buffer (`OBJECT_LOD_DTYPE`).

The raster programs (shaders/raster_surface.glsl: the G-buffer, mirror and cube-map passes) read the
vertices as the attributes `VERTEX_ATTRIBUTES`, through one vertex array per program (`vertex_array`);
the multi-draw of viewer/draw_list.py draws the index ranges, and its culling (shaders/cull.comp)
reads the levels' table at OBJECT_LOD_BINDING. Each vertex carries its object's index, by which the
raster passes read the object table (viewer/gpu_objects.py) and the G-buffer stores it beside the
material (an object picks its cube map). Tangents: viewer/tangent_frames.py. Light-map coordinates
and page per vertex (`lm_uv`, `lm_page`): row 0 of a page (v = 0) is GL's t = 0, no flip anywhere.
"""
from __future__ import annotations

import moderngl
import numpy as np

from glint.core.errors import GlintError
from glint.viewer import lod
from glint.viewer.gl import GL
from glint.viewer.gpu_objects import GpuObject
from glint.viewer.gpu_textures import clean
from glint.viewer.lod import LOD_LEVELS
from glint.viewer.tangent_frames import surface_tangents

VERTEX_DTYPE = np.dtype([("position", "<f4", 3), ("normal", "<f4", 3), ("tangent", "<f4", 4),
                         ("uv", "<f4", 2), ("lm_uv", "<f4", 2), ("lm_page", "<i4"), ("object", "<i4"),
                         ("color", "<f4", 3)])
VERTEX_FORMAT = "3f 3f 4f 2f 2f 1i 1i 3f"
VERTEX_ATTRIBUTES = ("in_position", "in_normal", "in_tangent", "in_uv", "in_lm_uv", "in_lm_page", "in_object",
                     "in_color")


def vertex_defines() -> dict:
    """The vertex layout as shaders/visibility_resolve.comp reads the vertex buffer, in 32-bit words:
    VERTEX_WORDS per vertex, VERTEX_<FIELD> the word offset of each field of VERTEX_DTYPE."""
    out = {"VERTEX_WORDS": VERTEX_DTYPE.itemsize // 4}
    for name, (dtype, offset) in VERTEX_DTYPE.fields.items():
        out[f"VERTEX_{name.upper()}"] = offset // 4
    return out


# Per object its levels of detail, finest first (viewer/lod.py; std430, shaders/cull.comp): first
# index in the scene's index buffer and index count of each; count 0 = no such level.
OBJECT_LOD_DTYPE = np.dtype([("first", "<i4", LOD_LEVELS), ("count", "<i4", LOD_LEVELS)])


class GpuMeshes:
    def __init__(self, ctx: moderngl.Context, gl: GL, bake, with_lod: bool = False):
        """Every object's mesh of the bake (`objects`: GpuObject, with its index range); with_lod: also its
        levels of detail (`lod_table`, `lod_buffer`; None without)."""
        self.ctx, self._gl = ctx, gl
        manifest = bake.model
        front_pages = len(manifest.lightmaps)
        # The tangent frame serves the lobes only (their anisotropy and the normal map's shading
        # normal; the diffuse part is the light map's): a scene without lobes (the bake's diffuse
        # cube-map renders) skips MikkTSpace.
        frames = any(m.lobes for m in manifest.materials)
        parts = [object_vertices(i, entry, mesh, front_pages if bake.has_back(i) else 0, frames)
                 for i, (entry, mesh) in enumerate(zip(manifest.objects, bake.meshes))]
        self.objects = [obj for obj, _, _ in parts]
        self.triangles = sum(o.triangles for o in self.objects)
        drawn = [o.bounds for o in self.objects if o.triangles]
        self.bounds = (np.stack([np.min([b[0] for b in drawn], axis=0), np.max([b[1] for b in drawn], axis=0)])
                       if drawn else np.zeros((2, 3)))
        vertices, indices = [], []
        first_vertex = first_index = 0
        for obj, v, idx in parts:
            obj.first_index = first_index
            vertices.append(v)
            indices.append(idx.reshape(-1) + np.uint32(first_vertex))
            first_vertex += len(v)
            first_index += 3 * obj.triangles
        self.lod_table = None
        if with_lod:  # the levels' vertices and triangles follow every object's own
            self.lod_table = np.zeros(max(len(parts), 1), OBJECT_LOD_DTYPE)
            for k, (obj, v, idx) in enumerate(parts):
                for level, (source, positions, tris) in enumerate(lod.levels(v["position"], idx)):
                    self.lod_table[k]["first"][level], self.lod_table[k]["count"][level] = first_index, tris.size
                    moved = v[source]
                    moved["position"] = positions
                    vertices.append(moved)
                    indices.append(tris.reshape(-1) + np.uint32(first_vertex))
                    first_vertex += len(moved)
                    first_index += tris.size
        what = f"the meshes ({len(parts)} objects, {self.triangles} triangles)"
        with self._gl.checked(f"upload {what}"):
            v = np.concatenate(vertices) if vertices else np.zeros(1, VERTEX_DTYPE)
            i = np.concatenate(indices) if indices and first_index else np.zeros(3, np.uint32)
            self.vertex_buffer = self.ctx.buffer(v.tobytes())
            self.index_buffer = self.ctx.buffer(i.astype(np.uint32).tobytes())
            self.lod_buffer = None if self.lod_table is None else self.ctx.buffer(self.lod_table.tobytes())
        self._vaos: dict = {}

    def vertex_array(self, program: moderngl.Program) -> moderngl.VertexArray:
        """The scene's vertex array for `program` (made once; attributes it lacks are skipped)."""
        key = program.glo
        if key not in self._vaos:
            self._vaos[key] = self.ctx.vertex_array(
                program, [(self.vertex_buffer, VERTEX_FORMAT, *VERTEX_ATTRIBUTES)], index_buffer=self.index_buffer,
                index_element_size=4, skip_errors=True)
        return self._vaos[key]

    def draw_object(self, program: moderngl.Program, index: int) -> None:
        """One object alone (the occlusion queries of planar reflectors): its range of the index buffer."""
        obj = self.objects[index]
        if obj.triangles:
            self.vertex_array(program).render(moderngl.TRIANGLES, vertices=3 * obj.triangles, first=obj.first_index)

    def release(self) -> None:
        for vao in self._vaos.values():
            vao.release()
        self._vaos.clear()
        for buf in (self.vertex_buffer, self.index_buffer, self.lod_buffer):
            if buf is not None:
                buf.release()


def object_vertices(index: int, entry: dict, mesh: dict, back_layer: int, frames: bool = True) -> tuple:
    """(GpuObject, its vertices as VERTEX_DTYPE, its (M, 3) local indices); frames: False leaves
    the tangents 0 (no tangent frame: shaders/raster_surface.glsl)."""
    indices = np.asarray(mesh.get("indices", np.zeros((0, 3))), np.uint32).reshape(-1, 3)
    positions = np.asarray(mesh["positions"], np.float64).reshape(-1, 3)
    n = len(positions)
    if len(indices) and (not np.all(np.isfinite(positions)) or int(indices.max()) >= n):
        raise GlintError(f"bake: object '{entry['name']}' has invalid positions or indices; run "
                         "`glint bake --force`")
    normals = clean(mesh["normals"], None).reshape(-1, 3)  # zero-length is guarded in GLSL
    uvs = mesh.get("uvs")
    uvs = None if uvs is None else clean(uvs, None).reshape(-1, 2)
    supplied = mesh.get("tangents")  # glTF TANGENT
    # Tangents may split vertices (MikkTSpace's handedness): the other attributes follow `source`.
    if frames:
        source, indices, frame = surface_tangents(positions, normals, uvs, indices,
                                                  None if supplied is None else clean(supplied, None).reshape(-1, 4))
    else:
        source, frame = np.arange(n), 0.0
    indices = indices.astype(np.uint32)
    positions = positions[source]
    v = np.zeros(len(source), VERTEX_DTYPE)
    v["position"] = positions
    v["normal"] = normals[source]
    v["tangent"] = frame
    if uvs is not None:
        v["uv"] = uvs[source]
    v["object"] = index
    colors = mesh.get("colors")  # glTF COLOR_0; -1 without (shaders/raster_surface.glsl)
    v["color"] = -1.0 if colors is None else np.clip(clean(colors), 0.0, 1.0).reshape(-1, 3)[source]
    v["lm_uv"] = clean(mesh["lm_uv"], None).reshape(-1, 2)[source]
    v["lm_page"] = np.asarray(mesh["lm_page"], np.int32).reshape(-1)[source]
    bounds = (np.stack([positions[indices.ravel()].min(axis=0), positions[indices.ravel()].max(axis=0)])
              if len(indices) else np.zeros((2, 3)))
    obj = GpuObject(entry.name, int(entry.material), entry.role, len(indices), bounds,
                    back_layer)
    return obj, (v if len(indices) else v[:0]), indices
