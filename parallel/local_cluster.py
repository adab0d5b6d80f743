"""`glint bake --scheduler local:N`: a Dask cluster of N worker processes on this machine, quick to start.

Dask's own `LocalCluster` starts each worker through a nanny, whose worker process multiprocessing
spawns or forks from a fork server that imports Dask and glint first, which delays the first task by
a large share of a small scene's bake; and a bake's process that is the client imports Dask and is
slower to exit with it (figures: docs/BAKE.md, "Why `local:N` has its own worker server").
Here one *worker server*, a single-threaded process, starts the whole cluster while the bake
prepares its work:

- it forks the **scheduler** (`distributed.Scheduler`, loopback TCP, no dashboard) as soon as it has
  imported Dask and been told how many workers, then the N **workers** (`distributed.Worker`, one
  thread each, no nanny), and the **client process**, which connects a `DaskExecutor` to the
  scheduler once the workers are in and runs the bake's requests for it (`WorkerServer.run`: the
  request pickled over a pipe, each result back as it comes), so that the bake's process never
  imports Dask. It forks another worker in the place of one that dies (a nanny's job: Dask runs the
  dead worker's tasks again, on the others or the new one), at most RESTARTS times; it stops them all
  and ends when the bake's process closes its pipes or ends. Its processes write nothing to the
  command's output (they report on the status pipe).
- It is *forked* from the bake's process where that is safe: by the `glint` command first of all,
  before it has imported more than the standard library (`fork_server`, glint/entry.py), so that it
  imports Dask and the light-map tasks' modules on the other core while the command imports glint.
  Forking a process that has used OpenImageIO, Embree or Open Image Denoise would copy their thread
  pools without their threads (a child forked after a bake hung in its first EXR write). Anywhere
  else (glint used as a library, the tests) it is *spawned*: a fresh interpreter that imports the
  same.

Reports come back on the status pipe, a line each (`WorkerServer.watch`): the scheduler's address,
each worker that has registered, a worker that failed and why, and the server giving up. Workers
that end by themselves (their scheduler closed or gone) are not replaced. POSIX only (os.fork).
"""
from __future__ import annotations

import os
import pickle
import re
import select
import signal
import struct
import subprocess
import sys
import time
from typing import Callable, Iterator

from glint.core.errors import GlintError, one_line

RESTARTS = 16  # workers forked in place of dead ones, in one cluster's life, before the server gives up
POLL_SECONDS = 0.05  # how often the server looks for dead workers while it waits on its pipe
STOP_SECONDS = 2.0  # a worker's time to end once the server has asked (SIGTERM), before SIGKILL
WORKER_DEATH_SECONDS = 10  # a worker cut off from its scheduler this long ends itself
# what every worker runs, imported by the server before it forks them; the modules of the tasks come
# from the caller (fork_server's, take_server's and WorkerServer.start's `modules`: the bake names its
# light-map stage and, where it has cube maps to render, the stage its caller handed it), so this layer
# never names a layer above it
TASK_MODULES = ("distributed",)
# the kinds of the server's reports, each line "KIND TEXT"
ADDRESS, UP, FAILED, GAVE_UP = "address", "up", "failed", "gave-up"

LOCAL_ADDRESS = re.compile(r"local:(\d+)")  # --scheduler local:N

_forked: WorkerServer | None = None  # fork_server's, until a cluster takes it


def asks_for_local_cluster(args: list[str]) -> bool:
    """Whether a command line has `--scheduler local:N` (or `--scheduler=local:N`)."""
    values = [b for a, b in zip(args, args[1:]) if a == "--scheduler"]
    values += [a.partition("=")[2] for a in args if a.startswith("--scheduler=")]
    return any(LOCAL_ADDRESS.fullmatch(value) for value in values)


def fork_server(modules: tuple[str, ...] = ()) -> None:
    """Fork the worker server now, for the next `local:N` cluster of this process, with `modules` (those
    its tasks will run) imported ahead. Called by the `glint` command before anything else runs in its
    process (see the module docstring); once."""
    global _forked
    if _forked is None and hasattr(os, "fork"):
        _forked = WorkerServer.fork(modules)


def take_server(modules: tuple[str, ...] = ()) -> WorkerServer:
    """The server `fork_server` forked, or else a spawned one importing `modules` ahead (module
    docstring)."""
    global _forked
    server, _forked = _forked, None
    if server is not None and server.running():
        return server
    if not hasattr(os, "fork"):
        raise GlintError("--scheduler local:N needs os.fork (Linux, macOS): start `dask scheduler` and "
                         "`dask worker` and pass --scheduler tcp://HOST:PORT")
    return WorkerServer.spawn(modules)


