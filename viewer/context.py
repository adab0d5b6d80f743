"""OpenGL contexts for the renderer.

The renderer itself only needs a `moderngl.Context` of OpenGL 4.3 core or newer
(compute shaders); it never asks where the pixels go. A window brings its own
context (moderngl-window); captures and tests use `headless_context()`, an EGL
context without any display: the GPU's driver where there is one, Mesa's llvmpipe
(OpenGL 4.5 in software) where there is not. The checks of a context's version and
limits are viewer/gl.py's.
"""
from __future__ import annotations

import moderngl

from glint.core.errors import GlintError, one_line
from glint.viewer.gl import GL_REQUIRED, check_context


def headless_context(require: int = GL_REQUIRED) -> moderngl.Context:
    """A standalone EGL context, or a GlintError that says what is missing and what to install."""
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=require)
    except Exception as e:  # moderngl/glcontext raise plain Exceptions with the EGL error in the text
        raise GlintError(
            f"cannot create a headless OpenGL {require // 100}.{require % 100 // 10} context with EGL "
            f"({one_line(e)}); install a GPU driver with EGL, or Mesa's EGL and llvmpipe "
            "(Debian/Ubuntu: apt-get install libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri)") from e
    check_context(ctx, require)
    return ctx
