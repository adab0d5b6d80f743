"""parallel/background.py: the one streaming background worker (the re-bake's process).

Expected values are the protocol's promises, not computed by the code under test: the newest request
wins and older waiting ones are skipped, a running request goes stale when a newer one is made, and
the worker ends with its parent (no orphan left running)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from glint.parallel.background import PARENT_CHECK_SECONDS, BackgroundWorker


def _echo(inbox, prefix):
    """Answers each request it takes with (number, prefix + payload), then works on it until it is
    stale, and says so."""
    inbox.send(("pid", os.getpid()))
    while (request := inbox.next()) is not None:
        number, payload = request
        inbox.send(("took", number, prefix + payload))
        deadline = time.monotonic() + 30
        while not inbox.stale(number) and time.monotonic() < deadline:
            time.sleep(0.01)
        inbox.send(("stale", number))
        time.sleep(0.2)  # so that the test's next two requests both wait: next() must take the newer


def _wait_for(worker, predicate, timeout=30.0):
    seen, deadline = [], time.monotonic() + timeout
    while time.monotonic() < deadline:
        seen += list(worker.messages())
        if predicate(seen):
            return seen
        time.sleep(0.01)
    raise AssertionError(f"not seen in {timeout} s: {seen}")


def test_the_newest_request_wins_and_the_running_one_goes_stale():
    """Bug it catches: request() not raising the shared number (the running request never goes stale:
    no ("stale", 1) arrives), or Inbox.next() taking the oldest waiting request instead of the newest
    (("took", 2, ...) before ("took", 3, ...))."""
    worker = BackgroundWorker(_echo, ("edit-",), name="glint-test-worker")
    try:
        assert worker.request("a") == 1
        _wait_for(worker, lambda seen: ("took", 1, "edit-a") in seen)
        assert worker.request("b") == 2 and worker.request("c") == 3
        seen = _wait_for(worker, lambda seen: ("took", 3, "edit-c") in seen)
        assert ("stale", 1) in seen
        assert not any(m[0] == "took" and m[1] == 2 for m in seen), seen  # skipped: a newer one waited
    finally:
        worker.close()
    assert not worker.alive()


_ORPHAN = """
import os, sys, time
sys.path.insert(0, {tests!r})
from test_background_worker import _echo
from glint.parallel.background import BackgroundWorker
if __name__ == "__main__":
    worker = BackgroundWorker(_echo, ("x",), name="glint-test-orphan")
    while True:
        for message in worker.messages():
            if message[0] == "pid":
                print(message[1], flush=True)
        time.sleep(0.01)
"""


def test_the_worker_ends_with_its_parent(tmp_path):
    """A parent killed with SIGKILL (no close()) leaves no worker behind: it ends within a few of its
    PARENT_CHECK_SECONDS. Bug it catches: Inbox.next() waiting forever on an empty queue without
    checking its parent (the worker outlived the parent by the whole 20 s this waits)."""
    script = tmp_path / "parent.py"
    script.write_text(_ORPHAN.format(tests=os.path.dirname(__file__)))
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        pid = int(parent.stdout.readline())
    finally:
        parent.send_signal(signal.SIGKILL)
        parent.wait()
    deadline = time.monotonic() + max(20.0, 10 * PARENT_CHECK_SECONDS)
    while time.monotonic() < deadline and _running(pid):
        time.sleep(0.05)
    assert not _running(pid), f"the worker {pid} outlived its parent"


def _running(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(") ", 1)[1][0] != "Z"  # a zombie has ended
    except FileNotFoundError:
        return False
