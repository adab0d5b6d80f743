"""Every texture unit, image unit, storage-buffer binding and fragment-output location of the
viewer's programs, in one table.

Python binds with these names (`texture.use(SKY_UNIT)`, `image.bind_to_image(TARGET_IMAGE, ...)`,
`buffer.bind_to_storage_buffer(MATERIAL_BINDING)`), and every shader gets each integer of this
module whose name ends in _BINDING, _UNIT, _IMAGE or _LOCATION as a `#define` of the same name
(viewer/shader_source.py `glsl_constants`), which its declarations use:

    layout(binding = SKY_UNIT) uniform sampler2D sky_map;

so each number stands here once and the two sides cannot drift apart.

Storage-buffer bindings are global: the scene's buffers are bound once for several programs, so
no two buffers share a number. Texture and image units are per program (a dispatch binds what it
reads right before it runs), so programs that never run together reuse the low numbers. The
shading programs' units past SHADING_CUBE_UNIT depend on the scene (one cube-map array per face
size, viewer/cubemaps.py): `shading_units` lays them out.
"""
from __future__ import annotations

# -- shader storage buffers (all programs) -----------------------------------------------------------
MATERIAL_BINDING = 0        # materials.glsl: viewer/gpu_materials.py MATERIAL_DTYPE rows
LOBE_BINDING = 1            # materials.glsl: LOBE_DTYPE rows
PATTERN_BINDING = 2         # specular.glsl: the lobes' pattern positions (xi1, xi2)
LOBE_PATTERN_BINDING = 3    # specular.glsl: PATTERN_DTYPE rows
CUBE_OBJECT_BINDING = 4     # cubemaps.glsl: viewer/cubemaps.py CUBE_OBJECT_DTYPE rows
BOUNDING_PLANE_BINDING = 5  # cubemaps.glsl: PLANE_DTYPE rows
EVAL_IN_BINDING = 6         # bench/glsl_eval.py, the test harness: its inputs ...
EVAL_OUT_BINDING = 7        # ... and outputs
SPECULAR_WORK_BINDING = 8   # specular.glsl: the queued tiles and counters (viewer/passes/shading.py)
# 9: free (was a flag per specular tile, before shading.comp queued its tiles per work group)
MIRROR_SLOT_BINDING = 10    # mirror_buffer.glsl: per mirror-buffer slot (viewer/passes/mirror.py SLOT_DTYPE)
MIRROR_OBJECT_BINDING = 11  # mirror_buffer.glsl: per object its slot this frame
LOBE_MR_BINDING = 12        # materials.glsl: per lobe how a metallic-roughness texture changes it (LOBE_MR_*)
SCENE_OBJECT_BINDING = 13   # scene_objects.glsl: per object its material, light-map layer, index range, box
DRAW_ORDER_BINDING = 14     # cull.comp: the object of each draw command (viewer/draw_list.py)
DRAW_COMMAND_BINDING = 15   # cull.comp: the indirect draw commands it writes
DRAW_STATE_BINDING = 16     # cull.comp: why each object was drawn or not
DRAW_HIDDEN_BINDING = 17    # cull.comp: per object, 1 = left out
OBJECT_LOD_BINDING = 18     # cull.comp: per object its levels of detail (viewer/gpu_meshes.py OBJECT_LOD_DTYPE)
LOBE_ALBEDO_BINDING = 19    # lobe_albedo.glsl: per lobe its layers of the albedo table (viewer/lobe_albedo.py)
LOBE_ALBEDO_TABLE_BINDING = 20  # lobe_albedo.glsl: the table's values, layer by layer
DRAW_BATCH_BINDING = 21     # compact.comp: per texture batch its first command and count
DRAW_COMPACT_BINDING = 22   # compact.comp: the drawn commands, packed per batch
DRAW_COUNT_BINDING = 23     # compact.comp: per batch how many it packed (the draws' count)
VERTEX_BINDING = 24         # visibility_resolve.comp: the scene's vertex buffer (viewer/gpu_meshes.py VERTEX_DTYPE)
INDEX_BINDING = 25          # visibility_resolve.comp: its index buffer
DRAW_BATCH_OF_OBJECT_BINDING = 26  # visibility_resolve.comp: per object its texture batch (viewer/draw_list.py)
VISIBILITY_TALLY_BINDING = 27   # visibility_classify.comp: per batch its pixels' count, offset, dispatch
VISIBILITY_PIXELS_BINDING = 28  # visibility_classify.comp: the pixels, batch after batch

