"""Local worker processes (parallel/executor.py LocalExecutor): where their state is built."""
from __future__ import annotations

import os

from glint.parallel.executor import LocalExecutor

BUILT: list[int] = []  # the processes that built a state, as this process sees them


def _setup(tag):
    BUILT.append(os.getpid())
    return {"built_by": os.getpid(), "tag": tag}


def _job(state, task):
    return state["built_by"], state["tag"], os.getpid()


def test_forked_workers_share_one_state_built_before_the_fork():
    """With fork, the state is built once, in this process, and every worker uses that one (its memory
    shared, not copied: the tracer's tables and BVH once for all workers). Catches a state built in every
    worker again (16 copies of the staircase's tracer competing for the shared cache on 16 cores): the
    builder's pid would be the worker's."""
    BUILT.clear()
    results = dict(LocalExecutor(2).run(_setup, ("scene",), _job, range(6)))
    assert BUILT == [os.getpid()]  # built here, once
    assert {built for built, _, _ in results.values()} == {os.getpid()}
    assert {tag for _, tag, _ in results.values()} == {"scene"}
    assert all(worker != os.getpid() for _, _, worker in results.values())  # the tasks ran in the workers


def test_spawned_workers_build_their_own_state():
    """With spawn (the cube-map stage's GL contexts), each worker builds its state from setup_args."""
    BUILT.clear()
    results = dict(LocalExecutor(2, start_method="spawn").run(_setup, ("scene",), _job, range(4)))
    assert BUILT == []
    assert all(built == worker and built != os.getpid() for built, _, worker in results.values())
