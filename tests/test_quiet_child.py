"""core/signals.py quiet_child: a worker whose parent died before it asked to be told ends at once.

PR_SET_PDEATHSIG only covers a parent that dies after the request. A bake SIGKILLed between forking a
pool worker and that worker's quiet_child left the worker waiting on its task pipe for good (seen once
under load: an orphan `glint bake` worker, parent 1, blocked in a pipe read, 40 minutes on).

Bug it catches: quiet_child without the parent check (the grandchild below stays alive: the test's
wait for its end times out)."""
from __future__ import annotations

import os
import subprocess
import sys
import time

_ORPHAN = """
import os, sys, time
from glint.core.signals import quiet_child
parent = os.getpid()
pid = os.fork()
if pid == 0:  # the worker: its parent is gone before it asks to be told
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)  # the test's pipes close with the parent
    os.dup2(null, 2)
    while os.getppid() == parent:
        time.sleep(0.01)
    quiet_child(parent)
    time.sleep(60)  # a worker waiting for tasks that never come
    os._exit(0)
print(pid, flush=True)
os._exit(0)  # the parent dies at once, as a SIGKILLed bake
"""


def test_a_worker_whose_parent_is_already_gone_ends():
    out = subprocess.run([sys.executable, "-c", _ORPHAN], capture_output=True, text=True, timeout=60)
    pid = int(out.stdout)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and _alive(pid):
        time.sleep(0.05)
    alive = _alive(pid)
    if alive:
        os.kill(pid, 9)  # leave no orphan behind a failed test
    assert not alive, f"worker {pid} outlived its parent"


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(") ", 1)[1][0] != "Z"
    except FileNotFoundError:
        return False
