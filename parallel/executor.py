"""Runs independent bake jobs (texel tiles, cube-map probes) on local worker processes or on a Dask cluster.

One interface, the protocol `Executor` (the one way the bake and the cube-map stage run work in
parallel), `executor.run(setup, setup_args, job, tasks)`: each task, a small typed object, is handled by
`job(state, task)` in a worker whose `state = setup(*setup_args)` was built once per worker
process, or once before a fork of local workers (an Embree scene cannot be pickled: a worker that
does not inherit one builds its own). Results come back in
completion order as (task index, result); the caller puts them in place, so the outcome does not
depend on the number of workers or on which worker ran what.

- `LocalExecutor(jobs)`: forked processes of this machine (they inherit the state, built once before
  the fork);
  `LocalExecutor(jobs, start_method="spawn")` where a worker's state does not survive fork (the
  cube-map stage's GL contexts).
- `DaskExecutor(address)`: the workers of a Dask cluster (`distributed`), for `glint bake
  --scheduler`: `tcp://HOST:PORT` (a running `dask scheduler`) or `local:N` (a cluster of N worker
  processes on this machine, started and closed by the executor: parallel/local_cluster.py).
  setup_args are scattered once (`client.scatter`, to every worker) and travel once to each worker,
  which builds its state from them on its first task and keeps it for the others; each task carries only its own small
  description (a TileTask: a tile's first texel and count; a ProbeTask: its probes). Dask is imported here only when
  such an executor starts (an optional extra: `pip install 'glint[cluster]'`).

`executor_for(settings)` picks one; use it as a context manager (`with executor_for(s) as ex:`), and
call `start()` once work is certain: a `local:N` cluster then starts in the background while the
caller goes on (unwrapping the scene), a remote scheduler is reached at once, so that a wrong
address fails before any work.
"""
from __future__ import annotations

import asyncio
import concurrent.futures
import importlib.util
import logging
import multiprocessing as mp
import os
import pickle
import re
import threading
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable, Iterable, Iterator, Protocol

from glint.parallel import local_cluster
from glint.parallel.cpus import one_blas_thread
from glint.core.errors import GlintError, one_line, warn
from glint.core.signals import deferred_signals, quiet_child

# What a future of a lost scheduler raises (Dask cancels every future when its connection is gone).
CANCELLED = (asyncio.CancelledError, concurrent.futures.CancelledError)
CONNECT_SECONDS = 5  # to reach a scheduler: a reachable one answers in milliseconds
LOST_INPUTS_RETRIES = 2
ARRIVAL_SECONDS = 30  # how long a local:N cluster's start waits for its workers to register, at most
# Tasks per worker thread a stage aims at on a cluster, at least: a late worker or a slow task then
# delays the stage by a fraction of a worker's share (bake/lightmap.py tile_size, the cube-map stage)
TASKS_PER_WORKER = 4
# Dask's log lines shown while a bake runs: none below CRITICAL (a lost scheduler or worker would
# otherwise print lines of its own beside the bake's one line; a worker that died and was replaced
# only makes the bake take longer)
QUIET = logging.CRITICAL
# `local:N` (local_cluster.LOCAL_ADDRESS), or a Dask address: [SCHEME://]HOST:PORT (tcp://, tls://, ws://,
# wss://, ucx://; no scheme: tcp)
REMOTE_ADDRESS = re.compile(r"(?:(tcp|tls|ws|wss|ucx)://)?(\[[0-9a-fA-F:.]+\]|[\w.-]+):(\d{1,5})")

_worker_state: Any = None
_worker_job: Callable | None = None


def _init_worker(parent: int, setup, setup_args, job, inherited: bool = False, state=None) -> None:
    """A pool's worker: its state built here (spawned), or `state`, the one its parent built before the
    fork (`inherited`)."""
    global _worker_state, _worker_job
    quiet_child(parent)  # Ctrl-C, SIGTERM, SIGHUP are the bake's: it stops the pool (no traceback of a worker's)
    _heap_for_large_arrays()
    _worker_state = state if inherited else setup(*setup_args)
    one_blas_thread()  # after the setup, which may load another BLAS (parallel/cpus.py)
    _worker_job = job


