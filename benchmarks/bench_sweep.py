"""`cosim sweep` throughput against the number of Dask workers (1 vs 2) on a LocalCluster.

For each worker count, a LocalCluster (one thread per worker process, as
`cosim sweep` makes it) is started once and warmed up: one short sample pinned
to each worker, then one small sweep (each worker imports the platform and the
scenario's classes, builds its FMU cache entry, reads the scenario and the
FMU's description and lays out the planner's routes: what every later sample
reuses, see benchmarks/README.md). Then a timed sweep of `--samples` runs of
satory_nominal (`--set duration=...`, the controller's gain ke varied) goes
through `cosim.execution.sweep.run_sweep` on that cluster. The worker counts
alternate over `--repeats` rounds. Prints runs per minute (best and median),
the cores the workers kept busy (CPU seconds of the worker processes and their
children per second of the sweep: above 1 with one worker, the recorder's
writer process already runs beside it), the scaling 2 workers / 1 worker
(target >= 1.8 on this 2-core machine) and the start-up of a cluster, which a
one-off `cosim sweep` pays on top.

    .venv/bin/python benchmarks/bench_sweep.py [--samples 8] [--seconds 20] [--repeats 2]
        [--transport inproc|zenoh] [--workers 1 2]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.common import emit_results, load_average, table_row  # noqa: E402

SCENARIO = ROOT / "scenarios" / "satory_nominal.yaml"
VARY = "components.controller.parameters.ke=3.0:5.0"
TARGET = 1.8


def _cpu_seconds() -> float:
    """CPU seconds of this (worker) process and of the children it waited for (CSV writers,
    component processes)."""
    import resource

    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _warm_up(run_dir: str, transport: str) -> None:
    """One short sample on this worker, its folder then removed."""
    import shutil

    from cosim.execution.sweep import run_scenario_sample

    try:
        run_scenario_sample(SCENARIO, ["duration=5"], Path(run_dir), transport)
    finally:
        shutil.rmtree(run_dir, ignore_errors=True)


def warm_every_worker(scheduler: str, transport: str) -> None:
    """A short sample pinned to each worker: a sweep of one sample per worker may put two on
    one worker and leave the other cold (imports, caches) for the timed sweep's first sample."""
    from distributed import Client

    with Client(scheduler) as client, tempfile.TemporaryDirectory(prefix="bench-sweep-warm-") as out:
        workers = sorted(client.scheduler_info(n_workers=-1)["workers"])
        client.gather([client.submit(_warm_up, f"{out}/{i}", transport, workers=[w], pure=False)
                       for i, w in enumerate(workers)])


def timed_sweep(scheduler: str, samples: int, seconds: float, transport: str, seed: int) -> tuple[float, float]:
    """One sweep on the cluster at `scheduler`: (runs per minute, cores its workers kept busy on average)."""
    from distributed import Client

    from cosim.execution.sweep import run_sweep

    with Client(scheduler) as client, tempfile.TemporaryDirectory(prefix="bench-sweep-") as out:
        cpu = sum(client.run(_cpu_seconds).values())
        start = time.perf_counter()
        result = run_sweep(SCENARIO, [VARY], samples, seed=seed, scheduler=scheduler, out_dir=out,
                           transport=transport, sets=[f"duration={seconds:g}"])
        elapsed = time.perf_counter() - start
        cpu = sum(client.run(_cpu_seconds).values()) - cpu
    if result.failures:
        raise SystemExit(f"bench_sweep: {len(result.failures)} samples failed: {result.failures[0].error}")
    return samples / elapsed * 60.0, cpu / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=8, help="runs per timed sweep")
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=2, help="timed sweeps per worker count")
    parser.add_argument("--transport", choices=("inproc", "zenoh"), default="inproc")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    if args.samples < 1 or args.repeats < 1 or min(args.workers) < 1:
        parser.error("need --samples, --repeats and --workers >= 1")
    from cosim.execution.sweep import local_cluster

    before = load_average()
    clusters, startup = {}, {}
    try:
        for n in args.workers:
            start = time.perf_counter()
            clusters[n] = local_cluster(n)  # as `cosim sweep` starts its cluster
            startup[n] = time.perf_counter() - start
            warm_every_worker(clusters[n].scheduler_address, args.transport)
            timed_sweep(clusters[n].scheduler_address, n, 5.0, args.transport, seed=99)  # warm-up
        rates: dict[int, list[float]] = {n: [] for n in args.workers}
        busy: dict[int, list[float]] = {n: [] for n in args.workers}
        for round_ in range(args.repeats):
            for n in args.workers:
                rate, cores = timed_sweep(clusters[n].scheduler_address, args.samples, args.seconds,
                                          args.transport, seed=round_)
                rates[n].append(rate)
                busy[n].append(cores)
    finally:
        for cluster in clusters.values():
            cluster.close()
    print(f"cosim sweep of satory_nominal ({args.samples} runs of {args.seconds:g} s, {args.transport}), "
          f"{args.repeats} alternating repeats; load average {before} before, {load_average()} after")
    print(f"{'workers':<10}{'best runs/min':>15}{'median':>10}{'cores busy':>12}{'cluster start s':>17}")
    figures: dict[str, float] = {}
    for n in args.workers:
        best, mid = max(rates[n]), statistics.median(rates[n])
        figures[f"{n} workers best"], figures[f"{n} workers median"] = best, mid
        figures[f"{n} workers cores busy"] = statistics.median(busy[n])
        print(f"{n:<10}{best:>15.1f}{mid:>10.1f}{statistics.median(busy[n]):>12.2f}{startup[n]:>17.2f}")
    if 1 in rates and 2 in rates:
        scaling = max(rates[2]) / max(rates[1])
        figures["scaling"] = scaling
        print(f"scaling 2 workers / 1 worker: {scaling:.2f}x (medians: "
              f"{statistics.median(rates[2]) / statistics.median(rates[1]):.2f}x); target >= {TARGET}: "
              f"{'met' if scaling >= TARGET else 'not met'}")
    rows = []
    if "scaling" in figures:
        rows.append(table_row(f"`cosim sweep` runs/min, 2 Dask workers / 1 ({args.samples} x {args.seconds:g} s "
                              f"satory, {args.transport})",
                              f"{figures['2 workers best']:.1f} vs {figures['1 workers best']:.1f} runs/min: "
                              f"{figures['scaling']:.2f}x (cores busy {figures['1 workers cores busy']:.2f} / "
                              f"{figures['2 workers cores busy']:.2f})", f">= {TARGET}x",
                              figures["scaling"] >= TARGET))
    emit_results("bench_sweep", {**figures, "samples": args.samples, "seconds": args.seconds,
                                 "transport": args.transport, "load": f"{before} -> {load_average()}"}, rows)


if __name__ == "__main__":
    main()
