"""GLSL sources from the `shaders` package, with `#include` and injected defines.

    #include "common.glsl"

is replaced by that file's text, recursively; each file goes into a program once
(as with `#pragma once`), so includes may include each other freely. The result
starts with `#version 430 core` and then one `#define NAME VALUE` per injected
define, which is how constants that Python also needs (buffer bindings, material
flags, work-group size) have a single source.

Every file becomes its own GLSL "source string" through `#line 1 <k>` directives,
so a compiler message `3:12(5): error ...` means line 12 of file k = 3;
`ShaderError` rewrites such messages to `sky.glsl:12: error ...`.
"""
from __future__ import annotations

import re
from functools import lru_cache
from importlib import resources

import moderngl

from glint.core import bsdf, constants
from glint.viewer import gl_bindings

GLSL_VERSION = "#version 430 core"
PACKAGE = "glint.shaders"
LOCAL_SIZE = 8  # compute work groups are LOCAL_SIZE x LOCAL_SIZE (a define of every compute shader)

_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"\s*(//.*)?$')
# Mesa: "3:12(5): error", NVIDIA: "3(12) : error", AMD: "ERROR: 3:12: ..."
_LOCATION = re.compile(r"\b(\d+)(?::(\d+)\(\d+\)|\((\d+)\)|:(\d+):)")


class ShaderError(RuntimeError):
    """A shader failed to compile or link: a bug in glint, reported with file names and lines."""


@lru_cache(maxsize=None)
def read(name: str) -> str:
    """The text of one file of the shaders package."""
    try:
        return resources.files(PACKAGE).joinpath(name).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ShaderError(f"no shader file '{name}' in the {PACKAGE} package") from None


def glsl_constants() -> dict:
    """The constants every shader gets as defines: core/constants.py, the BSDF's numerical guards and
    the fixed texture units and buffer bindings (viewer/gl_bindings.py)."""
    return {"HALF_MAX": constants.HALF_MAX, "XI1_BORDER": constants.XI1_BORDER, "LOBE_TAN_MAX": constants.LOBE_TAN_MAX,
            "MIRROR_PLANE_COS": constants.MIRROR_PLANE_COS, "GB_DARK_BIT": f"{constants.GB_DARK_BIT}u",
            "GB_NORMAL_MAPPED_BIT": f"{constants.GB_NORMAL_MAPPED_BIT}u",
            "GB_BITANGENT_NEGATIVE_BIT": f"{constants.GB_BITANGENT_NEGATIVE_BIT}u",
            "MIRROR_PLANE_DISTANCE": constants.MIRROR_PLANE_DISTANCE,
            "GB_ID_BITS": constants.GB_ID_BITS, "M_MIN": bsdf.M_MIN, "HZ_MIN": bsdf.HZ_MIN,
            "DOT_MIN": bsdf.DOT_MIN, "COS_MIN": bsdf.COS_MIN, "HALF_MIN": bsdf.HALF_MIN, "XI_MIN": bsdf.XI_MIN,
            **gl_bindings.glsl_defines()}


def preprocess(name: str, defines: dict | None = None) -> tuple[str, list[str]]:
    """(GLSL text of `name` with includes resolved and defines injected, file of each source string)."""
    files: list[str] = []
    out = [GLSL_VERSION]
    for key, value in {**glsl_constants(), **(defines or {})}.items():
        if not re.fullmatch(r"[A-Za-z_]\w*", key):
            raise ShaderError(f"bad define name {key!r}")
        out.append(f"#define {key} {_literal(value)}")

    def expand(file: str, chain: tuple[str, ...]) -> None:
        index = len(files)
        files.append(file)
        out.append(f"#line 1 {index}")
        for number, line in enumerate(read(file).splitlines(), start=1):
            m = _INCLUDE.match(line)
            if not m:
                out.append(line)
                continue
            child = m.group(1)
            if child in chain:
                raise ShaderError(f"{file}:{number}: include cycle {' -> '.join(chain + (child,))}")
            if child not in files:
                expand(child, chain + (child,))
            out.append(f"#line {number + 1} {index}")

    expand(name, (name,))
    return "\n".join(out) + "\n", files


def source(name: str, defines: dict | None = None) -> str:
    return preprocess(name, defines)[0]


def _literal(value) -> str:
    if isinstance(value, bool):
        return "1" if value else "0"
    return repr(value) if isinstance(value, float) else str(value)  # repr keeps '.', 'e' of floats


def explain_compile_error(error: Exception, stages: dict[str, list[str]]) -> ShaderError:
    """Rewrite the "k:line" locations of a compiler log into "file:line".

    moderngl heads each stage's log with a line naming the stage ("vertex_shader",
    "fragment_shader", "compute_shader"); the source strings are numbered per stage.
    """
    kinds = {"vertex_shader": 0, "fragment_shader": 1, "compute_shader": 0}
    tables = list(stages.values())
    files = tables[0]
    out = []
    for line in str(error).splitlines():
        if line.strip() in kinds:
            files = tables[min(kinds[line.strip()], len(tables) - 1)]

        def name(match: re.Match, files=files) -> str:
            k, number = int(match.group(1)), match.group(2) or match.group(3) or match.group(4)
            return f"{files[k]}:{number}" if k < len(files) else match.group(0)

        out.append(_LOCATION.sub(name, line))
    return ShaderError("\n".join(out).strip())


def compute_program(ctx: moderngl.Context, name: str, defines: dict | None = None) -> moderngl.ComputeShader:
    text, files = preprocess(name, {"LOCAL_SIZE": LOCAL_SIZE, **(defines or {})})
    try:
        return ctx.compute_shader(text)
    except Exception as e:
        raise explain_compile_error(e, {name: files}) from e


def raster_program(ctx: moderngl.Context, vertex: str, fragment: str,
                   defines: dict | None = None) -> moderngl.Program:
    vs, vfiles = preprocess(vertex, defines)
    fs, ffiles = preprocess(fragment, defines)
    try:
        return ctx.program(vertex_shader=vs, fragment_shader=fs)
    except Exception as e:
        raise explain_compile_error(e, {vertex: vfiles, fragment: ffiles}) from e


def dispatch(program: moderngl.ComputeShader, width: int, height: int) -> None:
    """Run a compute program over width x height invocations (the shader skips the excess)."""
    program.run(-(-width // LOCAL_SIZE), -(-height // LOCAL_SIZE), 1)


def set_uniforms(program, **values) -> None:
    """Set uniforms by name (bytes are written as they are: a matrix in GL's layout); ones the compiler
    removed as unused are skipped."""
    for name, value in values.items():
        member = program.get(name, None)  # a dict look-up (`name in program` walks every member)
        if member is None:
            continue
        if isinstance(value, bytes):
            member.write(value)
        else:
            member.value = value
