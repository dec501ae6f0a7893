"""`cosim sweep` throughput against the number of Dask workers (1 vs 2) on a LocalCluster.

For each worker count, a LocalCluster (one thread per worker process, each
process on its own CPU when there are several, as `cosim sweep` makes it) is started once and warmed up: one short sample pinned
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

`--long-samples N` (default 24; 0: none) times a second workload on the same
clusters, interleaved with the first: N runs of the same length. A sweep's
start (client, checks) and end (results, close) cost ~30 ms whatever its
size, a tenth of a 6-run sweep on 2 workers; in N = 24 runs they weigh a
quarter of that. It is printed after the first (`--samples`) workload's
figures, which stay the benchmark's figure against the target. From the two
workloads' median sweep times, each worker count's sweep time is then split
into a fixed part and a cost per run (a line through the two points): how far
the runs alone scale, and how much a sweep's start, end and last-run imbalance
(on 2 workers each runs half the samples: the sweep waits for the slower worker) weigh.

The clusters are joined by address (`run_sweep(scheduler=)`), so their workers are not
told how many runs they host (`run_scenario(runs_in_process=)`) and the controller loads
its compiled step whatever the length (COSIM_JIT=auto, numba installed); a one-off
`cosim sweep` of short samples, which starts its own cluster, runs them interpreted. The
benchmark times the warm, compiled runs a long sweep makes.

    .venv/bin/python benchmarks/bench_sweep.py [--samples 8] [--seconds 20] [--repeats 2]
        [--long-samples 24] [--transport inproc|zenoh] [--workers 1 2]
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

from benchmarks.common import emit_results, load_average, table_row, two_process_ceiling  # noqa: E402

SCENARIO = ROOT / "scenarios" / "satory_nominal.yaml"
VARY = "components.controller.parameters.ke=3.0:5.0"
TARGET = 1.8
CEILING_ROUNDS = 3  # alone / together pairs per measurement of the machine's ceiling (~1.5 s)


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
    parser.add_argument("--long-samples", type=int, default=24,
                        help="runs per sweep of the second workload, timed after each first one (0: none)")
    parser.add_argument("--transport", choices=("inproc", "zenoh"), default="inproc")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    if args.samples < 1 or args.repeats < 1 or min(args.workers) < 1 or args.long_samples < 0:
        parser.error("need --samples, --repeats and --workers >= 1, --long-samples >= 0")
    workloads = [args.samples] + ([args.long_samples] if args.long_samples else [])
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
        rates: dict[tuple[int, int], list[float]] = {(s, n): [] for s in workloads for n in args.workers}
        busy: dict[tuple[int, int], list[float]] = {key: [] for key in rates}
        ceilings: list[float] = []  # the machine's own 2-process scaling, around every round
        for round_ in range(args.repeats):
            ceilings.append(two_process_ceiling(rounds=CEILING_ROUNDS))
            for samples in workloads:
                for n in args.workers:
                    rate, cores = timed_sweep(clusters[n].scheduler_address, samples, args.seconds,
                                              args.transport, seed=round_)
                    rates[samples, n].append(rate)
                    busy[samples, n].append(cores)
        ceilings.append(two_process_ceiling(rounds=CEILING_ROUNDS))
    finally:
        for cluster in clusters.values():
            cluster.close()
    print(f"cosim sweep of satory_nominal ({args.samples} runs of {args.seconds:g} s, {args.transport}), "
          f"{args.repeats} alternating repeats; load average {before} before, {load_average()} after")
    ceiling = statistics.median(ceilings)
    print(f"two plain CPU-bound processes at once (one per CPU, as the workers), around the rounds: "
          f"{ceiling:.2f}x the work of one (min {min(ceilings):.2f}, max {max(ceilings):.2f}): "
          f"the most 2 workers can scale on this machine now")
    figures, rows = report(args, args.samples, rates, busy, startup, "", ceilings)
    if args.long_samples:
        print(f"second workload, not the figure above: {args.long_samples} runs of {args.seconds:g} s "
              f"per sweep, timed after each sweep of the first")
        more, more_rows = report(args, args.long_samples, rates, busy, startup,
                                 f"{args.long_samples} samples ", ceilings)
        figures.update(more)
        rows += more_rows
        figures.update(fixed_and_per_run(args, rates))
    emit_results("bench_sweep", {**figures, "samples": args.samples, "long samples": args.long_samples,
                                 "seconds": args.seconds, "transport": args.transport,
                                 "two-process ceiling": ceiling, "two-process ceilings": ceilings,
                                 "load": f"{before} -> {load_average()}"}, rows)


def report(args: argparse.Namespace, samples: int, rates: dict[tuple[int, int], list[float]],
           busy: dict[tuple[int, int], list[float]], startup: dict[int, float],
           prefix: str, ceilings: list[float]) -> tuple[dict[str, float], list[dict]]:
    """Print one workload's table and scaling; its figures (keys after `prefix`) and table row
    (which shows `ceilings`, the machine's own 2-process scaling measured around the rounds)."""
    print(f"{'workers':<10}{'best runs/min':>15}{'median':>10}{'cores busy':>12}{'cluster start s':>17}")
    figures: dict[str, float] = {}
    for n in args.workers:
        best, mid = max(rates[samples, n]), statistics.median(rates[samples, n])
        cores = statistics.median(busy[samples, n])
        figures[f"{prefix}{n} workers best"], figures[f"{prefix}{n} workers median"] = best, mid
        figures[f"{prefix}{n} workers cores busy"] = cores
        print(f"{n:<10}{best:>15.1f}{mid:>10.1f}{cores:>12.2f}{startup[n]:>17.2f}")
    if 1 not in args.workers or 2 not in args.workers:
        return figures, []
    scaling = max(rates[samples, 2]) / max(rates[samples, 1])
    figures[f"{prefix}scaling"] = scaling
    print(f"scaling 2 workers / 1 worker ({samples} runs a sweep): {scaling:.2f}x (medians: "
          f"{statistics.median(rates[samples, 2]) / statistics.median(rates[samples, 1]):.2f}x); "
          f"target >= {TARGET}: {'met' if scaling >= TARGET else 'not met'}")
    second = " (second workload)" if prefix else ""
    row = table_row(f"`cosim sweep` runs/min, 2 Dask workers / 1 ({samples} x {args.seconds:g} s "
                    f"satory, {args.transport}){second}",
                    f"{figures[prefix + '2 workers best']:.1f} vs {figures[prefix + '1 workers best']:.1f} "
                    f"runs/min: {scaling:.2f}x (cores busy {figures[prefix + '1 workers cores busy']:.2f} / "
                    f"{figures[prefix + '2 workers cores busy']:.2f}); two plain CPU-bound processes "
                    f"at once here: {statistics.median(ceilings):.2f}x ({min(ceilings):.2f}-"
                    f"{max(ceilings):.2f})", f">= {TARGET}x", scaling >= TARGET)
    return figures, [row]


def sweep_parts(samples: tuple[int, int], seconds_per_sweep: tuple[float, float]) -> tuple[float, float]:
    """(fixed ms per sweep, ms per run) of a straight line through two workloads' sweep times.

    Args:
        samples: the two workloads' runs per sweep (distinct).
        seconds_per_sweep: their sweep times, in seconds.
    """
    (n_a, n_b), (t_a, t_b) = samples, seconds_per_sweep
    per_run = (t_b - t_a) / (n_b - n_a)
    return (t_a - n_a * per_run) * 1e3, per_run * 1e3


def fixed_and_per_run(args: argparse.Namespace,
                      rates: dict[tuple[int, int], list[float]]) -> dict[str, float]:
    """Each worker count's sweep time split into a part that does not grow with the runs
    (client, checks, dispatch, results, the wait for the slower worker: what keeps a short
    sweep from scaling) and a cost per run, from the median sweep times of the two
    workloads; printed, and returned as figures.

    Not a row of the README's table: the fixed part is the difference of two noisy times
    (it came out -11 to 59 ms in three runs of the quick settings); the cost per run, and
    so how far the runs alone scale, is the steadier figure.
    """
    if 1 not in args.workers or 2 not in args.workers or args.long_samples in (0, args.samples):
        return {}
    workloads = (args.samples, args.long_samples)
    figures: dict[str, float] = {}
    for n in (1, 2):
        times = tuple(size / statistics.median(rates[size, n]) * 60.0 for size in workloads)
        fixed, per_run = sweep_parts(workloads, times)
        figures[f"{n} workers fixed ms"], figures[f"{n} workers ms per run"] = fixed, per_run
    if min(figures["1 workers ms per run"], figures["2 workers ms per run"]) <= 0.0:
        # the longer workload was not slower: the times are noise, the line says nothing
        print("1 / 2 workers, a line through the medians of both workloads: no cost per run "
              f"above 0 ({figures['1 workers ms per run']:.1f} / {figures['2 workers ms per run']:.1f} ms), "
              "the sweep times too noisy to split")
        return {}
    per_run_scaling = figures["1 workers ms per run"] / figures["2 workers ms per run"]
    figures["per-run scaling"] = per_run_scaling
    text = (f"fixed part {figures['1 workers fixed ms']:.0f} / {figures['2 workers fixed ms']:.0f} ms a "
            f"sweep, {figures['1 workers ms per run']:.1f} / {figures['2 workers ms per run']:.1f} ms a run: "
            f"the runs alone scale {per_run_scaling:.2f}x")
    print(f"1 / 2 workers, a line through the medians of both workloads: {text}")
    return figures


if __name__ == "__main__":
    main()
