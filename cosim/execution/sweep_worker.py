"""The Dask worker plugin of the clusters a sweep starts (`cosim.execution.sweep.local_cluster`).

A separate module: it imports `distributed` (a plugin must be a `WorkerPlugin`), which
`cosim.execution.sweep` loads only when a sweep starts its cluster.
"""

from __future__ import annotations

import signal
import threading
from typing import Any

from distributed import WorkerPlugin


class IgnoreInterrupt(WorkerPlugin):
    """The worker process ignores Ctrl-C (SIGINT), which a terminal sends to the sweep's
    whole process group: the sweep's own process handles it and closes the cluster (a
    worker interrupted on its own printed Dask's tracebacks and lost its sample)."""

    name = "cosim-ignore-interrupt"
    idempotent = True

    def setup(self, worker: Any) -> None:
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.SIG_IGN)
