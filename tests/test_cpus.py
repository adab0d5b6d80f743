"""How many workers a bake starts by default, and their BLAS threads (parallel/cpus.py)."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest
from threadpoolctl import threadpool_limits

from glint.bake.settings import BakeSettings
from glint.parallel.cpus import blas_threads, cgroup_quota, usable_cpus
from glint.parallel.executor import LocalExecutor

MISSING = ("/nonexistent/cpu.cfs_quota_us", "/nonexistent/cpu.cfs_period_us")


def _v2(tmp_path, text):
    path = tmp_path / "cpu.max"
    path.write_text(text)
    return path


def test_a_cgroup_quota_caps_the_workers(tmp_path):
    """A container allowed 1.5 CPUs (cgroup v2 `cpu.max` "150000 100000") gets 2 workers at most, one
    allowed 1 CPU gets 1 -- not one per CPU of the host. Catches `os.cpu_count()` as the default (it
    ignores the quota: 2 on a 2-core machine for the 1-CPU case)."""
    from pathlib import Path

    missing = tuple(Path(p) for p in MISSING)
    assert cgroup_quota(_v2(tmp_path, "150000 100000\n"), missing) == pytest.approx(1.5)
    assert usable_cpus(_v2(tmp_path, "100000 100000\n"), missing) == 1
    assert usable_cpus(_v2(tmp_path, "150000 100000\n"), missing) == min(2, len(os.sched_getaffinity(0)))
    # no limit ("max"), an unreadable file, v1's -1: the affinity alone
    affinity = len(os.sched_getaffinity(0))
    assert usable_cpus(_v2(tmp_path, "max 100000\n"), missing) == affinity
    assert usable_cpus(tmp_path / "absent", missing) == affinity
    quota, period = tmp_path / "quota", tmp_path / "period"
    quota.write_text("-1\n"), period.write_text("100000\n")
    assert cgroup_quota(tmp_path / "absent", (quota, period)) is None
    quota.write_text("50000\n")
    assert usable_cpus(tmp_path / "absent", (quota, period)) == 1
    assert usable_cpus(_v2(tmp_path, "garbage"), missing) == affinity


def test_the_affinity_caps_the_workers():
    """A process pinned to one core (as `taskset -c 0 glint bake ...`) bakes with one worker by default.
    Catches `os.cpu_count()`, which counts every core of the machine."""
    code = ("import os; os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]}); "
            "from glint.bake.settings import BakeSettings; print(BakeSettings(jobs=0).workers)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "1"
    assert BakeSettings(jobs=3).workers == 3


def _setup():
    return None


def _threads(state, task):
    return blas_threads()


def test_every_worker_process_runs_one_blas_thread():
    """Each of a LocalExecutor's worker processes runs numpy's BLAS on one thread (the parent here
    allows two). Catches a worker left with OpenBLAS's default, one thread per core in every worker
    (removing `one_blas_thread()` from executor._init_worker: 2 here)."""
    if blas_threads() == 0:
        pytest.fail("numpy has no BLAS that threadpoolctl sees: this test could not fail")
    with threadpool_limits(limits=2, user_api="blas"):
        assert blas_threads() == 2
        results = dict(LocalExecutor(2).run(_setup, (), _threads, [0, 1, 2, 3]))
    assert results == {0: 1, 1: 1, 2: 1, 3: 1}
