"""One background worker process that keeps its state and streams results: the other way glint runs
work beside its main process, for work that is a conversation rather than a pool of tasks.

parallel/executor.py runs many independent tasks (texel tiles, probes) and hands back each result
once. The re-bake after a material edit (bake/rebake.py) is another shape of work: its worker prepares
once (loads the scene, rasterises the texels), then streams progressive passes for each request, and
a newer request makes the running one stale. `BackgroundWorker` is that process's plumbing, kept apart
from what it computes:

- spawned, not forked: the caller may hold an OpenGL context and threads, which a fork copies without
  their threads; a daemon, at a lower priority (`nice`: a viewer's frames come first);
- requests in, messages out, over two queues; each request gets a number, the newest number is shared
  with the worker (`Inbox.stale`), so that it can drop work a newer request replaced at once;
- the worker ends with its parent: an idle one checks every PARENT_CHECK_SECONDS, a busy one at each
  `Inbox.stale`;
- `close()` asks it to stop, reads its messages meanwhile (a worker blocked writing to a full pipe
  needs them read) and terminates it after `stop_seconds`.

The worker's function is `target(inbox, *args)`; it takes requests with `inbox.next()` and sends
messages with `inbox.send(message)` (anything picklable).
"""
from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import queue
import time
from typing import Any, Callable, Iterator

PARENT_CHECK_SECONDS = 1.0  # how often an idle worker checks that its parent still runs
_STOP = ("stop",)
_STOPPED = -1  # `latest` after close(): every request is stale


class Inbox:
    """The worker's side: its requests, its messages and whether its work is still wanted."""

    def __init__(self, requests, messages, latest):
        self._requests, self._messages, self._latest = requests, messages, latest
        self._parent = mp.parent_process()

    def next(self) -> tuple[int, Any] | None:
        """The newest request waiting, as (number, payload), blocking until there is one; the older ones
        waiting are skipped (a newer request replaces them). None when the worker should end: it was
        asked to stop, or its parent is gone."""
        while True:
            try:
                request = self._requests.get(timeout=PARENT_CHECK_SECONDS)
            except queue.Empty:
                if not self.parent_alive():
                    return None
                continue
            while request != _STOP:
                try:
                    request = self._requests.get_nowait()
                except queue.Empty:
                    break
            return None if request == _STOP else request

    def send(self, message) -> None:
        self._messages.put(message)

    def stale(self, number: int) -> bool:
        """Whether request `number` was replaced by a newer one, the worker asked to stop, or its parent
        is gone: the work for it can end now."""
        return self._latest.value != number or not self.parent_alive()

    def parent_alive(self) -> bool:
        return self._parent is None or self._parent.is_alive()


def _main(target: Callable, nice: int, requests, messages, latest, args: tuple) -> None:
    with contextlib.suppress(OSError, AttributeError):
        os.nice(nice)
    target(Inbox(requests, messages, latest), *args)


class BackgroundWorker:
    """The caller's side (module docstring): `request(payload)`, `messages()`, `close()`."""

    def __init__(self, target: Callable, args: tuple = (), *, name: str, nice: int = 0,
                 stop_seconds: float = 5.0):
        ctx = mp.get_context("spawn")
        self._requests, self._messages = ctx.Queue(), ctx.Queue()
        self._latest = ctx.Value("q", 0, lock=False)  # the newest request's number
        self.stop_seconds = stop_seconds
        self.requests = 0
        self._process = ctx.Process(target=_main, name=name, daemon=True,
                                    args=(target, int(nice), self._requests, self._messages, self._latest,
                                          tuple(args)))
        self._process.start()

    def request(self, payload) -> int:
        """Send a request; the running one becomes stale. Returns its number (1, 2, ...)."""
        self.requests += 1
        self._latest.value = self.requests
        self._requests.put((self.requests, payload))
        return self.requests

    def messages(self) -> Iterator:
        """Every message the worker has sent so far, in order; never blocks."""
        while True:
            try:
                yield self._messages.get_nowait()
            except (queue.Empty, OSError, ValueError):
                return

    def alive(self) -> bool:
        return self._process is not None and self._process.is_alive()

    def close(self, drain: Callable[[Any], None] = lambda message: None) -> None:
        """Stop the worker: at once if it is between requests, else at its next `stale` check; terminated
        after `stop_seconds`. Messages read meanwhile go to `drain`."""
        if self._process is None:
            return
        self._latest.value = _STOPPED
        with contextlib.suppress(Exception):
            self._requests.put(_STOP)
        deadline = time.monotonic() + self.stop_seconds
        while self._process.is_alive() and time.monotonic() < deadline:
            for message in self.messages():
                drain(message)
            self._process.join(0.05)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join()
        for q in (self._requests, self._messages):
            q.close()
            q.cancel_join_thread()
        self._process = None
