"""Run GLSL functions over numpy arrays: the test harness that holds shaders equal to numpy.

    out = evaluate("bsdf.glsl", "f = lobe_value(wi, wo, Lobe(ks, shape));",
                   inputs={"wi": wi, "wo": wo, "ks": ks, "shape": shape}, outputs={"f": 1})

compiles one compute shader made of the shaders-package file `include` (with its own
#includes resolved by viewer/shader_source.py, and the defines every pass gets) and a
generated `main` that, per invocation i, declares each input as a local read from row i,
runs `body` (GLSL statements), and writes the outputs of row i back. Inputs are arrays of
shape (N,) or (N, k): k = 1 is a `float`, 2..4 a `vecK`, more a `float[k]`; they are sent
as float32 (cast ints in the body: `int(n)`). `outputs` maps names to widths the same way;
outputs start at zero. Results come back as float32 arrays of shape (N,) or (N, k).

All inputs share one shader storage buffer and all outputs another, at bindings
IN_BINDING and OUT_BINDING (above those of viewer/gpu_materials.py and cubemaps.py). Programs are
cached by source text, so a test that calls the same body many times compiles it once.
"""
from __future__ import annotations

import re

import moderngl
import numpy as np

from glint.viewer import shader_source
from glint.viewer.context import headless_context
from glint.viewer.gpu_scene import shader_defines

IN_BINDING, OUT_BINDING = 6, 7
GROUP_SIZE = 64

_NAME = re.compile(r"[A-Za-z_]\w*")
_context: moderngl.Context | None = None
_programs: dict[tuple[moderngl.Context, str], moderngl.ComputeShader] = {}  # keeps its contexts alive


def context() -> moderngl.Context:
    """One headless context shared by every evaluation in the process."""
    global _context
    if _context is None:
        _context = headless_context()
    return _context


def _columns(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=np.float32)
    if a.ndim == 1:
        return a[:, None]
    if a.ndim != 2:
        raise ValueError(f"inputs must be (N,) or (N, k), got shape {a.shape}")
    return a


def _reads(name: str, width: int, offset: int) -> str:
    items = ", ".join(f"eval_in[base_in + {offset + j}u]" for j in range(width))
    if width == 1:
        return f"    float {name} = {items};"
    if width <= 4:
        return f"    vec{width} {name} = vec{width}({items});"
    return f"    float {name}[{width}] = float[{width}]({items});"


def _zero(name: str, width: int) -> str:
    if width == 1:
        return f"    float {name} = 0.0;"
    if width <= 4:
        return f"    vec{width} {name} = vec{width}(0.0);"
    return f"    float {name}[{width}]; for (int j = 0; j < {width}; ++j) {name}[j] = 0.0;"


def _writes(name: str, width: int, offset: int) -> str:
    if width == 1:
        return f"    eval_out[base_out + {offset}u] = {name};"
    return "\n".join(f"    eval_out[base_out + {offset + j}u] = {name}[{j}];" for j in range(width))


def main_source(body: str, in_widths: dict[str, int], out_widths: dict[str, int]) -> str:
    """The generated compute shader `main` (appended after the included file)."""
    for name in (*in_widths, *out_widths):
        if not _NAME.fullmatch(name):
            raise ValueError(f"bad GLSL name {name!r}")
    lines = [f"layout(local_size_x = {GROUP_SIZE}) in;",
             f"layout(std430, binding = {IN_BINDING}) readonly buffer EvalIn {{ float eval_in[]; }};",
             f"layout(std430, binding = {OUT_BINDING}) writeonly buffer EvalOut {{ float eval_out[]; }};",
             "uniform uint eval_count;",
             "void main() {",
             "    uint i = gl_GlobalInvocationID.x;",
             "    if (i >= eval_count) return;",
             f"    uint base_in = i * {max(sum(in_widths.values()), 1)}u;",
             f"    uint base_out = i * {sum(out_widths.values())}u;"]
    offset = 0
    for name, width in in_widths.items():
        lines.append(_reads(name, width, offset))
        offset += width
    lines += [_zero(name, width) for name, width in out_widths.items()]
    lines += ["    {", body, "    }"]
    offset = 0
    for name, width in out_widths.items():
        lines.append(_writes(name, width, offset))
        offset += width
    lines.append("}")
    return "\n".join(lines) + "\n"


def program(include: str, main: str, defines: dict | None = None,
            ctx: moderngl.Context | None = None) -> moderngl.ComputeShader:
    """`include` (with its includes and defines) followed by `main`, compiled once per context."""
    ctx = ctx or context()
    text, files = shader_source.preprocess(include, {**shader_defines(), **(defines or {})})
    text += f"#line 1 {len(files)}\n" + main
    key = (ctx, text)
    if key not in _programs:
        try:
            _programs[key] = ctx.compute_shader(text)
        except Exception as e:
            raise shader_source.explain_compile_error(e, {include: files + ["<glsl_eval main>"]}) from e
    return _programs[key]


def evaluate(include: str, body: str, inputs: dict[str, np.ndarray], outputs: dict[str, int],
             defines: dict | None = None, ctx: moderngl.Context | None = None) -> dict[str, np.ndarray]:
    """Run `body` once per row of `inputs`; the `outputs` of each row as float32 numpy arrays."""
    ctx = ctx or context()
    columns = {name: _columns(a) for name, a in inputs.items()}
    counts = {len(c) for c in columns.values()}
    if len(counts) != 1:
        raise ValueError(f"inputs differ in length: { {k: len(c) for k, c in columns.items()} }")
    n = counts.pop()
    in_widths = {name: c.shape[1] for name, c in columns.items()}
    out_widths = {name: int(w) for name, w in outputs.items()}
    prog = program(include, main_source(body, in_widths, out_widths), defines, ctx)
    packed = np.concatenate(list(columns.values()), axis=1) if columns else np.zeros((n, 1), np.float32)
    out_stride = sum(out_widths.values())
    src = ctx.buffer(np.ascontiguousarray(packed, dtype=np.float32).tobytes() or b"\0" * 4)
    dst = ctx.buffer(reserve=max(n * out_stride * 4, 4))
    try:
        src.bind_to_storage_buffer(IN_BINDING)
        dst.bind_to_storage_buffer(OUT_BINDING)
        shader_source.set_uniforms(prog, eval_count=n)
        prog.run(-(-n // GROUP_SIZE), 1, 1)
        flat = np.frombuffer(dst.read(), dtype=np.float32)[:n * out_stride].reshape(n, out_stride)
    finally:
        src.release()
        dst.release()
    result, offset = {}, 0
    for name, width in out_widths.items():
        col = flat[:, offset:offset + width]
        result[name] = col[:, 0].copy() if width == 1 else col.copy()
        offset += width
    return result