# -- raster passes over the bake's meshes (raster_surface.glsl: G-buffer and mirror passes) -----------
LIGHTMAP_UNIT = 0
KD_TEXTURE_UNIT = 1
EMISSION_TEXTURE_UNIT = 2  # the material's emissive texture (MAT_EMISSION_TEXTURE)
METALLIC_ROUGHNESS_TEXTURE_UNIT = 3  # its metallic-roughness texture (MAT_MR_TEXTURE)
NORMAL_TEXTURE_UNIT = 4    # its normal map (MAT_NORMAL_TEXTURE)
ANISOTROPY_TEXTURE_UNIT = 5  # its anisotropy texture (MAT_ANISOTROPY_TEXTURE)
# gbuffer.frag's outputs = the G-buffer framebuffer's colour attachments, in this order
GB_SHADE_LOCATION = 0
GB_FRAME_LOCATION = 1
VISIBILITY_LOCATION = 0     # visibility.frag's one output (the visibility buffer's framebuffer)
# visibility_resolve.comp: the visibility buffer in (units past the raster textures'), the G-buffer ...
VISIBILITY_UNIT = 6
VISIBILITY_DEPTH_UNIT = 7
GB_SHADE_IMAGE = 0
GB_FRAME_IMAGE = 1
MIRROR_RADIANCE_IMAGE = 0   # ... or a mirror pass's targets (mirror.frag's, as images)
MIRROR_POSITION_IMAGE = 1
MIRROR_NORMAL_IMAGE = 2
# mirror.frag's and mirror_sky.frag's outputs = colour attachments of a mirror-buffer framebuffer
MIRROR_RADIANCE_LOCATION = 0
MIRROR_POSITION_LOCATION = 1
MIRROR_NORMAL_LOCATION = 2

# -- blit.frag (the window's frame and overlay) ---------------------------------------------------------
BLIT_UNIT = 0

# -- shading.comp, specular.comp; SKY_UNIT also mirror_sky.frag -----------------------------------------
GB_SHADE_UNIT = 0           # gbuffer_read.glsl: the G-buffer's targets
GB_FRAME_UNIT = 1
GB_DEPTH_UNIT = 2
SKY_UNIT = 3                # sky.glsl
SHADING_CUBE_UNIT = 4       # the first of the scene-dependent units (`shading_units`)
RADIANCE_IMAGE = 0          # shading.comp writes, specular.comp adds to the frame's radiance
MIRROR_PLANE_POSITION_IMAGE = 1  # specular.glsl: the still camera's per-pixel plane sums
MIRROR_PLANE_NORMAL_IMAGE = 2

# -- one image in, one out: resolve.comp, tonemap.comp, accumulate.comp ---------------------------------
SOURCE_UNIT = 0             # the image read (accumulate: this frame's estimate)
BASE_UNIT = 1               # accumulate.comp: the walkthrough image it fades from
TARGET_IMAGE = 0            # the image written (accumulate: the running sum)
SHOWN_IMAGE = 1             # accumulate.comp: the mean, shown

# -- mirror_mips.comp: one level of the mirror buffers' radiance chain from the level above ------------
MIP_SOURCE_IMAGE = 0
MIP_TARGET_IMAGE = 1

# -- split_sum_prefilter.comp (viewer/split_sum.py) ------------------------------------------------------
PREFILTER_CUBE_UNIT = 0     # the source cube-map arrays, one unit per size class from here
PREFILTER_IMAGE = 0         # the level written

_SUFFIXES = ("_BINDING", "_UNIT", "_IMAGE", "_LOCATION")
MIRROR_UNIT_NAMES = ("MIRROR_RADIANCE_UNIT", "MIRROR_POSITION_UNIT", "MIRROR_NORMAL_UNIT")


def glsl_defines() -> dict[str, int]:
    """Every fixed number of this module, by name: the defines each program gets."""
    return {name: value for name, value in globals().items()
            if name.isupper() and name.endswith(_SUFFIXES) and isinstance(value, int)}


def mirror_units(first_unit: int) -> dict[str, int]:
    """mirror_buffer.glsl's three texture arrays (radiance, position, normal) on consecutive units."""
    return {name: int(first_unit) + k for k, name in enumerate(MIRROR_UNIT_NAMES)}


def shading_units(cube_classes: int) -> dict[str, int]:
    """The shading programs' scene-dependent units, from SHADING_CUBE_UNIT on, with C =
    max(cube_classes, 1) (cubemaps.glsl's sampler arrays have at least one element): the cube-map
    classes, the mirror buffers' arrays and the split-sum prefiltered classes; UNIT_COUNT: how many
    units that is (the lobes' albedo table is a storage buffer: viewer/lobe_albedo.py)."""
    c = max(int(cube_classes), 1)
    mirror = SHADING_CUBE_UNIT + c
    split_sum = mirror + len(MIRROR_UNIT_NAMES)
    return {"CUBE_FIRST_UNIT": SHADING_CUBE_UNIT, **mirror_units(mirror), "SPLIT_SUM_FIRST_UNIT": split_sum,
            "UNIT_COUNT": split_sum + c}