def _run_task(indexed):
    index, task = indexed
    return index, _worker_job(_worker_state, task)


class Executor(Protocol):
    """What a bake stage runs its tasks on (the module docstring): `LocalExecutor` or `DaskExecutor`.

    `start(modules)` once work is certain (`modules`: what a cluster's workers import ahead of the
    tasks); `run(setup, setup_args, job, tasks)` yields (task index, result) in completion order, each
    task a small typed object (bake/lightmap.py TileTask, glint/cubemap_stage.py ProbeTask) handled by
    `job(state, task)` on a worker whose `state = setup(*setup_args)` was built once; `workers()` what
    a stage may size its tasks by; `distributed`: the workers are a Dask cluster's (they do not share
    this machine's files); `statistics`: what the cluster cost (empty for local processes). A context
    manager: leaving it closes what `start` opened."""

    distributed: bool
    statistics: dict

    def __enter__(self) -> "Executor": ...

    def __exit__(self, *exc) -> None: ...

    def start(self, modules: tuple[str, ...] = ()) -> None: ...

    def workers(self) -> int: ...

    def run(self, setup: Callable, setup_args: tuple, job: Callable, tasks: Iterable) -> Iterator[tuple[int, Any]]: ...


class LocalExecutor:
    """Processes of this machine, `jobs` at most, started by each `run` (one job or one task: this
    process). `start_method` "fork" (the default): the state is built here and the workers inherit it,
    sharing its memory; "spawn" for a state that does not survive fork (a GL context: the cube-map
    stage), each worker building its own from setup_args, pickled.
    A worker that dies ends the run with one line (GlintError); an error or a signal here stops the
    workers rather than wait for them."""

    distributed = False

    def __init__(self, jobs: int, start_method: str = "fork"):
        self.jobs = max(1, int(jobs))
        self.start_method = start_method
        self.statistics: dict = {}

    def __enter__(self) -> "LocalExecutor":
        return self

    def __exit__(self, *exc) -> None:
        pass

    def start(self, modules: tuple[str, ...] = ()) -> None:
        """Nothing to start: the processes are started by each `run`."""

    def workers(self) -> int:
        return self.jobs

    def run(self, setup: Callable, setup_args: tuple, job: Callable, tasks: Iterable) -> Iterator[tuple[int, Any]]:
        tasks = list(enumerate(tasks))
        if self.jobs == 1 or len(tasks) <= 1:
            _heap_for_large_arrays()
            state = setup(*setup_args)
            for index, task in tasks:
                yield index, job(state, task)
            return
        # Forked workers inherit a state built here, once: they share its pages (the path tracer's
        # tables and Embree's BVH, 43 MiB for the staircase) where a state built in every worker
        # would be as many copies, competing for the CPU's shared cache. A spawned worker builds its own.
        inherited = self.start_method == "fork"
        if inherited:
            _heap_for_large_arrays()
        state = setup(*setup_args) if inherited else None
        pool = ProcessPoolExecutor(min(self.jobs, len(tasks)), mp_context=mp.get_context(self.start_method),
                                   initializer=_init_worker,
                                   initargs=(os.getpid(), setup, setup_args, job, inherited, state))
        try:
            with deferred_signals():  # a signal between a fork and its worker's quiet_child is the bake's
                futures = [pool.submit(_run_task, task) for task in tasks]  # the processes start here
            for done in as_completed(futures):
                yield done.result()
        except BrokenProcessPool as e:  # a worker died (out of memory, killed): one line, no traceback
            _stop(pool)
            raise GlintError(f"a bake worker process stopped before its tasks were done ({e}); "
                             "bake again, or with --jobs 1") from None
        except BaseException:  # Ctrl-C, SIGTERM, an error: stop the workers, not wait for them
            _stop(pool)
            raise
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


def _stop(pool: ProcessPoolExecutor) -> None:
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        process.terminate()


def executor_for(settings) -> Executor:
    """The executor of a bake's settings: its Dask cluster (`settings.scheduler`), else `settings.workers`
    local processes."""
    scheduler = getattr(settings, "scheduler", None)
    return DaskExecutor(scheduler) if scheduler else LocalExecutor(settings.workers)


