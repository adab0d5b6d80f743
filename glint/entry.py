"""The `glint` command's entry point (pyproject.toml [project.scripts], `python -m glint`).

A command line with `--scheduler local:N` has its cluster's worker server forked first, from a process
that has imported nothing but the standard library (bake/local_cluster.py): the server imports Dask
and the light-map tasks' modules on the other core while this process imports glint, and its
cluster is up about when the bake needs it. Then glint/cli.py runs the command.
"""
from __future__ import annotations

import sys
import threading


def main() -> int:
    from glint.bake import local_cluster  # the standard library and glint.core.errors only

    if threading.active_count() == 1 and local_cluster.asks_for_local_cluster(sys.argv[1:]):
        local_cluster.fork_server()
    from glint.cli import main as run

    return run()
