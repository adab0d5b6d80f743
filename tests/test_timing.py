"""viewer/timing.py PassTimer with GPU timer queries, the way it times passes on a GPU (llvmpipe answers
the queries too; there the renderer itself uses glFinish and the wall clock)."""
import ctypes
import math

import moderngl

from glint.viewer.gl import GL, gl_functions
from glint.viewer.timing import LAG, PassTimer


def draw(ctx, fbo, vao):
    fbo.use()
    fbo.clear(0.2, 0.3, 0.4, 1.0)
    vao.render(moderngl.TRIANGLES, vertices=3)


def triangle(ctx):
    program = ctx.program(vertex_shader="#version 430\nvoid main() { vec2 p = vec2(gl_VertexID & 1, gl_VertexID >> 1);"
                                        " gl_Position = vec4(4.0 * p - 1.0, 0.0, 1.0); }",
                          fragment_shader="#version 430\nout vec4 c; void main() { c = vec4(1.0); }")
    return program, ctx.vertex_array(program, []), ctx.simple_framebuffer((256, 256))


class NumberedQueries:
    """The timer's GL calls, with each query's result replaced by the number of the BeginQuery that last
    started it, in ms (llvmpipe's own elapsed times are sometimes a wrapped negative): a frame that reads
    another frame's use of a query object shows it."""

    def __init__(self, gl):
        self.gl, self.begun, self.count = gl, {}, 0

    def BeginQuery(self, target, query):  # noqa: N802 (GL's name)
        self.gl.BeginQuery(target, query)
        self.count += 1
        self.begun[query] = self.count

    def GetQueryObjectui64v(self, query, what, out):  # noqa: N802
        self.gl.GetQueryObjectui64v(query, what, out)
        out._obj.value = self.begun[query] * 1_000_000

    def __getattr__(self, name):
        return getattr(self.gl, name)


def test_every_frame_is_read_once_with_queries(ctx):
    """Ten frames of two timed passes, frame k's starting BeginQuery number 2k + 1 and 2k + 2: each pass's
    samples are its own frames' numbers in order, each frame read once, the total their sum. Catches
    (tried): a query object handed back to the pool before its result is read (a later frame's pass
    started it again: samples of later numbers)."""
    program, vao, fbo = triangle(ctx)
    GL(ctx).errors()
    timer = PassTimer(ctx, history=60, method="query")
    timer._gl = NumberedQueries(timer._gl)
    for _ in range(10):
        timer.start_frame()
        with timer("a"):
            draw(ctx, fbo, vao)
        with timer("b"):
            draw(ctx, fbo, vao)
    medians = timer.median_ms
    assert timer.frames == 10 and set(medians) == {"a", "b", "total"}
    assert list(timer._samples["a"]) == [2.0 * k + 1 for k in range(10)]
    assert list(timer._samples["b"]) == [2.0 * k + 2 for k in range(10)]
    assert list(timer._samples["total"]) == [4.0 * k + 3 for k in range(10)]
    timer.release()
    assert not GL(ctx).errors()
    for obj in (vao, program, fbo):
        obj.release()


def test_a_frame_is_not_waited_for_while_the_gpu_is_busy(ctx, monkeypatch):
    """While the GPU has not finished a frame's queries, the next frames start without reading it (the CPU
    prepares frame N while the GPU draws N - 1: issue 27 found every frame's Python and driver time added
    to its GPU time when the previous frame was read at each start); only with more than LAG frames
    unread is the oldest waited for. `collect` then reads the rest. Catches (tried): reading the previous
    frame at every start (frames read = k instead of k - LAG)."""
    program, vao, fbo = triangle(ctx)
    GL(ctx).errors()
    timer = PassTimer(ctx, method="query")
    monkeypatch.setattr(timer, "_ready", lambda frame: False)  # a GPU that is always behind
    for k in range(6):
        timer.start_frame()
        assert timer.frames == max(0, k - LAG), f"frame {k}: {timer.frames} frames read"
        with timer("pass"):
            draw(ctx, fbo, vao)
    timer.collect()
    assert timer.frames == 6
    timer.release()
    assert not GL(ctx).errors()
    for obj in (vao, program, fbo):
        obj.release()


def test_release_deletes_every_query(ctx):
    """The queries of frames still in flight and the pooled ones are deleted (glIsQuery), none left behind.
    Catches (tried): the in-flight frames' queries forgotten by release."""
    program, vao, fbo = triangle(ctx)
    GL(ctx).errors()
    timer = PassTimer(ctx, method="query")
    for _ in range(4):
        timer.start_frame()
        with timer("pass"):
            draw(ctx, fbo, vao)
    made = set(timer._free) | {q for f in (*timer._in_flight, timer._frame) for q in f.values()}
    is_query = gl_functions(ctx)("glIsQuery", ctypes.c_ubyte, ctypes.c_uint)
    assert made and all(is_query(q) for q in made)
    timer.release()
    assert not any(is_query(q) for q in made)
    assert not GL(ctx).errors()
    for obj in (vao, program, fbo):
        obj.release()