class WorkerServer:
    """This side of a worker server: its process and its pipes: commands to it, reports from it, and the
    requests to and the results from its client process (`run`)."""

    def __init__(self, pid: int, fds: dict[str, int], popen: subprocess.Popen | None = None):
        self.pid, self.popen = pid, popen
        self.command_fd, self.status_fd = fds["command"], fds["status"]
        self.requests_fd, self.results_fd = fds["requests"], fds["results"]
        self.started = "spawned" if popen is not None else "forked"  # how: the module docstring

    @staticmethod
    def _pipes() -> tuple[dict[str, int], dict[str, int]]:
        """The server's ends and this side's ends of its four pipes."""
        command_r, command_w = os.pipe()
        status_r, status_w = os.pipe()
        requests_r, requests_w = os.pipe()
        results_r, results_w = os.pipe()
        return ({"command": command_r, "status": status_w, "requests": requests_r, "results": results_w},
                {"command": command_w, "status": status_r, "requests": requests_w, "results": results_r})

    @classmethod
    def fork(cls, modules: tuple[str, ...] = ()) -> WorkerServer:
        theirs, ours = cls._pipes()
        pid = os.fork()
        if pid == 0:  # the server: never returns
            code = 1
            try:
                for fd in ours.values():
                    os.close(fd)
                _detach_output()
                code = serve(**theirs, modules=tuple(modules))
            finally:
                os._exit(code)
        for fd in theirs.values():
            os.close(fd)
        return cls(pid, ours)

    @classmethod
    def spawn(cls, modules: tuple[str, ...] = ()) -> WorkerServer:
        theirs, ours = cls._pipes()
        arguments = {**theirs, "modules": tuple(modules)}
        code = f"import sys; from glint.parallel.local_cluster import serve; sys.exit(serve(**{arguments!r}))"
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}  # this process's glint
        try:
            popen = subprocess.Popen([sys.executable, "-c", code], pass_fds=tuple(theirs.values()), env=env,
                                     stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        finally:
            for fd in theirs.values():
                os.close(fd)
        return cls(popen.pid, ours, popen)

    def running(self) -> bool:
        if self.popen is not None:
            return self.popen.poll() is None
        try:
            return os.waitpid(self.pid, os.WNOHANG) == (0, 0)
        except ChildProcessError:
            return False

    def start(self, count: int, log_level: int, modules: tuple[str, ...] = ()) -> None:
        """Start the scheduler, `count` workers with `modules` imported (besides TASK_MODULES and the
        server's own) and the client process, Dask's log lines below `log_level` held back."""
        os.write(self.command_fd, f"{count} {log_level} {','.join(modules) or '-'}\n".encode())

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

    def run(self, function: Callable[..., Iterator], *args) -> Iterator:
        """`function(*args)`'s items, run in the server's client process (module docstring): the request
        pickled to it, each item pickled back as it comes. An exception there is raised here; None as the
        last item: the client process is gone (the server gave up or ended)."""
        import cloudpickle  # Dask's: functions of a script's __main__ travel by value, as Dask sends them

        _send(self.requests_fd, (function, args), cloudpickle.dumps)
        while True:
            message = _receive(self.results_fd)
            if message is None:
                yield None
                return
            kind, value = message
            if kind == "error":
                raise value
            if kind == "done":
                return
            yield value

    def close(self) -> None:
        """Ask the server to stop its client, scheduler and workers and end: its pipes closed. It ends by
        itself (`serve`): nothing waits for it here (`watch` reaps it)."""
        for name in ("requests_fd", "command_fd"):
            if getattr(self, name) is not None:
                os.close(getattr(self, name))
                setattr(self, name, None)


# -- the server's side -----------------------------------------------------------------------------
def _detach_output() -> None:
    """The server and its children write nothing to the command's output (they report on the status pipe):
    a `glint bake ... | tee` then ends with the bake, not when the cluster's last process has stopped."""
    null = os.open(os.devnull, os.O_WRONLY)
    for fd in (1, 2):
        os.dup2(null, fd)
    os.close(null)


def serve(command: int, status: int, requests: int, results: int, modules: tuple[str, ...] = ()) -> int:
    """The worker server's life: import TASK_MODULES and `modules`, wait for "COUNT LOG_LEVEL MODULES"
    (WorkerServer.start), import those, fork the scheduler, COUNT workers and the client process, keep
    the workers until the command pipe closes, then stop them all. The first four arguments are the
    server's ends of its pipes (WorkerServer._pipes)."""
    command_fd, status_fd = command, status
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the bake's: it closes the cluster
    try:
        for module in TASK_MODULES:
            __import__(module)
    except Exception as e:
        _report(status_fd, GAVE_UP, f"the worker server cannot import {module} ({one_line(e)})")
        return 1
    _import_quietly(modules)
    line = _read_line(command_fd)
    if not line:
        return 0
    count, log_level, started = line.split()
    count, log_level = int(count), int(log_level)
    _import_quietly(started.split(",") if started != "-" else ())
    address_r, address_w = os.pipe()
    scheduler = _fork(_run_scheduler, log_level, address_w,
                      close=(command_fd, status_fd, requests, results, address_r))
    os.close(address_w)
    address = _read_line(address_r)
    os.close(address_r)
    if not address:
        _report(status_fd, GAVE_UP, "the scheduler did not start")
        _stop([scheduler])
        return 1
    _report(status_fd, ADDRESS, address)

    arrivals_r, arrivals_w = os.pipe()  # a byte from each worker that has registered, for the client

    def worker(name: str) -> int:
        return _fork(_run_worker, address, name, log_level, status_fd, arrivals_w,
                     close=(command_fd, requests, results, arrivals_r))

    workers = {worker(f"local-{slot}"): slot for slot in range(count)}
    client = _fork(_run_client, address, count, log_level, requests, results, arrivals_r,
                   close=(command_fd, status_fd, arrivals_w))
    for fd in (requests, results, arrivals_r):
        os.close(fd)
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
            if slot is None or status == 0:  # the scheduler or the client, or a worker that ended by itself
                continue
            if restarts == RESTARTS:
                _report(status_fd, GAVE_UP, f"worker processes ended abnormally {restarts + 1} times")
                _stop([client, *workers, scheduler])
                return 1
            restarts += 1
            workers[worker(f"local-{slot}-{restarts}")] = slot
    _stop([client, *workers, scheduler])
    return 0


def _import_quietly(modules) -> None:
    """Import the tasks' modules once here, not in every worker. One that fails is left to the workers:
    a worker imports it when a task needs it, or says why it cannot."""
    for module in modules:
        try:
            __import__(module)
        except Exception:  # noqa: BLE001 -- reported by the task that needs it
            pass


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
            try:
                os.close(fd)
            except OSError:  # closed in the server already (a worker forked after the client process)
                pass
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


def _run_worker(address: str, name: str, log_level: int, status_fd: int, arrivals_fd: int) -> int:
    import asyncio

    distributed = _quiet_dask(log_level)

    async def work():
        async with distributed.Worker(address, nthreads=1, name=name, host="127.0.0.1", dashboard=False,
                                      death_timeout=WORKER_DEATH_SECONDS, silence_logs=log_level) as worker:
            _report(status_fd, UP, name)
            os.write(arrivals_fd, b"+")
            await worker.finished()

    try:
        asyncio.run(work())
    except Exception as e:
        _report(status_fd, FAILED, f"worker {name}: {one_line(e)}")
        return 1
    return 0


# -- the client process ----------------------------------------------------------------------------
_client_context: dict = {}


def client_context(timeout: float) -> str:
    """In the client process: the scheduler's address, once all the workers have registered (at most
    `timeout` seconds of waiting: Dask's own waits look every 0.1 s)."""
    fd, count = _client_context["arrivals"], _client_context["count"]
    arrived, deadline = 0, time.monotonic() + timeout
    while arrived < count and time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
        if ready:
            arrived += len(os.read(fd, count - arrived))
    return _client_context["address"]


def _run_client(address: str, count: int, log_level: int, requests_fd: int, results_fd: int,
                arrivals_fd: int) -> int:
    """Serve the bake's requests (WorkerServer.run) until its pipe closes: each a function and its
    arguments, whose items go back one by one, then "done" (or "error" and the exception)."""
    _quiet_dask(log_level)
    _client_context.update(address=address, count=count, arrivals=arrivals_fd)
    while True:
        try:
            request = _receive(requests_fd)
        except Exception as e:  # a request that does not unpickle here
            _send(results_fd, ("error", GlintError(f"the local Dask cluster's client: {one_line(e)}")))
            continue
        if request is None:
            return 0
        function, args = request
        try:
            for item in function(*args):
                _send(results_fd, ("item", item))
            _send(results_fd, ("done", None))
        except Exception as e:
            try:
                pickle.dumps(e)
            except Exception:
                e = GlintError(f"on the local Dask cluster: {type(e).__name__}: {one_line(e)}")
            _send(results_fd, ("error", e))


LENGTH = struct.Struct("<Q")


def _send(fd: int, value, dumps: Callable = pickle.dumps) -> None:
    data = dumps(value, protocol=5)
    for part in (LENGTH.pack(len(data)), data):  # not joined: a request can be hundreds of MiB
        view = memoryview(part)
        while view:
            view = view[os.write(fd, view):]


def _receive(fd: int):
    """The next value sent on `fd`, or None at its end."""
    head = _read_exactly(fd, LENGTH.size)
    if head is None:
        return None
    data = _read_exactly(fd, LENGTH.unpack(head)[0])
    return None if data is None else pickle.loads(data)


def _read_exactly(fd: int, size: int) -> bytearray | None:
    data = bytearray()
    while len(data) < size:
        try:
            chunk = os.read(fd, min(size - len(data), 1 << 24))
        except OSError:
            return None
        if not chunk:
            return None
        data += chunk
    return data  # not copied to bytes: pickle and struct read a bytearray
