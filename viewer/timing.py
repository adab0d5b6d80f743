"""Time per pass: GPU timer queries (GL_TIME_ELAPSED), or glFinish-bracketed wall clock.

    timer = PassTimer(ctx)
    timer.start_frame()                  # collects the results of earlier frames that are ready
    with timer("gbuffer"):
        ...draw...
    timer.last_ms, timer.median_ms       # {"gbuffer": ms, ..., "total": ms}

A frame's queries are read once the GPU has finished them, at a later frame's start, so the CPU never
waits for the GPU to finish the frame before: it prepares frame N while the GPU draws frame N - 1 (and
waits only when LAG frames are still unread). Reading them at the next frame's start made every frame's
Python and driver work add to its GPU time (issue 27's H200 measurement: wall time 2.3 ms over GPU time
in the living room, 7.9 ms on the staircase). `median_ms` and `collect` read everything (they wait).
One GL query object per pass and frame in flight; passes must not nest (GL allows one active time query
at a time).

Mesa's llvmpipe runs "GPU" work on the CPU threads and rasterises lazily, when a
later command needs the result, so its timer queries put the G-buffer's raster
time into whichever pass comes next (docs/VIEWER.md, "Pass timing on llvmpipe").
There `method = "finish"` is used instead: glFinish before and after
each pass and the wall clock in between -- exact for a software renderer, but it
stalls a real GPU's pipeline, so hardware uses queries. `method = "off"` times
nothing (work that nobody reads the times of, e.g. the bake's cube-map renders,
should not pay for the glFinish calls).
"""
from __future__ import annotations

import ctypes
import time
from collections import deque
from contextlib import contextmanager
from statistics import median

import moderngl

from glint.viewer.gl import GL, GL_QUERY_RESULT, GL_QUERY_RESULT_AVAILABLE, GL_TIME_ELAPSED, software_renderer

QUERY_INVALID = 2 ** 31  # ns; a 32-bit result this large is a wrapped negative (seen on llvmpipe)
LAG = 2  # frames whose queries may still be unread when a frame starts (more: wait for the oldest)


def default_method(ctx: moderngl.Context) -> str:
    return "finish" if software_renderer(ctx) else "query"


class PassTimer:
    def __init__(self, ctx: moderngl.Context, history: int = 60, method: str | None = None):
        self.ctx = ctx
        self.method = method or default_method(ctx)
        if self.method not in ("query", "finish", "off"):
            raise ValueError(f"timing method must be 'query', 'finish' or 'off', not {self.method!r}")
        self._gl = GL(ctx) if self.method == "query" else None
        self._free: list[int] = []       # query objects not in use
        self._frame: dict[str, float | int] = {}  # this frame's passes: ms (finish), or the query object
        self._in_flight: deque = deque()  # earlier frames' dicts, oldest first, not read yet
        self._samples: dict[str, deque] = {}
        self.history = history
        self.last_ms: dict[str, float] = {}
        self.frames = 0

    @property
    def description(self) -> str:
        return {"query": "OpenGL timer queries", "finish": "wall clock between glFinish calls (software renderer)",
                "off": "not timed"}[self.method]

    @contextmanager
    def __call__(self, name: str):
        if self.method == "off":
            yield
            return
        if name in self._frame:  # measured twice in one frame: start a new frame
            self.start_frame()
        if self.method == "finish":
            self.ctx.finish()
            start = time.perf_counter()
            yield
            self.ctx.finish()
            self._frame[name] = (time.perf_counter() - start) * 1e3
            return
        gl = self._gl
        if self._free:
            query = self._free.pop()
        else:
            name_ = ctypes.c_uint(0)
            gl.GenQueries(1, ctypes.byref(name_))
            query = name_.value
        gl.BeginQuery(GL_TIME_ELAPSED, query)
        try:
            yield
        finally:
            gl.EndQuery(GL_TIME_ELAPSED)
            self._frame[name] = query

    def start_frame(self) -> None:
        """The frame before goes in flight; the frames in flight whose results are ready are read (the
        oldest is waited for while more than LAG are)."""
        if self._frame:
            self._in_flight.append(self._frame)
            self._frame = {}
        while self._in_flight and (len(self._in_flight) > LAG or self._ready(self._in_flight[0])):
            self._read(self._in_flight.popleft())

    def collect(self) -> None:
        """Read every frame's results, this frame's too (waits for the GPU to finish them)."""
        self.start_frame()
        while self._in_flight:
            self._read(self._in_flight.popleft())

    def _ready(self, frame: dict) -> bool:
        """Whether the GPU has finished all of a frame's queries (never waits)."""
        for value in frame.values():
            if isinstance(value, int):
                available = ctypes.c_uint(0)
                self._gl.GetQueryObjectuiv(value, GL_QUERY_RESULT_AVAILABLE, ctypes.byref(available))
                if not available.value:
                    return False
        return True

    def _read(self, pending: dict) -> None:
        frame = {}
        for name, value in pending.items():
            if isinstance(value, int):  # a query object: its result, then back to the pool
                ns = ctypes.c_uint64(0)
                self._gl.GetQueryObjectui64v(value, GL_QUERY_RESULT, ctypes.byref(ns))
                self._free.append(value)
                value = ns.value / 1e6 if ns.value < QUERY_INVALID else None
            if value is not None:
                frame[name] = value
        if not frame:
            return
        frame["total"] = sum(frame.values())
        for name, ms in frame.items():
            self._samples.setdefault(name, deque(maxlen=self.history)).append(ms)
        self.last_ms = frame
        self.frames += 1

    @property
    def median_ms(self) -> dict[str, float]:
        """Median over the last `history` frames, per pass and in total."""
        self.collect()
        return {name: float(median(samples)) for name, samples in self._samples.items()}

    def reset(self) -> None:
        self.collect()
        self._samples.clear()
        self.last_ms = {}
        self.frames = 0

    def release(self) -> None:
        """Delete the query objects (reading nothing more)."""
        queries = self._free + [v for f in (*self._in_flight, self._frame) for v in f.values() if isinstance(v, int)]
        for query in queries:
            self._gl.DeleteQueries(1, ctypes.byref(ctypes.c_uint(query)))
        self._free, self._in_flight, self._frame = [], deque(), {}
