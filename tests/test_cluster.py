"""`glint bake --scheduler`: the bake's light-map tiles and cube maps as tasks on a Dask cluster
(parallel/executor.py DaskExecutor, glint/cubemap_stage.py), on loopback.

The reference of every comparison is the local executor's bake of the same scene (two forked
processes, cube maps rendered in this process): the cluster's bake must be its bytes, file by file
(light maps, cube maps, textures, meshes), and its manifest apart from the statistics of time and
place (seconds, rays per second, processes, the cluster's address).
"""
from __future__ import annotations

import importlib.util
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import distributed  # in the `test` extra (pyproject.toml): CI runs these tests
import pytest
from conftest import FAST

import glint
from glint.parallel import executor as executor_module
from glint.bake import lightmap
from glint.parallel.executor import DaskExecutor
from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.cli import main
from glint.core.errors import GlintError
from glint.scenes.stress import many_objects
from glint.services import bake_scene

# 26,012 texels (13 tiles of glint.bake.lightmap.TILE), nine cube maps (probe_sharing = 0: one per
# metal box, every box metal); about 0.2 s a tile at 32 samples, so a worker killed after the first
# result still has work. (With three cube maps, two workers had sometimes finished the other two by the
# first result: "no worker had a task in flight to lose: [2, 0]", in 2 of the last 5 full runs.)
SETTINGS = {**FAST, "samples": 32, "texels_per_metre": 12.0}
CLI = ["-q", "draft", "--samples", "32", "--texels-per-metre", "12", "--no-denoise"]
# statistics that say when, where and in how many tasks, not what
TIMING = {"seconds", "trace_seconds", "phase_seconds", "rays_per_second", "seconds_per_cubemap", "processes", "cluster", "device",
          "tiles", "task_seconds_max", "worker_setup_seconds_max"}


@pytest.fixture(scope="module")
def scene_path(tmp_path_factory) -> Path:
    case = many_objects(tmp_path_factory.mktemp("cluster"), objects=9, metal_every=1)
    side = case.path.with_name(case.path.stem + ".glint.toml")
    side.write_text(side.read_text().replace("[bake]\n", "[bake]\nprobe_sharing = 0\n"))
    return case.path


@pytest.fixture(scope="module")
def reference(scene_path) -> Path:
    """The local executor's bake (two processes)."""
    out = scene_path.with_name("local.bake")
    scene = load_scene(scene_path)
    report = bake_scene(scene, resolve_settings(scene.bake_settings, **SETTINGS, jobs=2), out, progress=False)
    assert report.manifest["statistics"]["cubemaps"]["rendered"] == 9
    assert report.manifest["statistics"]["lightmaps"]["texels"] > 6 * 2048
    return out


def files_of(bake_dir: Path) -> dict[str, bytes]:
    return {p.relative_to(bake_dir).as_posix(): p.read_bytes() for p in sorted(bake_dir.rglob("*")) if p.is_file()}


def without_timing(value):
    if isinstance(value, dict):
        return {k: without_timing(v) for k, v in value.items() if k not in TIMING}
    return value


def assert_same_bake(bake: Path, reference: Path) -> None:
    ours, theirs = files_of(bake), files_of(reference)
    assert sorted(ours) == sorted(theirs)
    assert sum(name.startswith("cubemaps/") for name in ours) == 9
    differ = [name for name in theirs if name != "manifest.json" and ours[name] != theirs[name]]
    assert differ == [], "these files differ from the local bake's"
    ours, theirs = (json.loads(d["manifest.json"]) for d in (ours, theirs))
    assert without_timing(ours) == without_timing(theirs)


