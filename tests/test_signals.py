"""SIGTERM (a CI timeout, `kill`) and SIGHUP (a closed terminal) end a bake as Ctrl-C does: its worker
processes stopped, its temporary directory removed, the previous bake intact, one line on stderr, exit
128 + the signal; a SIGKILLed bake's leftovers are removed by the next bake of its directory.

Each test runs a real `python -m glint bake living-room -j 2` (about 6 s on 2 cores) and
signals it once its temporary directory and its two pool workers exist."""
from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

psutil = pytest.importorskip("psutil")

BAKE = ["bake", "living-room", "-q", "draft", "-j", "2"]


def contents(root: Path) -> dict:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def previous(tmp_path_factory):
    """A finished bake of living-room (the one a signalled re-bake must leave as it was)."""
    root = tmp_path_factory.mktemp("signals")
    env = dict(os.environ, GLINT_CACHE=str(root / "cache"))
    done = subprocess.run([sys.executable, "-m", "glint", *BAKE, "-o", str(root / "lr")], env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return root, env, contents(root / "lr")


# The bake as a terminal starts it: the default actions of Ctrl-C and SIGHUP restored before Python starts.
# A command started with SIGINT ignored keeps it ignored (Python installs no KeyboardInterrupt then, as a
# shell's background job expects), and pytest run in the background of a non-interactive shell (`.ci/run ... &`)
# passes that on: there the SIGINT case's bake ran to its end, exit 0. Likewise SIGHUP under `nohup .ci/run`
# (a bake started with SIGHUP ignored stays immune to it, core/signals.py): the SIGHUP case's bake ran to its
# end and replaced the bake the later cases compare with.
AS_FROM_A_TERMINAL = ("import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); "
                      "signal.signal(signal.SIGHUP, signal.SIG_DFL); "
                      "os.execv(sys.executable, [sys.executable, *sys.argv[1:]])")


def start_and_wait(root: Path, env: dict) -> tuple[subprocess.Popen, list]:
    """A forced re-bake, returned once its temporary directory and its two light-map workers exist."""
    bake = subprocess.Popen([sys.executable, "-c", AS_FROM_A_TERMINAL, "-m", "glint", *BAKE, "-o", str(root / "lr"),
                             "--force"], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    process, deadline = psutil.Process(bake.pid), time.monotonic() + 120
    while time.monotonic() < deadline:
        workers = process.children(recursive=True)
        if len(workers) >= 2 and any(n.endswith(".tmp") for n in os.listdir(root)):
            return bake, workers
        assert bake.poll() is None, bake.communicate()
        time.sleep(0.05)
    bake.kill()
    pytest.fail("the bake never had its workers and temporary directory")


def running(workers: list) -> list:
    """The pids of `workers` still running after up to 5 s."""
    deadline = time.monotonic() + 5
    while True:
        left = [w.pid for w in workers if w.is_running() and w.status() != psutil.STATUS_ZOMBIE]
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.1)


@pytest.mark.parametrize("signum, group, status, line", [
    (signal.SIGTERM, False, 143, "glint: terminated (SIGTERM); nothing was half-written"),
    (signal.SIGHUP, False, 129, "glint: terminated (SIGHUP); nothing was half-written"),
    (signal.SIGINT, True, 130, "glint: interrupted; nothing was half-written"),
], ids=["SIGTERM", "SIGHUP", "SIGINT"])
def test_a_signal_ends_a_bake_cleanly(previous, signum, group, status, line):
    """Bugs caught: SIGTERM/SIGHUP ended the bake silently (exit 143 with no line), left its
    .NAME.*.tmp directory and a worker running on; Ctrl-C (SIGINT to the terminal's process group)
    printed `Process ForkPoolWorker-2:` and a worker's traceback."""
    root, env, before = previous
    bake, workers = start_and_wait(root, env)
    if group:  # as the terminal sends Ctrl-C: to every process of the foreground group
        os.killpg(bake.pid, signum)
    else:  # as `kill` or a CI timeout: to the command only
        os.kill(bake.pid, signum)
    sent = time.monotonic()
    out, err = bake.communicate(timeout=60)
    assert bake.returncode == status, f"exit {bake.returncode} {time.monotonic() - sent:.2f} s after the signal: {err}"
    assert err.splitlines() == [line], err
    assert running(workers) == []
    assert sorted(os.listdir(root)) == ["lr"]  # no .lr.*.tmp, nothing set aside
    assert contents(root / "lr") == before


def test_a_killed_bakes_leftovers_go_with_the_next_bake(previous):
    """Bugs caught: a SIGKILLed bake's .lr.<pid>.<random>.tmp left for good (the next bake, even one that
    finds the bake up to date, removes it), and its pool workers running on without their parent."""
    root, env, before = previous
    bake, workers = start_and_wait(root, env)
    bake.kill()
    bake.communicate(timeout=60)
    assert running(workers) == []  # they get SIGTERM when their parent dies (core/signals.py quiet_child)
    left = [n for n in os.listdir(root) if n.endswith(".tmp")]
    assert len(left) == 1 and left[0].startswith(f".lr.{bake.pid}.")
    again = subprocess.run([sys.executable, "-m", "glint", *BAKE, "-o", str(root / "lr")], env=env,
                           capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert "up to date" in again.stdout
    assert sorted(os.listdir(root)) == ["lr"]
    assert contents(root / "lr") == before
