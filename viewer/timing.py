"""Time per pass: GPU timer queries (GL_TIME_ELAPSED), or glFinish-bracketed wall clock.

    timer = PassTimer(ctx)
    timer.start_frame()                  # collects the previous frame's results
    with timer("gbuffer"):
        ...draw...
    timer.last_ms, timer.median_ms       # {"gbuffer": ms, ..., "total": ms}

Queries are read only when asked for, or when the next frame starts, so the CPU
does not wait for the GPU at the end of every frame. One query object per pass
name; passes must not nest (GL allows one active time query at a time).

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

import time
from collections import deque
from contextlib import contextmanager
from statistics import median

import moderngl

from glint.viewer.gl import software_renderer

QUERY_INVALID = 2 ** 31  # ns; a 32-bit result this large is a wrapped negative (seen on llvmpipe)


def default_method(ctx: moderngl.Context) -> str:
    return "finish" if software_renderer(ctx) else "query"


class PassTimer:
    def __init__(self, ctx: moderngl.Context, history: int = 60, method: str | None = None):
        self.ctx = ctx
        self.method = method or default_method(ctx)
        if self.method not in ("query", "finish", "off"):
            raise ValueError(f"timing method must be 'query', 'finish' or 'off', not {self.method!r}")
        self._queries: dict[str, moderngl.Query] = {}
        self._pending: dict[str, float | None] = {}  # measured this frame, not yet collected
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
        if name in self._pending:  # measured twice in one frame: start a new frame
            self.collect()
        if self.method == "finish":
            self.ctx.finish()
            start = time.perf_counter()
            yield
            self.ctx.finish()
            self._pending[name] = (time.perf_counter() - start) * 1e3
            return
        query = self._queries.get(name)
        if query is None:
            query = self._queries[name] = self.ctx.query(time=True)
        with query:
            yield
        self._pending[name] = None  # read in collect()

    def start_frame(self) -> None:
        self.collect()

    def collect(self) -> None:
        """Read the pending results (waits for the GPU to finish them)."""
        if not self._pending:
            return
        frame = {}
        for name, ms in self._pending.items():
            if ms is None:
                ns = self._queries[name].elapsed
                ms = ns / 1e6 if 0 <= ns < QUERY_INVALID else None
            if ms is not None:
                frame[name] = ms
        self._pending = {}
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
