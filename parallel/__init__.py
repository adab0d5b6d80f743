"""Running work beside the main process: pools of typed tasks (executor.py), a local cluster's
worker server (local_cluster.py), one streaming background worker (background.py)."""
