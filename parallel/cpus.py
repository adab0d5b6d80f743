"""How many CPUs this process may use, and one BLAS thread per worker process.

`usable_cpus()` is the default number of bake workers (`--jobs 0`). `os.cpu_count()` counts the
machine's CPUs, not the ones this process is allowed: a container limited by a CPU quota (Docker's
`--cpus`, a Kubernetes limit: cgroup `cpu.max`) or a process pinned to some cores (`taskset`, a
batch scheduler's affinity) would start one worker per CPU of the host, each slowed by the others.

`one_blas_thread()` holds numpy's BLAS (OpenBLAS) to one thread in a worker process. Left alone,
every worker's OpenBLAS starts as many threads as the machine has cores, and they spin while
waiting for work: on 16 cores, 16 workers of 16 threads each. Even on 2 cores the staircase's
light-map tracing was 7-10 % slower so (docs/BAKE.md, "Seen on 16 cores").
"""
from __future__ import annotations

import math
import os
from pathlib import Path

# cgroup v2 (one file: "QUOTA PERIOD" or "max PERIOD") and v1 (two files) CPU bandwidth limits
CGROUP_V2 = Path("/sys/fs/cgroup/cpu.max")
CGROUP_V1 = (Path("/sys/fs/cgroup/cpu/cpu.cfs_quota_us"), Path("/sys/fs/cgroup/cpu/cpu.cfs_period_us"))


def usable_cpus(cgroup_v2: Path = CGROUP_V2, cgroup_v1: tuple[Path, Path] = CGROUP_V1) -> int:
    """The CPUs this process may run on (its affinity) capped by its cgroup's CPU quota, rounded up;
    at least 1. The paths are parameters for the tests."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not Linux
        cpus = os.cpu_count() or 1
    quota = cgroup_quota(cgroup_v2, cgroup_v1)
    if quota is not None:
        cpus = min(cpus, max(1, math.ceil(quota)))
    return max(1, cpus)


def cgroup_quota(cgroup_v2: Path = CGROUP_V2, cgroup_v1: tuple[Path, Path] = CGROUP_V1) -> float | None:
    """CPUs' worth of time the cgroup allows (quota / period), or None: no limit, or none readable."""
    try:
        quota, period = cgroup_v2.read_text().split()[:2]
        return None if quota == "max" else _ratio(quota, period)
    except (OSError, ValueError):
        pass
    try:
        return _ratio(cgroup_v1[0].read_text().strip(), cgroup_v1[1].read_text().strip())
    except (OSError, ValueError):
        return None


def _ratio(quota: str, period: str) -> float | None:
    q, p = int(quota), int(period)
    return q / p if q > 0 and p > 0 else None  # v1 writes -1 for no limit


def one_blas_thread() -> None:
    """numpy's BLAS on one thread in this process, for as long as it lives (threadpoolctl)."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1, user_api="blas")


def blas_threads() -> int:
    """The threads numpy's BLAS would use in this process now (the largest of its libraries'; 0 without one)."""
    from threadpoolctl import threadpool_info

    return max((int(lib["num_threads"]) for lib in threadpool_info() if lib.get("user_api") == "blas"), default=0)
