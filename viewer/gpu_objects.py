"""The objects on the GPU: a row per object (`SCENE_OBJECT_DTYPE`, std430) in one shader storage buffer
at SCENE_OBJECT_BINDING (bound by viewer/draw_list.py), read as shaders/scene_objects.glsl's
`scene_objects` by the object id every vertex carries: the raster passes take the object's material
and back-side light-map layer from it (shaders/raster_surface.glsl), the culling its world box, index
range and whether it emits (shaders/cull.comp), so one multi-draw draws every object.
"""
from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from glint.viewer.gl import GL
from glint.viewer.gl_bindings import SCENE_OBJECT_BINDING

# Per object (std430; shaders/scene_objects.glsl): world box (lo, hi; lo.w 1 for emitters) and (material,
# back-side light-map layer offset, first index, index count).
SCENE_OBJECT_DTYPE = np.dtype([("lo", "<f4", 4), ("hi", "<f4", 4), ("info", "<i4", 4)])


@dataclass
class GpuObject:
    name: str
    material: int
    role: str
    triangles: int
    bounds: np.ndarray  # (2, 3) world-space box
    back_layer: int  # light-map layers a back face adds to its page: 0 = no back-side light map
    first_index: int = 0  # its first index in the scene's index buffer (3 per triangle)


class GpuObjectTable:
    binding = SCENE_OBJECT_BINDING

    def __init__(self, ctx: moderngl.Context, gl: GL, objects: list[GpuObject], emissive: np.ndarray):
        """objects: with their index ranges in the scene's index buffer (viewer/gpu_meshes.py);
        emissive: per material whether it emits (viewer/gpu_materials.py `GpuMaterials.emissive`)."""
        self.ctx, self._gl, self.objects = ctx, gl, objects
        table = np.zeros(max(len(objects), 1), SCENE_OBJECT_DTYPE)
        for k, obj in enumerate(objects):
            table[k]["lo"][:3], table[k]["hi"][:3] = obj.bounds
            table[k]["info"] = (obj.material, obj.back_layer, obj.first_index, 3 * obj.triangles)
        self.table = table
        self.buffer = None
        self.upload(emissive)

    def upload(self, emissive: np.ndarray) -> None:
        """The table (again), lo.w marking the objects whose material emits: a material edit changes
        it (viewer/draw_list.py never culls emitters as too small)."""
        table = self.table
        if self.objects:
            table["lo"][:len(self.objects), 3] = emissive[table["info"][:len(self.objects), 0]]
        if self.buffer is not None:
            self.buffer.release()
        with self._gl.checked(f"upload the object table ({len(self.objects)} objects)"):
            self.buffer = self.ctx.buffer(table.tobytes())

    def release(self) -> None:
        self.buffer.release()