def test_cluster_bake_is_the_bytes_of_the_local_bake(scene_path, reference, monkeypatch, capsys):
    """`glint bake --scheduler tcp://...` of a two-worker cluster started here (so that this process is
    its client), its tasks run last first (Dask priorities), the light maps in
    smaller tiles than the local bake's (bake/lightmap.py tile_size, here 16 tiles of 1626 texels
    against 13 of 2048; a texel's random numbers follow its index): every light map,
    cube map, texture and the meshes are the local bake's bytes, the manifest its own apart from timing
    (so the stages' hashes too: a local bake of the same directory then finds it up to date); the
    cube-map progress counts each probe once; the workers, not this process, rendered the probes.
    Deliberate bugs tried: DaskExecutor.run yielding each result with its place in the order of
    completion instead of its task's index: "glint: internal error: ValueError: could not broadcast
    input array from shape (1626,3) into shape (1622,3)" (the first tile put in the last, shorter
    slot; tasks in their submitted order hid this bug in a run without the priorities). And
    bake_inputs reading the bake directory's top level only (glob, not rglob): exit 2, "glint: on the
    Dask worker machine vm: image: no such file /tmp/glint-probes-.../lightmaps/page_0.exr"."""
    from glint import services

    counted, stats = [], {}
    real = services.render_cubemaps

    def counting(bake_dir, plans, progress=None, workers=1, cluster=None):
        result = real(bake_dir, plans, progress=lambda: (counted.append(1), progress()), workers=workers,
                      cluster=cluster)
        stats.update(result)
        return result

    monkeypatch.setattr(services, "render_cubemaps", counting)
    # the last task first: results come back in about the reverse of the order they were submitted in
    submitted = []
    real_submit = distributed.Client.submit

    def last_first(self, *args, **kwargs):
        submitted.append(1)
        return real_submit(self, *args, **{**kwargs, "priority": len(submitted)})

    monkeypatch.setattr(distributed.Client, "submit", last_first)
    # tiles of 1626 texels on the cluster (26,012 / (8 x 2 workers)) against the local bake's 2048
    monkeypatch.setattr(lightmap, "TASKS_PER_WORKER", 8)
    out = scene_path.with_name("dask.bake")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=50) as cluster:
        address = cluster.scheduler_address
        assert main(["bake", str(scene_path), "-o", str(out), *CLI, "--scheduler", address]) == 0
    assert json.loads((out / "manifest.json").read_text())["statistics"]["lightmaps"]["tiles"] == 16
    assert json.loads((reference / "manifest.json").read_text())["statistics"]["lightmaps"]["tiles"] == 13
    assert_same_bake(out, reference)
    assert len(counted) == 9 and stats["cluster"] == address and stats["processes"] >= 1
    capsys.readouterr()
    assert main(["bake", str(scene_path), "-o", str(out), *CLI]) == 0
    assert "up to date" in capsys.readouterr().out


@pytest.mark.parametrize("workers", [2, 1])
def test_a_worker_killed_mid_bake_and_the_bake_is_still_the_same_bytes(scene_path, reference, monkeypatch, workers):
    """Once the first result of each stage (light-map tiles, cube maps) is in, the process of a worker
    that is running a task is killed (SIGKILL): Dask runs its tasks again on the other worker or the
    one the worker server forks in its place (parallel/local_cluster.py), and the bake is the local bake's bytes. With one worker the
    scattered inputs die with it: they are scattered again to its successor.
    Deliberate bug tried: no retries (`distributed.scheduler.allowed-failures` 0): the bake ends with
    "a bake task ended the Dask worker that ran it, on every try (Attempted to run task
    'glint-_trace_tile-2-...' on 1 different workers, but all those workers died ...)". No second
    scatter (LOST_INPUTS_RETRIES 0): with one worker, "the bake's inputs were lost on the Dask
    cluster at local:1 ..."."""
    killed = []
    real_run = DaskExecutor.run

    def run_and_kill(self, *args):
        for n, result in enumerate(real_run(self, *args)):
            if n == 0:
                killed.append(kill_a_busy_worker(self.client))
            yield result

    monkeypatch.setattr(DaskExecutor, "run", run_and_kill)
    out = scene_path.with_name(f"killed-{workers}.bake")
    scene = load_scene(scene_path)
    bake_scene(scene, resolve_settings(scene.bake_settings, **SETTINGS, scheduler=f"local:{workers}"), out,
               progress=False)
    assert len(killed) == 2 and all(killed), f"no worker had a task in flight to lose: {killed}"
    assert_same_bake(out, reference)


