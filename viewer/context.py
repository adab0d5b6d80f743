"""OpenGL contexts for the renderer.

The renderer itself only needs a `moderngl.Context` of OpenGL 4.3 core or newer
(compute shaders); it never asks where the pixels go. A window brings its own
context (moderngl-window); captures and tests use `headless_context()`, an EGL
context without any display: the GPU's driver where there is one, Mesa's llvmpipe
(OpenGL 4.5 in software) where there is not.
"""
from __future__ import annotations

import moderngl

from glint.core.errors import GlintError

GL_REQUIRED = 430  # compute shaders and shader storage buffers (docs/VIEWER.md: the floor)


def headless_context(require: int = GL_REQUIRED) -> moderngl.Context:
    """A standalone EGL context, or a GlintError that says what is missing and what to install."""
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=require)
    except Exception as e:  # moderngl/glcontext raise plain Exceptions with the EGL error in the text
        detail = " ".join(str(e).split()) or type(e).__name__
        raise GlintError(
            f"cannot create a headless OpenGL {require // 100}.{require % 100 // 10} context with EGL "
            f"({detail}); install a GPU driver with EGL, or Mesa's EGL and llvmpipe "
            "(Debian/Ubuntu: libegl1 libgl1-mesa-dri)") from e
    check_context(ctx, require)
    return ctx


def check_context(ctx: moderngl.Context, require: int = GL_REQUIRED) -> None:
    """GlintError unless `ctx` offers OpenGL `require` (e.g. a window that got an older context)."""
    if ctx.version_code < require:
        raise GlintError(f"OpenGL {ctx.version_code // 100}.{ctx.version_code % 100 // 10} "
                         f"({describe(ctx)}) is too old: glint needs OpenGL "
                         f"{require // 100}.{require % 100 // 10} for its compute shaders")


def describe(ctx: moderngl.Context) -> str:
    """'renderer (vendor, GL version)', for statistics and messages."""
    info = ctx.info
    return f"{info.get('GL_RENDERER', '?')} ({info.get('GL_VENDOR', '?')}, GL {info.get('GL_VERSION', '?')})"
