"""Signals: SIGTERM and SIGHUP end a command the way Ctrl-C does.

A CI timeout or `kill` (SIGTERM) and a closed terminal (SIGHUP) would otherwise end the process
where it stands: a bake's temporary directory left behind, its worker processes running on.
`handle_termination()` (called by the `glint` command first thing) makes them raise `Terminated`,
a KeyboardInterrupt, so every cleanup Ctrl-C runs (BakeDirWriter's, the worker pools') runs for
them too; glint/cli.py prints one line and exits 128 + the signal's number (`exit_status`).

Worker processes leave the signals to the command: `quiet_child()` in a forked or spawned worker
ignores Ctrl-C and SIGHUP (the whole terminal's process group gets them; the command stops its
workers) and dies silently on SIGTERM (how a pool is stopped), with no traceback of its own.
`deferred_signals()` holds the three back over a few statements that must not be cut in two
(BakeDirWriter.commit's two renames, the forks of a pool) and delivers them afterwards.
"""
from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
from contextlib import contextmanager
from typing import Iterator

PR_SET_PDEATHSIG = 1  # linux/prctl.h
NAMES = {signal.SIGINT: "SIGINT", signal.SIGTERM: "SIGTERM", signal.SIGHUP: "SIGHUP"}


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP arrived (`signum`): handled like Ctrl-C."""

    def __init__(self, signum: int):
        super().__init__(NAMES.get(signum, str(signum)))
        self.signum = signum


def _terminate(signum, frame) -> None:
    raise Terminated(signum)


def handle_termination() -> None:
    """SIGTERM and SIGHUP raise Terminated in the main thread from now on (call it there)."""
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGTERM, signal.SIGHUP):
            if signal.getsignal(signum) is not signal.SIG_IGN:  # `nohup glint ...` stays immune to SIGHUP
                signal.signal(signum, _terminate)


def exit_status(interrupt: KeyboardInterrupt) -> tuple[str, int]:
    """(the signal's name, the exit status 128 + its number) of Ctrl-C or a Terminated."""
    signum = getattr(interrupt, "signum", signal.SIGINT)
    return NAMES.get(signum, str(signum)), 128 + int(signum)


def quiet_child(parent: int | None = None) -> None:
    """In a worker process: Ctrl-C and SIGHUP ignored (the command stops its workers), SIGTERM kills at
    once; on Linux it also gets SIGTERM when its parent dies (a SIGKILLed bake leaves no worker running).
    `parent`: the pid of the process that started this one. A parent that died before the request was
    made (between the fork and here) sends nothing: the worker then ends at once. Without this check a
    pool worker of a bake SIGKILLed at that moment was left waiting on its task pipe for good (seen
    once, under load, in tests/test_signals.py)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        except (OSError, AttributeError):
            pass
    if parent is not None and os.getppid() != parent:
        os._exit(128 + signal.SIGTERM)


@contextmanager
def deferred_signals() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP back for the `with` block, then deliver them (to the handlers
    that were in place). A process forked inside the block exits on SIGTERM and ignores the others until
    it sets its own (quiet_child). Outside the main thread it does nothing (handlers live there)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    owner, pending = os.getpid(), []

    def hold(signum, frame) -> None:
        if os.getpid() == owner:
            pending.append(signum)
        elif signum == signal.SIGTERM:  # a child forked in the block, before its own handlers
            os._exit(128 + signum)

    saved = {signum: signal.signal(signum, hold) for signum in NAMES}
    try:
        yield
    finally:
        for signum, handler in saved.items():
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)
        for signum in dict.fromkeys(pending):
            signal.raise_signal(signum)