def check_scheduler_address(address: str) -> str:
    """`address` if it is `local:N` (N >= 1) or [SCHEME://]HOST:PORT, else a one-line GlintError."""
    local = local_cluster.LOCAL_ADDRESS.fullmatch(address)
    if (local and int(local.group(1)) >= 1) or (not local and REMOTE_ADDRESS.fullmatch(address)):
        return address
    raise GlintError(f"bad --scheduler '{address}': expected tcp://HOST:PORT (a running `dask scheduler`) "
                     "or local:N (N worker processes on this machine), e.g. tcp://10.0.0.5:8786 or local:4")


def worker_version() -> str:
    """The glint version of the process it runs in (on a Dask worker: `client.run(worker_version)`),
    read when called: the package's attribute as that process has it."""
    import glint

    return glint.__version__


def version_error(address: str, theirs: str, ours: str) -> GlintError:
    return GlintError(f"the Dask worker {address} runs glint {theirs} but this bake runs glint {ours}: "
                      f"install glint {ours} on every worker (bakes must be the same bytes on every machine)")


# -- on a Dask worker ------------------------------------------------------------------------------
# A worker process keeps the state of the inputs it last set up (keyed by their scattered data's
# key), so that every task of a stage after the first on that worker reuses it; `_forget` drops it
# when the stage ends. A lock, because a worker may run several tasks at once (--nthreads > 1).
_states: dict[str, Any] = {}
_states_lock = threading.Lock()


def _dask_task(setup: Callable, setup_args: tuple, key: str, job: Callable, task, version: str):
    """One task on a Dask worker: the worker's state for `key` (built on first use), then the job."""
    if worker_version() != version:  # a worker that joined after the check at connect
        raise version_error(_import_distributed().get_worker().address, worker_version(), version)
    with _states_lock:
        if key not in _states:
            for old in list(_states):
                _release(_states.pop(old))
            _heap_for_large_arrays()
            _states[key] = setup(*setup_args)
            one_blas_thread()
        state = _states[key]
    return job(state, task)


M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameters
MMAP_THRESHOLD = 32 << 20  # glibc's own upper bound for its dynamic mmap threshold (64-bit)
TRIM_THRESHOLD = 2 * MMAP_THRESHOLD  # twice the mmap threshold, as glibc's dynamic rule sets it


def _heap_for_large_arrays() -> None:
    """Let glibc keep the path tracer's arrays in the heap, in every process that runs bake jobs (the
    local executor's, a Dask worker's).

    Dask's nanny starts its workers with MALLOC_TRIM_THRESHOLD_=65536, which also pins glibc's mmap
    threshold at 128 KiB, so every array of the tracer's batches (a few MiB) would be mapped and
    unmapped anew, a page fault each time; raised thresholds keep them in the heap, faster than glibc's
    own dynamic thresholds in a plain process too (figures: docs/BAKE.md, "Worker heap settings").
    Nothing happens where the C library is not glibc."""
    import ctypes

    try:
        libc = ctypes.CDLL(None)
        libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)
        libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD)
    except (OSError, AttributeError):
        pass


def _forget(key: str) -> None:
    with _states_lock:
        if key in _states:
            _release(_states.pop(key))


def _release(state) -> None:
    """A state that holds more than memory (a GL context, a folder) has `release()`."""
    release = getattr(state, "release", None)
    if release is not None:
        release()


