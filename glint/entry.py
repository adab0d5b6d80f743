"""The `glint` command's entry point (pyproject.toml [project.scripts], `python -m glint`).

A command line with `--scheduler local:N` has its cluster's worker server forked first, from a process
that has imported nothing but the standard library (parallel/local_cluster.py): the server imports Dask
and the light-map tasks' modules on the other core while this process imports glint, and its
cluster is up about when the bake needs it. Then glint/cli.py runs the command.
"""
from __future__ import annotations

import sys
import threading


# what a bake's tasks run first (bake/pipeline.py starts the cluster with the same); a name, not the
# module: importing it here would import numpy and Embree before the fork
LIGHTMAP_STAGE = "glint.bake.lightmap"


def main() -> int:
    from glint.parallel import local_cluster  # the standard library and glint.core.errors only

    if threading.active_count() == 1 and local_cluster.asks_for_local_cluster(sys.argv[1:]):
        local_cluster.fork_server(modules=(LIGHTMAP_STAGE,))
    from glint.cli import main as run

    return run()