def kill_a_busy_worker(client) -> int:
    """SIGKILL the process of a worker with a task in flight; its task count, 0 if none had one."""
    for _ in range(100):
        busy = {worker: keys for worker, keys in client.processing().items() if keys}
        if busy:
            worker = sorted(busy)[0]
            pid = client.run(os.getpid, workers=[worker])[worker]
            os.kill(pid, signal.SIGKILL)
            return len(busy[worker])
        time.sleep(0.01)
    return 0


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_unreachable_scheduler_one_line_and_the_previous_bake_intact(scene_path, reference, tmp_path):
    """`python -m glint bake --force --scheduler tcp://127.0.0.1:<a free port>` over a previous bake: exit
    2 within the connect timeout (5 s) and some start-up, one line on stderr naming the address and
    what to do, no traceback; the previous bake is byte for byte as it was, and no temporary
    directory is left beside it.
    Deliberate bug tried: the connect error caught as TimeoutError only: "glint: internal error:
    OSError: Timed out trying to connect to tcp://127.0.0.1:38395 after 5 s (run with --debug for the
    traceback)", exit 1."""
    out = tmp_path / "previous.bake"
    shutil.copytree(reference, out)
    before = files_of(out)
    address = f"tcp://127.0.0.1:{free_port()}"
    t0 = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "glint", "bake", str(scene_path), "-o", str(out), *CLI, "--force",
                          "--scheduler", address], capture_output=True, text=True, timeout=120)
    seconds = time.perf_counter() - t0
    lines = run.stderr.strip().splitlines()
    assert run.returncode == 2 and len(lines) == 1, run.stderr
    assert lines[0].startswith(f"glint: cannot reach the Dask scheduler at {address}") and "dask scheduler" in lines[0]
    assert seconds < executor_module.CONNECT_SECONDS + 15
    assert files_of(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["previous.bake"]


def test_scheduler_lost_mid_bake_one_line_and_the_previous_bake_intact(scene_path, reference, tmp_path, monkeypatch):
    """A `dask scheduler` and a `dask worker` started here as processes; the scheduler is killed once the
    first light-map tile is in: the bake ends with one line that says so (within Dask's reconnect
    time, the connect timeout), and the previous bake in the output directory is as it was.
    Deliberate bug tried: `_result` without the CancelledError case: "distributed.client.
    FutureCancelledError: glint-_trace_tile-1-tuple-... cancelled for reason: scheduler-connection-lost"
    came out (an internal error at the command line), not a GlintError."""
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = [sys.executable, "-m", "dask"]
    scheduler = subprocess.Popen([*dask, "scheduler", "--port", str(port), "--no-dashboard"],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    worker = subprocess.Popen([*dask, "worker", address, "--nthreads", "1", "--no-dashboard"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_for_workers(address, 1)
        real_run = DaskExecutor.run

        def run_and_kill_the_scheduler(self, *args):
            for result in real_run(self, *args):
                scheduler.kill()
                yield result

        monkeypatch.setattr(DaskExecutor, "run", run_and_kill_the_scheduler)
        out = tmp_path / "previous.bake"
        shutil.copytree(reference, out)
        before = files_of(out)
        scene = load_scene(scene_path)
        t0 = time.perf_counter()
        with pytest.raises(GlintError) as lost:
            bake_scene(scene, resolve_settings(scene.bake_settings, **SETTINGS, scheduler=address), out,
                       force=True, progress=False)
        assert time.perf_counter() - t0 < executor_module.CONNECT_SECONDS + 20
    finally:
        for process in (worker, scheduler):
            process.kill()
            process.wait()
    assert str(lost.value).startswith(f"lost the Dask scheduler at {address} during the bake")
    assert "\n" not in str(lost.value)
    assert files_of(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["previous.bake"]


def wait_for_workers(address: str, count: int) -> None:
    with distributed.Client(address, timeout=30, set_as_default=False) as client:
        client.wait_for_workers(count, timeout=60)


def test_workers_without_egl_say_what_to_install(scene_path, tmp_path):
    """A cluster whose worker cannot open an EGL display (no EGL vendor library found, as on a machine
    without libegl-mesa0 or a GPU driver): the light maps bake there, and the cube-map stage ends the
    bake with one line that names the worker machine and the packages to install; nothing is written.
    Deliberate bug tried: ClusterProbeWorker without its GlintError case: the line was "cannot create a
    headless OpenGL 4.3 context with EGL (requested device index 0, but found 0 devices); install ..."
    without "on the Dask worker machine vm:" (whose EGL is missing, this machine's or a worker's?)."""
    no_egl = {"__EGL_VENDOR_LIBRARY_FILENAMES": str(tmp_path / "none.json")}
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None,
                                  env=no_egl, silence_logs=50) as cluster:
        scene = load_scene(scene_path)
        out = tmp_path / "no-egl.bake"
        with pytest.raises(GlintError) as failed:
            bake_scene(scene, resolve_settings(scene.bake_settings, **SETTINGS, scheduler=cluster.scheduler_address),
                       out, progress=False)
    message = str(failed.value)
    assert message.startswith(f"on the Dask worker machine {socket.gethostname()}: cannot create a headless OpenGL")
    assert "apt-get install libegl1 libegl-mesa0" in message and "\n" not in message
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == []


def test_workers_of_another_glint_version_are_refused(scene_path, monkeypatch):
    """A cluster whose worker runs glint 0.0.1 (a preload that sets glint.__version__ there): connecting
    refuses it with one line naming both versions. A worker that passed the check but whose version
    differs from the bake's by the time a task runs (as one that joins later) fails that task with the
    same line.
    Deliberate bugs tried: `_check_versions` not called at connect: "DID NOT RAISE" at start() (the
    bake would run on the other version's worker); the check in `_dask_task` left out: "DID NOT RAISE"
    for the task."""
    old = "import glint; glint.__version__ = '0.0.1'  # this worker's glint is another"
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None,
                                  preload=[old], silence_logs=50) as cluster:
        executor = DaskExecutor(cluster.scheduler_address)
        with pytest.raises(GlintError) as refused:
            executor.start()
    message = str(refused.value)
    assert "glint 0.0.1" in message and f"glint {glint.__version__}" in message and "\n" not in message

    with DaskExecutor("local:1") as executor:
        executor.start()
        monkeypatch.setattr(executor_module, "worker_version", lambda: "9.9.9")  # the bake's side only
        with pytest.raises(GlintError) as late:  # refused before setup (str) or job (max) would run
            list(executor.run(str, (), max, ["a", "b"]))
    message = str(late.value)
    assert f"runs glint {glint.__version__} but this bake runs glint 9.9.9" in message


def test_without_dask_the_scheduler_option_says_what_to_install(monkeypatch):
    """`distributed` not importable: --scheduler gives one line with the pip command.
    Deliberate bug tried: the ImportError not caught: "ModuleNotFoundError: import of distributed
    halted; None in sys.modules" (an internal error at the command line)."""
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(GlintError, match=r"pip install 'glint\[cluster\]'"):
        DaskExecutor("tcp://127.0.0.1:8786").start()
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *args: None)  # local:N looks before it forks
    with pytest.raises(GlintError, match=r"pip install 'glint\[cluster\]'"):
        DaskExecutor("local:2").start()


def test_a_local_bake_does_not_import_dask(tmp_path):
    """Without --scheduler Dask is never imported (an optional extra): a whole `glint bake` in a fresh
    interpreter leaves `dask` and `distributed` out of sys.modules.
    Deliberate bug tried: `import distributed` at the top of parallel/executor.py: "0 ['dask', 'distributed']"."""
    code = ("import sys; from glint.cli import main; "
            f"code = main(['bake', 'cornell-box', '-o', {str(tmp_path / 'c.bake')!r}, '-q', 'draft', '--samples', '1', "
            "'--no-denoise']); "
            "loaded = sorted(m for m in ('dask', 'distributed') if m in sys.modules); "
            "print(code, loaded)")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert run.stdout.strip().splitlines()[-1] == "0 []", run.stdout + run.stderr


# -- local:N's own worker server (parallel/local_cluster.py) --------------------------------------------
def glint_processes(marker: str) -> list:
    """The processes whose command line names `marker` (a forked worker server and its workers carry the
    command line of the `glint` process they were forked from)."""
    import psutil  # a dependency of distributed

    found = []
    for process in psutil.process_iter(["cmdline"]):
        if any(marker in part for part in process.info["cmdline"] or ()):
            found.append(process)
    return found


def test_the_glint_command_forks_its_worker_server_and_bakes_the_same_bytes(scene_path, reference, tmp_path):
    """`python -m glint bake --scheduler local:2` in a process of its own: its worker server is forked
    from it (statistics.cluster.worker_server), the bake is the local bake's bytes, and once the command
    has ended no process of its cluster is left.
    Deliberate bugs tried: glint/cli.py without its fork_server call: "assert 'spawned' == 'forked'".
    The forked server keeping the command pipe's write end open (so it never sees the bake close it):
    the command's output never ended (the server, still running, holds it): subprocess.run timed out."""
    out = tmp_path / "forked.bake"
    run = subprocess.run([sys.executable, "-m", "glint", "bake", str(scene_path), "-o", str(out), *CLI,
                          "--scheduler", "local:2"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    cluster = json.loads((out / "manifest.json").read_text())["statistics"]["cluster"]
    assert cluster["worker_server"] == "forked" and cluster["workers"] == 2
    assert_same_bake(out, reference)
    deadline = time.monotonic() + 10
    while glint_processes(str(out)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not glint_processes(str(out)), f"{len(glint_processes(str(out)))} left"


def test_a_killed_bake_leaves_no_worker_processes(scene_path, tmp_path):
    """The `glint bake --scheduler local:2` process killed (SIGKILL) while its workers trace: its worker
    server sees its pipe close, stops the workers and ends; within 10 s nothing of the cluster is left.
    Deliberate bug tried: `serve` not watching its command pipe once the workers run (select on nothing):
    "N processes of the killed bake's cluster still run"."""
    import psutil

    out = tmp_path / "killed.bake"
    bake = subprocess.Popen([sys.executable, "-m", "glint", "bake", str(scene_path), "-o", str(out), *CLI,
                             "--scheduler", "local:2"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    children = []
    deadline = time.monotonic() + 120
    while len(children) < 5 and time.monotonic() < deadline:  # the server, its scheduler, client, two workers
        children = psutil.Process(bake.pid).children(recursive=True)  # (and any short-lived helper process)
        time.sleep(0.05)
    assert len(children) >= 5, f"the bake's cluster did not start: {children}"
    bake.kill()
    bake.wait()
    gone, alive = psutil.wait_procs(children, timeout=10)
    for process in alive:
        process.kill()
    assert not alive, f"{len(alive)} processes of the killed bake's cluster still run"


GIVES_UP = """
import os
from glint.parallel import local_cluster
from glint.parallel.executor import DaskExecutor
from glint.core.errors import GlintError
def end_the_worker(state, task):
    os._exit(3)

local_cluster.RESTARTS = 1  # the forked server (and its client process) have these too
local_cluster.fork_server()

with DaskExecutor("local:1") as executor:
    try:
        list(executor.run(str, (), end_the_worker, ["a"]))
    except GlintError as e:
        print("GlintError:", e)
"""


def test_workers_that_keep_dying_end_the_bake_with_one_line(tmp_path):
    """A task that ends its worker every time, on local:1 whose server may replace a worker once: the
    server gives up after the second death and the bake ends with one line that says so (Dask alone would
    wait for a worker for ever).
    Deliberate bug tried: DaskExecutor.start without its watching thread: "GlintError: lost the Dask
    scheduler at local:1 during the bake (No valid workers found) ..." (the scatter again of the lost
    inputs timed out), a line that blames the wrong thing."""
    run = subprocess.run([sys.executable, "-c", GIVES_UP], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    lines = run.stdout.strip().splitlines()
    assert lines == ["GlintError: the worker processes of the local Dask cluster (local:1) could not be kept running "
                     "(worker processes ended abnormally 2 times): bake without --scheduler"], run.stdout + run.stderr


def test_a_local_cluster_bake_does_not_import_dask_in_the_bake_process(scene_path, reference, tmp_path):
    """`glint bake --scheduler local:1` in a fresh interpreter: the bake is the local bake's bytes and
    `distributed` never entered the bake's own process (the cluster's client is its worker server's,
    parallel/local_cluster.py), which is what keeps the cluster's start and exit off a small bake's time.
    Deliberate bug tried: DaskExecutor.run for local:N through the in-process client (`self.client`)
    instead of the server's: "0 ['dask', 'distributed']"."""
    out = tmp_path / "client.bake"
    code = ("import sys; from glint.cli import main; "
            f"code = main(['bake', {str(scene_path)!r}, '-o', {str(out)!r}, *{CLI!r}, '--scheduler', 'local:1']); "
            "loaded = sorted(m for m in ('dask', 'distributed') if m in sys.modules); "
            "print(code, loaded)")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert run.stdout.strip().splitlines()[-1] == "0 []", run.stdout + run.stderr
    assert_same_bake(out, reference)