class DaskExecutor:
    """The workers of a Dask cluster, with `run` as LocalExecutor's. See the module docstring.

    Faults: a worker that dies has its tasks run again elsewhere by Dask (up to Dask's
    `distributed.scheduler.allowed-failures`, 3: a task that ends more workers is reported); should
    the scattered inputs die with it (no other worker held them yet), they are scattered again and
    the unfinished tasks submitted again (LOST_INPUTS_RETRIES times). The results are assembled by
    task index, so the order and the place they come from never matter. A scheduler that cannot be
    reached or goes away, a worker with another glint version, or a task's own GlintError end the
    bake with one line (GlintError). Dask's own log lines are held back while the executor is open
    (QUIET)."""

    distributed = True

    def __init__(self, address: str, name: str | None = None):
        self.address = check_scheduler_address(address)
        self.name = name or address  # in messages and statistics: local:N for a local cluster's client
        local = local_cluster.LOCAL_ADDRESS.fullmatch(address)
        self.local_workers = int(local.group(1)) if local else None
        self._client = self._error = self._server = None
        self._closing = False
        self._failure: GlintError | None = None  # set by _watch_server
        # local:N, from its server's reports (_watch_server): the scheduler's address, then the workers in
        self._local_address: str | None = None
        self._address_known = threading.Event()  # also set when the server fails
        self._arrived = threading.Event()  # set once the workers have registered, or the server failed
        self._workers_up = 0
        self._watched = threading.Event()  # set when _watch_server has seen the server end
        self._quiet = None  # Dask's log lines kept to QUIET while open
        # for the manifest's statistics.cluster: what the cluster cost this bake
        self.statistics = {"scheduler": self.name, "workers": 0, "threads": 0, "start_seconds": 0.0,
                           "waited_seconds": 0.0, "scatter_seconds": 0.0, "scattered_mib": 0.0, "tasks": 0}

    def __enter__(self) -> "DaskExecutor":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def start(self, modules: tuple[str, ...] = ()) -> None:
        """Reach the scheduler now (a remote one: a wrong address fails before any work), or start the
        `local:N` cluster in the background (the caller goes on), its workers with `modules` imported
        (those its tasks will run). Twice is once."""
        if self._client is not None or self._server is not None:
            return
        if self.local_workers is None:
            self._connect()
            return
        self._started = time.perf_counter()
        if importlib.util.find_spec("distributed") is None:  # the server would fail to import it
            _import_distributed()  # raises the one line that says what to install
        self._server = local_cluster.take_server(modules)  # forked or spawned here, on the main thread
        self._server.start(self.local_workers, QUIET, modules)
        self.statistics.update(worker_server=self._server.started, workers=self.local_workers,
                               threads=self.local_workers)
        threading.Thread(target=self._watch_server, args=(self._server,), name="glint-dask-server",
                         daemon=True).start()

    @property
    def client(self):
        """The connected `distributed.Client`. A local:N cluster's bake needs none here (its client is the
        server's: `run`); one is made on demand (tests, benchmarks), which imports Dask."""
        self.start()
        if self.local_workers is not None and self._client is None and self._error is None:
            self._connect()
        if self._error is not None:
            raise self._error
        return self._client

    def _connect(self) -> None:
        t0 = time.perf_counter()
        try:
            distributed = _import_distributed()
            self._quiet = distributed.utils.silence_logging_cmgr(QUIET)
            self._quiet.__enter__()
            if self.local_workers is not None:  # the server has started the scheduler meanwhile (or fails)
                self._address_known.wait(ARRIVAL_SECONDS)
                if self._failure is not None or self._local_address is None:
                    raise self._failure or GlintError(f"the local Dask cluster ({self.address}) did not start in "
                                                      f"{ARRIVAL_SECONDS} s: bake without --scheduler")
                address = self._local_address
            else:
                address = self.address
            try:
                self._client = distributed.Client(address, timeout=CONNECT_SECONDS, set_as_default=False)
            except (OSError, TimeoutError) as e:
                raise GlintError(f"cannot reach the Dask scheduler at {self.name} ({one_line(e)}): start one "
                                 "with `dask scheduler`, or use --scheduler local:N") from None
            if self.local_workers is not None:  # forked from this glint, or spawned from its files
                self._arrived.wait(ARRIVAL_SECONDS)
                if self._failure is not None:
                    raise self._failure
                return
            self._check_versions()
            threads = self._client.nthreads()
            self.statistics.update(start_seconds=round(time.perf_counter() - t0, 3), workers=len(threads),
                                   threads=sum(threads.values()))
            if self.local_workers is None and not threads:
                warn(f"the Dask scheduler at {self.address} has no workers yet: the bake waits for them "
                     f"(start some with `dask worker {self.address} --nthreads 1`)")
        except BaseException as e:  # kept, so that `client` reports it again rather than retry
            self._error = e
            self._disconnect()
            raise

    def _check_versions(self) -> None:
        """Refuse the cluster if a worker runs another glint version (its bytes could differ)."""
        ours = worker_version()
        for address, theirs in sorted(self._client.run(worker_version).items()):
            if theirs != ours:
                raise version_error(address, theirs, ours)

    def workers(self) -> int:
        """Worker threads in the cluster now (what a stage may size its tasks by); local:N: N, registered
        or about to be."""
        if self.local_workers is not None:
            return self.local_workers
        return max(1, sum(self.client.nthreads().values()))

    def _watch_server(self, server) -> None:
        """A local:N cluster's worker server's reports: the scheduler's address, the workers that came; and
        a server that gives up or ends while the bake runs ends the bake: the reason is kept for `_lost`
        (which waits for it: the server stops the scheduler too), and the client is closed, which cancels
        the futures `run` waits on."""
        reason = None

        def report(kind: str, text: str) -> None:
            nonlocal reason
            if kind == local_cluster.ADDRESS:
                self._local_address = text
                self._address_known.set()
            elif kind == local_cluster.UP:
                self._workers_up += 1
                if self._workers_up >= self.local_workers:
                    self._arrived.set()
            else:  # FAILED, GAVE_UP
                reason = text
                if kind == local_cluster.GAVE_UP:
                    self._failure = self._server_failure(reason)

        try:
            server.watch(report)
            if not self._closing:
                self._failure = self._failure or self._server_failure(reason or "their server ended")
                self._address_known.set()
                self._arrived.set()
                client = self._client
                if client is not None:
                    try:
                        client.close()
                    except Exception:  # closing already
                        pass
        finally:
            self._watched.set()

    def _server_failure(self, reason: str) -> GlintError:
        return GlintError(f"the worker processes of the local Dask cluster ({self.address}) could not be "
                          f"kept running ({reason}): bake without --scheduler")

    def run(self, setup: Callable, setup_args: tuple, job: Callable, tasks: Iterable,
            version: str | None = None) -> Iterator[tuple[int, Any]]:
        """LocalExecutor.run's results; `version`: the glint version the workers must run (this one's)."""
        version = version or worker_version()
        if self.local_workers is not None:
            yield from self._run_on_local_cluster(setup, setup_args, job, list(tasks), version)
            return
        client = self.client
        distributed = _import_distributed()
        pending = dict(enumerate(tasks))
        for _ in range(1 + LOST_INPUTS_RETRIES):
            if not pending:
                return
            try:
                # Once per worker: every task depends on the scattered inputs, which Dask copies to every
                # worker (from one worker to the next, in a tree) and to a worker that joins later (from
                # a peer); each worker builds its state from them once.
                t0 = time.perf_counter()
                [inputs] = client.scatter([setup_args], broadcast=True, hash=False)
                self._count(scatter_seconds=time.perf_counter() - t0, tasks=len(pending),
                            scattered_mib=_pickled_bytes(setup_args) / 2 ** 20)
                futures = {client.submit(_dask_task, setup, inputs, inputs.key, job, task, version,
                                         key=f"glint-{getattr(job, '__name__', 'job')}-{index}-{inputs.key}",
                                         pure=False): index
                           for index, task in pending.items()}
            except (OSError, *CANCELLED) as e:
                raise self._lost(e) from None
            try:
                for future in distributed.as_completed(futures, loop=client.loop):
                    result = self._result(future)
                    if result is _INPUTS_LOST:
                        continue  # submitted again, below
                    yield futures[future], result
                    del pending[futures[future]]
            finally:
                for future in futures:
                    future.cancel()
                try:
                    client.run(_forget, inputs.key)
                except Exception:  # workers gone or the scheduler lost: nothing left to free there
                    pass
        if pending:
            raise GlintError(f"the bake's inputs were lost on the Dask cluster at {self.name}: the workers that "
                             f"held them ended, on each of {1 + LOST_INPUTS_RETRIES} tries; bake again")

    def _run_on_local_cluster(self, setup, setup_args, job, tasks, version):
        """`run` on a local:N cluster: the request goes to its server's client process (parallel/local_cluster.py),
        which runs it with a DaskExecutor of its own (`_run_in_client_process`); results come back as
        they come, and what the client process counted goes into this executor's statistics."""
        self.start()
        t0 = time.perf_counter()
        for item in self._server.run(_run_in_client_process, setup, setup_args, job, tasks, version, self.name):
            if item is None:  # the client process is gone: its server gave up, or ended
                raise self._lost(ConnectionError("the cluster's client process ended"))
            kind, value = item
            if kind == "ready":  # the first request: the client connected, the workers are in
                self.statistics.update(start_seconds=round(time.perf_counter() - self._started, 3),
                                       waited_seconds=round(time.perf_counter() - t0, 3))
            elif kind == "result":
                yield value
            else:  # "statistics", after each request: the client's running totals
                self.statistics.update(value)

    def _count(self, **amounts) -> None:
        for key, amount in amounts.items():
            self.statistics[key] = round(self.statistics[key] + amount, 3)

    def _result(self, future):
        distributed = _import_distributed()
        try:
            return future.result()
        except GlintError:
            raise
        except distributed.KilledWorker as e:  # Dask's own retries spent
            raise GlintError(f"a bake task ended the Dask worker that ran it, on every try ({one_line(e)}); the "
                             "workers may be short of memory: give them more, or bake without --scheduler") from None
        except CANCELLED as e:
            if self._client is not None and self._client.status == "running" and self._failure is None:
                # its inputs were lost with the workers that held them (also when its result was lost with
                # the worker that had just finished it: "Couldn't gather 1 keys, rescheduling")
                return _INPUTS_LOST
            raise self._lost(e) from None
        except OSError as e:
            raise self._lost(e) from None

    def _lost(self, e: BaseException) -> GlintError:
        if self.local_workers is not None and not self._closing:
            self._watched.wait(local_cluster.STOP_SECONDS + 2)  # did its server stop it? (_watch_server)
        if self._failure is not None:
            return self._failure
        reason = "connection lost" if isinstance(e, CANCELLED) else one_line(e)
        return GlintError(f"lost the Dask scheduler at {self.name} during the bake ({reason}); "
                          "the previous bake directory is as it was: bake again")

    def close(self) -> None:
        """Disconnect; a `local:N` cluster is shut down."""
        self._disconnect()

    def _disconnect(self) -> None:
        self._closing = True
        client, server, self._client, self._server = self._client, self._server, None, None
        for part in (client, server):
            if part is not None:
                try:
                    part.close()
                except Exception:  # closing after the scheduler went away: nothing to close
                    pass
        if self._quiet is not None:
            self._quiet, quiet = None, self._quiet
            quiet.__exit__(None, None, None)


