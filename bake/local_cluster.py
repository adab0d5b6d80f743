"""`glint bake --scheduler local:N`: a Dask cluster of N worker processes on this machine, quick to start.

Dask's own `LocalCluster` starts each worker through a nanny, whose worker process multiprocessing
spawns or forks from a fork server that imports Dask and glint first: about 0.6 s on the 2-core
machine before a task could run, a third of a small scene's whole bake (docs/BAKE.md, "On a
cluster (Dask)"). Here:

- the **scheduler** runs in the bake's process: Dask's `LocalCluster` without workers, on its
  event-loop thread (`start_scheduler`);
- a **worker server**, a single-threaded process, forks the N workers (`distributed.Worker`, one
  thread each, no nanny) as soon as it has the scheduler's address, and forks another in the place of
  one that dies (a nanny's job: Dask runs the dead worker's tasks again, on the others or the new one),
  at most RESTARTS times; it stops its workers and ends when the bake's process closes its pipe or
  ends. The server is *forked* from the bake's process where that is safe: by the `glint` command
  itself before it has done anything but import its modules (`fork_server`, glint/cli.py), so it has
  glint already and imports Dask while the bake's process does. Forking a process that has used
  OpenImageIO, Embree or Open Image Denoise would copy their thread pools without their threads (a
  child forked after a bake hung in its first EXR write). Anywhere else (glint used as a library, the
  tests) it is *spawned*: a fresh interpreter that imports Dask and what the tasks run first.

Workers that end by themselves (the scheduler closed or gone) are not replaced. POSIX only (os.fork).
Reports come back on a status pipe, one line each: a worker that failed to start says why, and the
server says when it gave up; `WorkerServer.watch` reads them.
"""
from __future__ import annotations

import functools
import os
import select
import signal
import subprocess
import sys
import threading
import time

from glint.core.errors import GlintError, one_line

RESTARTS = 16  # workers forked in place of dead ones, in one cluster's life, before the server gives up
POLL_SECONDS = 0.05  # how often the server looks for dead workers while it waits on its pipe
STOP_SECONDS = 2.0  # a worker's time to end once the server has asked (SIGTERM), before SIGKILL
WORKER_DEATH_SECONDS = 10  # a worker cut off from its scheduler this long ends itself
# what the workers' tasks run, imported by a spawned server before it forks them
TASK_MODULES = ("distributed", "glint.bake.lightmap", "glint.cubemap_stage")
GAVE_UP = "gave-up"

_forked: WorkerServer | None = None  # fork_server's, until a cluster takes it


def fork_server() -> None:
    """Fork the worker server now, for the next `local:N` cluster of this process. Called by the `glint`
    command before anything else runs in its process (see the module docstring); once."""
    global _forked
    if _forked is None and hasattr(os, "fork"):
        _forked = WorkerServer.fork()


def take_server() -> WorkerServer:
    """The server `fork_server` forked, or else a spawned one (module docstring)."""
    global _forked
    server, _forked = _forked, None
    if server is not None and server.running():
        return server
    if not hasattr(os, "fork"):
        raise GlintError("--scheduler local:N needs os.fork (Linux, macOS): start `dask scheduler` and "
                         "`dask worker` and pass --scheduler tcp://HOST:PORT")
    return WorkerServer.spawn()


def start_scheduler(distributed, quiet: int, workers: int, arrived: threading.Event):
    """A Dask scheduler in this process (LocalCluster without workers, no dashboard), on loopback TCP;
    `arrived` is set once `workers` workers have registered with it. (Dask's own waits, in
    `Client.scatter` and `wait_for_workers`, look every 0.1 s: a tenth of a small bake.)"""
    cluster = distributed.LocalCluster(n_workers=0, processes=False, host="127.0.0.1", protocol="tcp://",
                                       dashboard_address=None, silence_logs=quiet)

    class Arrivals(distributed.diagnostics.plugin.SchedulerPlugin):
        def add_worker(self, scheduler, worker):
            if len(scheduler.workers) >= workers:
                arrived.set()

    cluster.scheduler.add_plugin(Arrivals(), name="glint-arrivals")
    return cluster


