"""`glint bake --scheduler local:N`: a Dask cluster of N worker processes on this machine, quick to start.

Dask's own `LocalCluster` starts each worker through a nanny, whose worker process multiprocessing
spawns or forks from a fork server that imports Dask and glint first: about 0.8 s on the 2-core
machine before a task could run, a third of a small scene's whole bake (docs/BAKE.md, "On a
cluster (Dask)"). Here one *worker server*, a single-threaded process, starts the cluster while
the bake's process imports Dask for its client:

- it forks the **scheduler** (`distributed.Scheduler`, loopback TCP, no dashboard) as soon as it has
  imported Dask and been told how many workers, then the N **workers** (`distributed.Worker`, one
  thread each, no nanny); it forks another worker in the place of one that dies (a nanny's job: Dask
  runs the dead worker's tasks again, on the others or the new one), at most RESTARTS times; it stops
  them all and ends when the bake's process closes its pipe or ends.
- It is *forked* from the bake's process where that is safe: by the `glint` command itself before it
  has done anything but import its modules (`fork_server`, glint/cli.py), so it has glint already.
  (Forked before those imports, to import on another core meanwhile, it made the cornell-box bake
  slower: 2.14-2.27 s against 2.03-2.23 s, five runs each.)
  Forking a process that has used OpenImageIO, Embree or Open Image Denoise would copy their thread
  pools without their threads (a child forked after a bake hung in its first EXR write). Anywhere
  else (glint used as a library, the tests) it is *spawned*: a fresh interpreter that imports Dask
  and what the tasks run first.

Reports come back on a status pipe, a line each (`WorkerServer.watch`): the scheduler's address, each
worker that has registered, a worker that failed and why, and the server giving up. Workers that end
by themselves (their scheduler closed or gone) are not replaced. POSIX only (os.fork).
"""
from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import time
from typing import Callable

from glint.core.errors import GlintError, one_line

RESTARTS = 16  # workers forked in place of dead ones, in one cluster's life, before the server gives up
POLL_SECONDS = 0.05  # how often the server looks for dead workers while it waits on its pipe
STOP_SECONDS = 2.0  # a worker's time to end once the server has asked (SIGTERM), before SIGKILL
WORKER_DEATH_SECONDS = 10  # a worker cut off from its scheduler this long ends itself
# what the workers' tasks run, imported by a spawned server before it forks them
TASK_MODULES = ("distributed", "glint.bake.lightmap", "glint.cubemap_stage")
# the kinds of the server's reports, each line "KIND TEXT"
ADDRESS, UP, FAILED, GAVE_UP = "address", "up", "failed", "gave-up"

LOCAL_ADDRESS = re.compile(r"local:(\d+)")  # --scheduler local:N

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

    def start(self, count: int, log_level: int) -> None:
        """Start the scheduler and `count` workers, Dask's log lines below `log_level` held back."""
        os.write(self.command_fd, f"{count} {log_level}\n".encode())

    def watch(self, report: Callable[[str, str], None]) -> None:
        """Hand each of the server's reports to `report(kind, text)` until its pipe closes (the server and
        its workers are gone), then reap the server. Run on a thread of its own (DaskExecutor._watch_server)."""
        pending = b""
        while True:
            try:
                chunk = os.read(self.status_fd, 4096)
            except OSError:
                chunk = b""
            if not chunk:
                break
            *lines, pending = (pending + chunk).split(b"\n")
            for line in lines:
                kind, _, text = line.decode(errors="replace").partition(" ")
                report(kind, text)
        os.close(self.status_fd)
        try:
            self.popen.wait() if self.popen is not None else os.waitpid(self.pid, 0)
        except ChildProcessError:  # reaped already
            pass

    def close(self) -> None:
        """Ask the server to stop its scheduler and workers and end: its pipe closed. It ends by itself
        (`serve`): nothing waits for it here (`watch` reaps it)."""
        if self.command_fd is not None:
            os.close(self.command_fd)
            self.command_fd = None