_INPUTS_LOST = object()  # DaskExecutor._result of a task to submit again

# In a local:N cluster's client process (parallel/local_cluster.py): its DaskExecutor, made on the first request
_client_executor: DaskExecutor | None = None


def _run_in_client_process(setup, setup_args, job, tasks, version, name):
    """A local:N cluster's request, in its client process: ("ready", None) after connecting (first request
    only), then ("result", (index, result)) per task, then ("statistics", its running totals)."""
    global _client_executor
    if _client_executor is None:
        address = local_cluster.client_context(ARRIVAL_SECONDS)
        executor = DaskExecutor(address, name=name)
        executor.start()
        _client_executor = executor
        yield "ready", None
    for result in _client_executor.run(setup, setup_args, job, tasks, version=version):
        yield "result", result
    yield "statistics", {key: _client_executor.statistics[key] for key in ("scatter_seconds", "scattered_mib", "tasks")}


def _pickled_bytes(value) -> int:
    """The bytes `value` travels as (pickle protocol 5, as Dask sends it; arrays not copied to count them)."""
    buffers = []
    head = pickle.dumps(value, protocol=5, buffer_callback=buffers.append)
    return len(head) + sum(b.raw().nbytes for b in buffers)


def _import_distributed():
    try:
        import distributed
    except ImportError:
        raise GlintError("--scheduler needs Dask, which is not installed: pip install 'glint[cluster]'") from None
    return distributed
