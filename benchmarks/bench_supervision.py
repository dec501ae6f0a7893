"""Benchmark: what the run's supervision costs the master per tick, in one run.

(a) breadcrumb: one store of the master's breadcrumb word into the shared page
    (`cosim.execution.supervisor.ControlPage`), as the master does before each
    component call and once at the end of each tick;
(b) recording a tick of the lane-keeping closed loop's width (31 signals):
    `Recorder.after_tick` (the row through an mmap window into the kernel, then
    the row count; the page faults of the mmap included);
(c) the fork of the supervisor: `os.fork` of a process that has loaded what
    `cosim run` has loaded by then (typer, rich), until the child runs.
Times are this thread's CPU time (the machine is shared), the best of the
repetitions; the fork's is wall time. Time to tick 0 with and without the supervisor: `bench_startup.py --transports
zenoh,zenoh-nosupervise`; the whole loop: `bench_closed_loop.py`.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_supervision.py [--ticks 200000]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from cosim.execution.supervisor import ControlPage  # noqa: E402
from cosim.results.recorder import Recorder  # noqa: E402

COLUMNS = 30  # signals besides time


def crumb_ns(ticks: int) -> float:
    words = ControlPage().crumb
    start = time.thread_time()
    for k in range(ticks):
        words[0] = (k << 20) | 0x20001
    return (time.thread_time() - start) / ticks * 1e9


def _layout(n: int) -> SimpleNamespace:
    layout = SimpleNamespace(scalar_columns=lambda: [(f"c.s{i}", i) for i in range(n)],
                             array_signals=lambda: [], ports={})
    return SimpleNamespace(layout=layout, components={}, values=[0.0] * n)


def recorder_ns(ticks: int, folder: Path) -> float:
    recorder = Recorder(folder, flush_interval=1e9, keep_spool=True)
    recorder.begin(_layout(COLUMNS))
    values, arrays = [float(i) for i in range(COLUMNS)], np.zeros(0)
    start = time.thread_time()
    for k in range(ticks):
        recorder.after_tick(k, k * 0.01, values, arrays)
    elapsed = time.thread_time() - start
    for table in recorder._tables:  # noqa: SLF001 - no CSV conversion: not what is measured
        table.close()
    return elapsed / ticks * 1e9


def fork_ms(repeats: int) -> float:
    import rich.console  # noqa: F401 - what `cosim run` has loaded when it forks
    import typer  # noqa: F401

    best = float("inf")
    for _ in range(repeats):
        read, write = os.pipe()
        start = time.perf_counter()
        pid = os.fork()
        if pid == 0:
            os.write(write, b"x")
            os._exit(0)
        os.read(read, 1)
        best = min(best, time.perf_counter() - start)
        os.waitpid(pid, 0)
        os.close(read)
        os.close(write)
    return best * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=200000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    results: dict[str, list[float]] = {"crumb": [], "recorder": []}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeats):
            folder = Path(tmp) / str(r)
            folder.mkdir()
            results["crumb"].append(crumb_ns(args.ticks))
            results["recorder"].append(recorder_ns(args.ticks, folder))
    best = {k: min(v) for k, v in results.items()}
    print(f"breadcrumb store                 {best['crumb']:7.0f} ns (per component call, "
          f"and one per tick)")
    print(f"recorder, mmap spool + count     {best['recorder']:7.0f} ns per tick "
          f"({1 + COLUMNS} floats)")
    print(f"fork of the supervisor           {fork_ms(args.repeats):7.2f} ms once, at start-up")


if __name__ == "__main__":
    main()
