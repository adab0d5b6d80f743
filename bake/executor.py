"""Runs independent bake jobs (texel tiles) on local worker processes.

One interface, `LocalExecutor.run(tasks)`: each task is handled by
`job(state, task)` in a worker whose `state = setup(*setup_args)` was built once
per process (an Embree scene cannot be pickled, so every worker builds its own).
Results come back in completion order as (task index, result); the caller puts
them in place, so the outcome does not depend on the number of workers.
"""
from __future__ import annotations

import multiprocessing as mp
from typing import Any, Callable, Iterable, Iterator

_worker_state: Any = None
_worker_job: Callable | None = None


def _init_worker(setup, setup_args, job) -> None:
    global _worker_state, _worker_job
    _worker_state = setup(*setup_args)
    _worker_job = job


def _run_task(indexed):
    index, task = indexed
    return index, _worker_job(_worker_state, task)


class LocalExecutor:
    def __init__(self, jobs: int):
        self.jobs = max(1, int(jobs))

    def run(self, setup: Callable, setup_args: tuple, job: Callable, tasks: Iterable) -> Iterator[tuple[int, Any]]:
        tasks = list(enumerate(tasks))
        if self.jobs == 1 or len(tasks) <= 1:
            state = setup(*setup_args)
            for index, task in tasks:
                yield index, job(state, task)
            return
        # fork: workers inherit the scene without pickling it
        ctx = mp.get_context("fork")
        pool = ctx.Pool(min(self.jobs, len(tasks)), _init_worker, (setup, setup_args, job))
        try:
            yield from pool.imap_unordered(_run_task, tasks)
            pool.close()
        except BaseException:
            pool.terminate()
            raise
        finally:
            pool.join()
