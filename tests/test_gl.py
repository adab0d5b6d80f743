"""viewer/gl.py and viewer/gl_bindings.py: the error checks of the ctypes calls, and the table of
units and bindings."""
from __future__ import annotations

import pytest

from glint.core.errors import GlintError
from glint.viewer import gl_bindings
from glint.viewer.gl import GL, GL_RGBA16F, check_compute_texture_units


def test_a_refused_allocation_is_a_glint_error_naming_it(ctx):
    gl = GL(ctx)
    too_big = int(ctx.info["GL_MAX_CUBE_MAP_TEXTURE_SIZE"]) * 2
    with pytest.raises(GlintError, match=r"could not allocate a test cube map \(GL_INVALID_VALUE"):
        gl.allocate_cube_array(too_big, 6, 1, GL_RGBA16F, "a test cube map")
    assert gl.errors() == []  # reported once, nothing left behind
    name = gl.allocate_cube_array(4, 6, 3, GL_RGBA16F, "a test cube map")  # a good one still works
    assert name > 0
    gl.delete_textures([name])


def test_too_many_texture_units_is_a_glint_error(ctx):
    check_compute_texture_units(ctx, 16, "a test")  # the minimum OpenGL 4.3 guarantees
    with pytest.raises(GlintError, match="a test needs 100000 texture units"):
        check_compute_texture_units(ctx, 100000, "a test")


def test_buffer_bindings_are_distinct_and_shading_units_follow_the_fixed_ones():
    bindings = {k: v for k, v in gl_bindings.glsl_defines().items() if k.endswith("_BINDING")}
    assert len(set(bindings.values())) == len(bindings)
    for classes in (0, 1, 3):
        units = gl_bindings.shading_units(classes)
        fixed = [gl_bindings.GB_SHADE_UNIT, gl_bindings.GB_FRAME_UNIT, gl_bindings.GB_DEPTH_UNIT,
                 gl_bindings.SKY_UNIT]
        c = max(classes, 1)
        taken = [*fixed, *range(units["CUBE_FIRST_UNIT"], units["CUBE_FIRST_UNIT"] + c),
                 *(units[name] for name in gl_bindings.MIRROR_UNIT_NAMES),
                 *range(units["SPLIT_SUM_FIRST_UNIT"], units["SPLIT_SUM_FIRST_UNIT"] + c)]
        assert sorted(taken) == list(range(len(taken)))  # no unit twice, none skipped
        assert units["UNIT_COUNT"] == len(taken)


def test_scene_textures_past_the_limits_are_a_glint_error(ctx, tmp_path, monkeypatch):
    """Light maps (and material textures, the sky map) larger than the context allows are one
    GlintError naming them and what to do, before GL refuses the upload and leaves them empty
    (black surfaces). Catches GpuScene uploading without check_texture_size: with the limit
    lowered below the light-map page the upload would go on."""
    from conftest import FAST, write_room

    from glint.bake.gltf_loader import load_scene
    from glint.bake.settings import resolve_settings
    from glint.core.bake_dir import Bake
    from glint.services import bake_scene
    from glint.viewer.gpu_scene import GpuScene

    scene = load_scene(write_room(tmp_path / "room.glb"))
    bake_scene(scene, resolve_settings(scene.bake_settings, **FAST), tmp_path / "room.bake", progress=False)
    bake = Bake(tmp_path / "room.bake")
    page = bake.lightmap(0).shape
    monkeypatch.setitem(ctx.info, "GL_MAX_TEXTURE_SIZE", max(page[:2]) - 1)
    with pytest.raises(GlintError, match=r"the light maps \(1 pages\) is .*texels-per-metre"):
        GpuScene(ctx, bake)
