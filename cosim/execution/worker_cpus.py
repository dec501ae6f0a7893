"""One CPU for each worker process of the local cluster a sweep starts.

A sweep's `distributed.LocalCluster` runs one single-threaded worker process per
CPU, each running one sample after another. Left to the OS, the workers move
between CPUs and now and then share one while another idles; each on its own
CPU, they keep theirs (and a sample's component processes and CSV writer,
started from the worker's thread, inherit it). Measured (6 runs of 10 s of
satory_nominal a sweep, 2 workers against 1, 4 alternating rounds, quiet
machine): 1368 runs/min with the OS placement, 1434 with a CPU per worker, i.e.
a scaling of 1.77 -> 1.85. The client and the scheduler, in the sweep's own
process, keep every CPU.

`OwnCpu` is a Dask worker plugin: it runs as each worker process starts
(restarts included) and puts every thread of that process on the CPU its
worker's index names. Only for a cluster of processes with no more workers than
CPUs, on Linux.
"""

from __future__ import annotations

import os
from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin

from cosim.engine.one_cpu import supported


class OwnCpu(WorkerPlugin):
    """Worker i of a LocalCluster on `cpus[i % len(cpus)]`.

    Args:
        cpus: the CPUs the sweep's process may use, in order.
    """

    name = "cosim-own-cpu"

    def __init__(self, cpus: list[int]) -> None:
        self.cpus = list(cpus)

    def setup(self, worker: Any) -> None:
        try:
            index = int(worker.name)  # a LocalCluster names its workers 0, 1, ...
        except (TypeError, ValueError):
            return
        cpu = {self.cpus[index % len(self.cpus)]}
        for tid in os.listdir("/proc/self/task"):
            try:
                os.sched_setaffinity(int(tid), cpu)
            except OSError:  # a thread that ended meanwhile, or a cpuset that refuses
                pass


def worker_plugins(workers: int, processes: bool) -> set[WorkerPlugin]:
    """The plugins that give each of `workers` worker processes its own CPU, or none (threads,
    a single worker, more workers than CPUs, no CPU affinity here)."""
    if not processes or workers < 2 or not supported():
        return set()
    cpus = sorted(os.sched_getaffinity(0))
    return {OwnCpu(cpus)} if workers <= len(cpus) else set()