# -- the server's side -----------------------------------------------------------------------------
def serve(command_fd: int, status_fd: int) -> int:
    """The worker server's life: import, wait for "COUNT LOG_LEVEL", fork the scheduler and COUNT
    workers, keep the workers until the command pipe closes, then stop them all."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the bake's: it closes the cluster
    try:
        for module in TASK_MODULES:
            __import__(module)
    except Exception as e:
        _report(status_fd, GAVE_UP, f"the worker server cannot import {module} ({one_line(e)})")
        return 1
    line = _read_line(command_fd)
    if not line:
        return 0
    count, log_level = (int(word) for word in line.split())
    address_r, address_w = os.pipe()
    scheduler = _fork(_run_scheduler, log_level, address_w, close=(command_fd, status_fd, address_r))
    os.close(address_w)
    address = _read_line(address_r)
    os.close(address_r)
    if not address:
        _report(status_fd, GAVE_UP, "the scheduler did not start")
        _stop([scheduler])
        return 1
    _report(status_fd, ADDRESS, address)

    def worker(name: str) -> int:
        return _fork(_run_worker, address, name, log_level, status_fd, close=(command_fd,))

    workers = {worker(f"local-{slot}"): slot for slot in range(count)}
    restarts = 0
    while True:
        ready, _, _ = select.select([command_fd], [], [], POLL_SECONDS)
        if ready and not os.read(command_fd, 4096):
            break  # the bake closed the cluster, or ended
        while True:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:  # no children left
                break
            if pid == 0:
                break
            slot = workers.pop(pid, None)
            if slot is None or status == 0:  # the scheduler, or a worker ended by itself (its scheduler went)
                continue
            if restarts == RESTARTS:
                _report(status_fd, GAVE_UP, f"worker processes ended abnormally {restarts + 1} times")
                _stop([*workers, scheduler])
                return 1
            restarts += 1
            workers[worker(f"local-{slot}-{restarts}")] = slot
    _stop([*workers, scheduler])
    return 0


def _read_line(fd: int) -> str:
    data = b""
    while not data.endswith(b"\n"):
        chunk = os.read(fd, 4096)
        if not chunk:
            return ""
        data += chunk
    return data.decode().strip()


def _report(fd: int, kind: str, text: str) -> None:
    try:
        os.write(fd, f"{kind} {text}\n".encode())
    except OSError:  # the bake's process is gone
        pass


def _stop(pids: list[int]) -> None:
    """SIGTERM, then after STOP_SECONDS SIGKILL; each reaped (those already gone are skipped)."""
    left = set()
    for pid in pids:
        try:
            os.kill(pid, signal.SIGTERM)
            left.add(pid)
        except ProcessLookupError:
            pass
    deadline = time.monotonic() + STOP_SECONDS
    while left and time.monotonic() < deadline:
        left = {pid for pid in left if not _reaped(pid)}
        time.sleep(0.01)
    for pid in left:
        os.kill(pid, signal.SIGKILL)
        _reaped(pid, wait=True)


def _reaped(pid: int, wait: bool = False) -> bool:
    try:
        return os.waitpid(pid, 0 if wait else os.WNOHANG)[0] != 0
    except ChildProcessError:  # not a child any more: reaped by the server's loop
        return True


def _fork(run: Callable[..., int], *args, close: tuple[int, ...]) -> int:
    """A child process that closes the server's descriptors in `close`, runs `run(*args)` and exits with
    its result (1 on an exception); its pid."""
    pid = os.fork()
    if pid:
        return pid
    code = 1
    try:  # the child: never returns
        for fd in close:
            os.close(fd)
        code = run(*args)
    finally:
        os._exit(code)


def _quiet_dask(log_level: int):
    import logging

    import distributed

    logging.getLogger("distributed").setLevel(log_level)
    return distributed


def _run_scheduler(log_level: int, address_fd: int) -> int:
    import asyncio

    distributed = _quiet_dask(log_level)

    async def schedule():
        async with distributed.Scheduler(host="127.0.0.1", port=0, protocol="tcp://", dashboard=False,
                                         dashboard_address=None) as scheduler:
            os.write(address_fd, f"{scheduler.address}\n".encode())
            os.close(address_fd)
            await scheduler.finished()

    asyncio.run(schedule())
    return 0


def _run_worker(address: str, name: str, log_level: int, status_fd: int) -> int:
    import asyncio

    distributed = _quiet_dask(log_level)

    async def work():
        async with distributed.Worker(address, nthreads=1, name=name, host="127.0.0.1", dashboard=False,
                                      death_timeout=WORKER_DEATH_SECONDS, silence_logs=log_level) as worker:
            _report(status_fd, UP, name)
            await worker.finished()

    try:
        asyncio.run(work())
    except Exception as e:
        _report(status_fd, FAILED, f"worker {name}: {one_line(e)}")
        return 1
    return 0