class WorkerServer:
    """This side of a worker server: its process and the two pipes (commands to it, reports from it)."""

    def __init__(self, pid: int, command_fd: int, status_fd: int, popen: subprocess.Popen | None = None):
        self.pid, self.command_fd, self.status_fd, self.popen = pid, command_fd, status_fd, popen
        self.started = "spawned" if popen is not None else "forked"  # how: the module docstring

    @classmethod
    def fork(cls) -> WorkerServer:
        command_r, command_w = os.pipe()
        status_r, status_w = os.pipe()
        pid = os.fork()
        if pid == 0:  # the server: never returns
            code = 1
            try:
                os.close(command_w)
                os.close(status_r)
                code = serve(command_r, status_w)
            finally:
                os._exit(code)
        os.close(command_r)
        os.close(status_w)
        return cls(pid, command_w, status_r)

    @classmethod
    def spawn(cls) -> WorkerServer:
        command_r, command_w = os.pipe()
        status_r, status_w = os.pipe()
        code = f"import sys; from glint.bake.local_cluster import serve; sys.exit(serve({command_r}, {status_w}))"
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}  # this process's glint
        try:
            popen = subprocess.Popen([sys.executable, "-c", code], pass_fds=(command_r, status_w), env=env,
                                     stdin=subprocess.DEVNULL)
        finally:
            os.close(command_r)
            os.close(status_w)
        return cls(popen.pid, command_w, status_r, popen)

    def running(self) -> bool:
        if self.popen is not None:
            return self.popen.poll() is None
        try:
            return os.waitpid(self.pid, os.WNOHANG) == (0, 0)
        except ChildProcessError:
            return False

    def start_workers(self, address: str, count: int, log_level: int) -> None:
        """Fork `count` workers of the scheduler at `address`, Dask's log lines below `log_level` held back."""
        os.write(self.command_fd, f"{address} {count} {log_level}\n".encode())

    def watch(self) -> str | None:
        """Block until the server gives up or ends (its reports' pipe closes: it and its workers are gone,
        then it is reaped); the reason, its last report, or None if it ended without one (it was asked to
        stop). Run on a thread of its own (DaskExecutor._watch_server)."""
        reports = b""
        while (GAVE_UP + "\n").encode() not in reports:
            try:
                chunk = os.read(self.status_fd, 4096)
            except OSError:
                break
            if not chunk:
                self._reap()
                break
            reports += chunk
        lines = [line for line in reports.decode(errors="replace").splitlines() if line and line != GAVE_UP]
        return lines[-1] if lines else None

    def close(self) -> None:
        """Ask the server to stop its workers and end: its pipe closed. It ends by itself (`serve`): nothing
        waits for it here (`watch` reaps it)."""
        if self.command_fd is not None:
            os.close(self.command_fd)
            self.command_fd = None

    def _reap(self) -> None:
        try:
            self.popen.wait() if self.popen is not None else os.waitpid(self.pid, 0)
        except ChildProcessError:  # reaped already
            pass


# -- the server's side -----------------------------------------------------------------------------
def serve(command_fd: int, status_fd: int) -> int:
    """The worker server's life: import, wait for "ADDRESS COUNT", fork and keep COUNT workers until the
    command pipe closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the bake's: it closes the cluster
    try:
        for module in TASK_MODULES:
            __import__(module)
    except Exception as e:
        _report(status_fd, f"the worker server cannot import {module} ({one_line(e)})", GAVE_UP)
        return 1
    line = _read_line(command_fd)
    if not line:
        return 0
    address, count, log_level = line.split()
    start = functools.partial(_fork_worker, address, int(log_level), command_fd, status_fd)
    workers = {start(f"local-{slot}"): slot for slot in range(int(count))}
    restarts = 0
    while True:
        ready, _, _ = select.select([command_fd], [], [], POLL_SECONDS)
        if ready and not os.read(command_fd, 4096):
            break
        while workers:
            pid, status = os.waitpid(-1, os.WNOHANG)
            if pid == 0:
                break
            slot = workers.pop(pid, None)
            if slot is None or status == 0:  # ended by itself: its scheduler closed
                continue
            if restarts == RESTARTS:
                _report(status_fd, f"worker processes ended abnormally {restarts + 1} times", GAVE_UP)
                _stop(workers)
                return 1
            restarts += 1
            workers[start(f"local-{slot}-{restarts}")] = slot
    _stop(workers)
    return 0


def _read_line(fd: int) -> str:
    data = b""
    while not data.endswith(b"\n"):
        chunk = os.read(fd, 4096)
        if not chunk:
            return ""
        data += chunk
    return data.decode().strip()


def _report(fd: int, *lines: str) -> None:
    try:
        os.write(fd, "".join(line + "\n" for line in lines).encode())
    except OSError:
        pass


def _stop(workers: dict) -> None:
    for pid in workers:
        os.kill(pid, signal.SIGTERM)
    deadline = time.monotonic() + STOP_SECONDS
    left = set(workers)
    while left and time.monotonic() < deadline:
        left = {pid for pid in left if os.waitpid(pid, os.WNOHANG)[0] == 0}
        time.sleep(0.01)
    for pid in left:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)


def _fork_worker(address: str, log_level: int, command_fd: int, status_fd: int, name: str) -> int:
    pid = os.fork()
    if pid:
        return pid
    code = 1
    try:  # the worker: never returns
        os.close(command_fd)
        code = _run_worker(address, name, log_level, status_fd)
    finally:
        os._exit(code)


def _run_worker(address: str, name: str, log_level: int, status_fd: int) -> int:
    import asyncio
    import logging

    import distributed

    logging.getLogger("distributed").setLevel(log_level)

    async def work():
        async with distributed.Worker(address, nthreads=1, name=name, host="127.0.0.1", dashboard=False,
                                      death_timeout=WORKER_DEATH_SECONDS, silence_logs=log_level) as worker:
            await worker.finished()

    try:
        asyncio.run(work())
    except Exception as e:
        _report(status_fd, f"a worker could not start or ended ({one_line(e)})")
        return 1
    return 0
