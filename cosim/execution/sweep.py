"""Monte-Carlo sweeps of a scenario on Dask: sample parameters, run, summarize metrics.

`run_sweep` draws `samples` points over the given ranges (`PATH=LOW:HIGH`,
PATH as in `cosim run --set`), seeded and deterministic: Latin hypercube by
default (each range cut in `samples` equal strata, one point per stratum, in
a random order per dimension), or plain uniform. Each point is a full run
(`cosim.execution.run.run_scenario` with the overrides) executed as one Dask task, on a
`distributed.LocalCluster` by default or on the cluster whose scheduler
address is given. Results, in sample order whatever order the tasks finish:

    OUT/samples.csv     sample, the varied values, status, every metric, error
    OUT/summary.csv     per metric: n, mean, std, min, p5, p50, p95, max
    OUT/summary.md      the same as a Markdown table
    OUT/sweep.json      the sweep's settings
    OUT/samples/sample_NNNN/   each sample's run folder

OUT must be missing or empty; `force` replaces an earlier sweep's folder (one holding
sweep.json or samples.csv, which is written as the sweep starts, status "running") and
refuses any other non-empty folder. --samples is 1..MAX_SAMPLES.

A sample whose run fails (a user error before tick 0, a component failure
mid-run, a lost worker) is kept in samples.csv with status "failed" and the
reason; the summary uses the samples that finished. A sample whose worker process
dies while running it (a segfault in a component) fails alone and once: the cluster
a sweep starts does not run a task again after it killed its worker
(`distributed.scheduler.allowed-failures` 0), the samples lost with that worker
without having started run again, and the dead sample's run folder is completed
(`cosim.execution.sweep_samples`: CSV files from the spools, manifest "failed").
On Ctrl-C (KeyboardInterrupt) nothing more is submitted, the running samples are
cancelled (their cluster closed), their folders completed as "interrupted", and the
index files are written with every sample that finished; `SweepInterrupted` then
carries that result. std is the sample
standard deviation (ddof = 1; 0 for a single value); percentiles interpolate
linearly between order statistics (numpy's default).
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import logging
import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from cosim.analysis.outputs import make_folder, write_failure
from cosim.analysis.rundata import AnalysisError
from cosim.execution.sweep_samples import (check_samples_count, check_sweep_out, empty_folder,
                                           lost_outcome, recorded_task,
                                           remove_marks)
from cosim.scenario.imports import import_roots

STATS = ("n", "mean", "std", "min", "p5", "p50", "p95", "max")
METHODS = ("lhs", "uniform")
RunFunction = Callable[[Path, Sequence[str], Path, str], dict[str, float]]


@dataclass(frozen=True)
class Vary:
    """One varied scenario value: PATH sampled in [low, high]."""

    path: str
    low: float
    high: float


def parse_vary(text: str) -> Vary:
    """Parse "PATH=LOW:HIGH" (e.g. "components.vehicle.uncertainty.m.scale=0.7:1.3").

    Raises:
        AnalysisError: the text is malformed, a bound is not a finite number, or LOW > HIGH.
    """
    path, sep, bounds = text.partition("=")
    low_text, colon, high_text = bounds.partition(":")
    if not sep or not colon or not path.strip():
        raise AnalysisError(f"--vary {text!r}: expected PATH=LOW:HIGH")
    try:
        low, high = float(low_text), float(high_text)
    except ValueError:
        raise AnalysisError(f"--vary {text!r}: LOW and HIGH must be numbers") from None
    if not (np.isfinite(low) and np.isfinite(high)):
        raise AnalysisError(f"--vary {text!r}: LOW and HIGH must be finite")
    if low > high:
        raise AnalysisError(f"--vary {text!r}: LOW {low:g} is above HIGH {high:g}")
    return Vary(path.strip(), low, high)


def sample_points(varies: Sequence[Vary], samples: int, seed: int,
                  method: str = "lhs") -> np.ndarray:
    """The (samples, len(varies)) matrix of sampled values.

    Args:
        varies: the ranges.
        samples: number of points (>= 1).
        seed: seed of numpy's default generator (same seed, same points), from 0 up.
        method: "lhs" (Latin hypercube) or "uniform".
    """
    check_samples_count(samples)
    if seed < 0:  # numpy's generators take a seed from 0 up
        raise AnalysisError(f"--seed {seed}: must be a whole number from 0 up")
    if method not in METHODS:
        raise AnalysisError(f"--method {method!r}: choose from {', '.join(METHODS)}")
    rng = np.random.default_rng(seed)
    dims = len(varies)
    if method == "lhs":
        strata = np.column_stack([rng.permutation(samples) for _ in range(dims)])
        unit = (strata + rng.random((samples, dims))) / samples
    else:
        unit = rng.random((samples, dims))
    low = np.array([v.low for v in varies])
    high = np.array([v.high for v in varies])
    return low + unit * (high - low)


def format_override(path: str, value: float) -> str:
    """A `--set` override "PATH=VALUE" whose VALUE YAML reads back as the same float."""
    text = repr(float(value))
    if "e" in text and "." not in text:
        mantissa, exponent = text.split("e")
        text = f"{mantissa}.0e{exponent}"  # YAML 1.1 needs a dot to read 1e-05 as a float
    return f"{path}={text}"


def summarize(values: Sequence[float]) -> dict[str, float]:
    """n, mean, std (ddof 1), min, p5, p50, p95, max of the values.

    Args:
        values: at least one finite number.
    """
    v = np.asarray(values, dtype=float)
    # values near the largest float: a sum or a square overflows and the mean or the std is
    # then inf or nan, shown as such in the table, without numpy's warnings
    with np.errstate(over="ignore", invalid="ignore"):
        p5, p50, p95 = np.percentile(v, [5, 50, 95])
        return {"n": float(len(v)), "mean": float(np.mean(v)),
                "std": float(np.std(v, ddof=1)) if len(v) > 1 else 0.0,
                "min": float(np.min(v)), "p5": float(p5), "p50": float(p50),
                "p95": float(p95), "max": float(np.max(v))}


@dataclass
class SampleResult:
    """One sample: its index, varied values, status ("ok"/"failed"), metrics, error."""

    index: int
    values: list[float]
    status: str
    metrics: dict[str, float] = field(default_factory=dict)
    error: str = ""


@dataclass
class SweepResult:
    """A finished sweep: settings, per-sample results, per-metric summary, files written."""

    varies: list[Vary]
    samples: list[SampleResult]
    summary: dict[str, dict[str, float]]
    out_dir: Path
    files: list[Path]

    @property
    def failures(self) -> list[SampleResult]:
        """The samples whose run failed."""
        return [s for s in self.samples if s.status != "ok"]


def run_scenario_sample(scenario_path: Path, overrides: Sequence[str], run_dir: Path,
                        transport: str, runs_in_process: int | None = None) -> dict[str, float]:
    """Run one sample for real and return its metrics (the default run function).

    Args:
        scenario_path: the scenario YAML.
        overrides: "PATH=VALUE" strings, as `cosim run --set`.
        run_dir: the sample's run folder.
        transport: "inproc" or "zenoh".
        runs_in_process: at most how many samples this worker process runs (a cluster the
            sweep starts and closes: all of them), None when unknown (a cluster joined
            with a scheduler address); see `cosim.execution.run.run_scenario`.

    Raises:
        UserError: the scenario or the run failed (the message says why).
    """
    from cosim.errors import UserError
    from cosim.analysis.metrics import write_metrics
    from cosim.analysis.rundata import read_json_object, recorded_run
    from cosim.execution.run import run_scenario
    from cosim.scenario.loader import load_scenario

    # samples run side by side, one per worker: the run does not choose a CPU itself (two
    # could choose the same one); the worker's own CPU, if it has one (worker_cpus), holds the
    # sample's processes too, since they start from the worker's thread
    result = run_scenario(load_scenario(scenario_path, list(overrides)), out_dir=run_dir,
                          transport=transport, progress=False, lockstep_cpu="off",
                          runs_in_process=runs_in_process)
    if result.status != "ok":
        raise UserError(result.error or f"run ended with status {result.status!r}")
    # one parse and one analysis of the run folder: metrics.json then holds the
    # components' metrics and the platform's, which is what the sample reports
    write_metrics(run_dir, run=recorded_run(run_dir, result.full_signals))
    return {k: v for k, v in read_json_object(run_dir / "metrics.json").items()
            if isinstance(v, (int, float)) and not isinstance(v, bool)}


def sample_problem(scenario_path: Path, overrides: Sequence[str],
                   roots: Sequence[str] = ()) -> str:
    """Why one sample is invalid (`cosim validate`'s message, one line), or "" if it is valid.

    Args:
        scenario_path: the scenario YAML.
        overrides: the sample's "PATH=VALUE" overrides (fixed ones first).
        roots: folders to put in front of the import path first (on a Dask worker).
    """
    from cosim.errors import UserError
    from cosim.execution.validate import validate_scenario
    from cosim.scenario.imports import add_import_roots
    from cosim.scenario.loader import load_scenario

    if roots:
        add_import_roots(tuple(roots))
    try:
        validate_scenario(load_scenario(scenario_path, list(overrides)))
    except UserError as exc:
        return str(exc).replace("\n", "; ")
    return ""


def refuse_invalid(scenario_path: Path, samples: Sequence[Sequence[str]],
                   problems: Sequence[str], shown: int = 5) -> None:
    """Raise a UserError listing the invalid samples (index, overrides, problem), one a line.

    Args:
        scenario_path: the scenario YAML.
        samples: each sample's overrides; problems: each one's `sample_problem`.
        shown: how many invalid samples the message lists.
    """
    from cosim.errors import UserError

    bad = [f"sample {index} ({' '.join(overrides)}): {problem}"
           for index, (overrides, problem) in enumerate(zip(samples, problems)) if problem]
    if bad:
        more = f"\n... and {len(bad) - shown} more" if len(bad) > shown else ""
        raise UserError(f"{scenario_path}: sweep refused before its first run: {len(bad)} "
                        f"of {len(samples)} samples are invalid:\n" + "\n".join(bad[:shown]) + more)


def check_samples(scenario_path: Path, samples: Sequence[Sequence[str]],
                  shown: int = 5) -> None:
    """Validate the scenario with every sample's overrides here, as `cosim validate` does.

    Args:
        scenario_path: the scenario YAML.
        samples: each sample's "PATH=VALUE" overrides (fixed ones first).
        shown: how many invalid samples the message lists.
    Raises:
        UserError listing the invalid samples (index, overrides, problem), one a line.
    """
    refuse_invalid(scenario_path, samples, [sample_problem(scenario_path, o) for o in samples], shown)


def validate_chunk(scenario_path: Path, roots: Sequence[str],
                   chunk: Sequence[Sequence[str]]) -> list[str]:
    """`sample_problem` of each sample of a chunk, in order (one cluster task validates many:
    a task per sample cost a scheduler round trip each, for a check of a few ms)."""
    return [sample_problem(scenario_path, overrides, roots) for overrides in chunk]


def chunks(items: Sequence[Any], count: int) -> list[list[int]]:
    """The indices of `items` dealt into at most `count` non-empty chunks of nearly equal size."""
    count = max(1, min(count, len(items)))
    return [list(range(first, len(items), count)) for first in range(count)] if items else []


@dataclass
class SampleCheck:
    """The validation of a sweep's samples (see `execute_samples`).

    `local` samples are validated here and now, before any cluster starts (a broken
    scenario is then refused at once, every sample listed); the others on the cluster's
    workers, in parallel and in one task per worker thread, while the runs wait for them
    on the cluster, not in this process (no round trip through the client between the
    checks and the first run).
    """

    scenario_path: Path
    samples: list[list[str]]
    roots: tuple[str, ...]
    local: int = 1  # how many samples, from the first, are validated in this process

    def __post_init__(self) -> None:
        self.local = min(self.local, len(self.samples))
        self.order: list[list[int]] = []  # the cluster's chunks: indices into samples[local:]
        self.problems = [sample_problem(self.scenario_path, o) for o in self.samples[:self.local]]
        if any(self.problems):
            check_samples(self.scenario_path, self.samples)  # raises, naming every invalid sample

    def submit(self, client: Any, threads: int) -> list[Any]:
        """The cluster's validation tasks (futures of lists of problems), one per chunk."""
        rest = self.samples[self.local:]
        self.order = chunks(rest, threads)
        return [client.submit(validate_chunk, self.scenario_path, self.roots,
                              [rest[i] for i in chunk], pure=False) for chunk in self.order]

    def refuse(self, chunk_problems: Sequence[Sequence[str]]) -> None:
        """Raise the refusal (UserError) if a sample of any chunk is invalid."""
        problems = self.problems + [""] * (len(self.samples) - self.local)
        for chunk, found in zip(self.order, chunk_problems):
            for i, problem in zip(chunk, found):
                problems[self.local + i] = problem
        refuse_invalid(self.scenario_path, self.samples, problems)


def _gated(task: Callable[..., tuple[str, dict[str, float], str]],
           chunk_problems: Sequence[Sequence[str]], *job: Any) -> tuple[str, dict[str, float], str]:
    """A run task that waits, on the cluster, for the samples' validation (its dependencies)
    and runs nothing if any sample is invalid (the client then raises the refusal)."""
    if any(problem for found in chunk_problems for problem in found):
        return "refused", {}, ""
    return task(*job)


def _run_task(run_fn: RunFunction, scenario_path: Path, transport: str, roots: tuple[str, ...],
              index: int, overrides: list[str], run_dir: Path) -> tuple[str, dict[str, float], str]:
    """One Dask task: run a sample, turn any failure into a "failed" status and message.

    `roots` (the scenario's folder and the master's cwd) go in front of the worker's
    import path, so a sample imports the scenario's modules as `cosim run` does.
    """
    from cosim.scenario.imports import add_import_roots

    add_import_roots(roots)
    try:
        return "ok", dict(run_fn(scenario_path, overrides, run_dir, transport)), ""
    except Exception as exc:  # noqa: BLE001 - one bad sample must not end the sweep
        from cosim.errors import UserError

        # a UserError's message says what failed (a component's crash too): no class name
        what = str(exc) if isinstance(exc, UserError) else f"{type(exc).__name__}: {exc}"
        return "failed", {}, f"sample {index}: {what}"


# Dask's periodic work, slowed down for the clusters a sweep starts: the event-loop health
# tick (20 ms by default) and the system and memory monitors (0.5 s, 0.1 s) cost the
# client's process about 0.03 of a core while the workers run (0.008 so), CPU the
# workers then do not get when they keep every core busy; nothing reads them sooner.
# The workers' profiler (a thread sampling the running task's stack every 10 ms, for a
# dashboard a sweep does not start) is off: ~4 % more runs per minute
# A task that was running on a worker that died is not run again (Dask's default: 3 more
# times, on 3 more workers): a sample that segfaults kills one worker, and fails alone.
CLUSTER_CONFIG = {"distributed.scheduler.allowed-failures": 0,
                  "distributed.admin.tick.interval": "1s",
                  "distributed.admin.system-monitor.interval": "2s",
                  "distributed.worker.memory.monitor-interval": "1s",
                  "distributed.worker.profile.enabled": False}


def local_cluster(workers: int, **options: Any) -> Any:
    """The `distributed.LocalCluster` a sweep starts: `workers` processes of one thread each,
    each on its own CPU (`cosim.execution.worker_cpus`), no dashboard, Dask's logs silent
    (a sample's failure, a worker's death included, is the sweep's to report, in one line), Dask's
    periodic work slowed (`CLUSTER_CONFIG`), the scheduler's streams to the workers batched
    every `BATCH_INTERVAL`; `options` are more LocalCluster keyword arguments (e.g.
    processes=False)."""
    import dask
    import distributed.scheduler
    from distributed import LocalCluster

    settings = {"n_workers": workers, "threads_per_worker": 1, "processes": True,
                "dashboard_address": None, "silence_logs": logging.CRITICAL, **options}
    if "plugins" not in settings:  # each worker process on its own CPU (worker_cpus)
        from cosim.execution.worker_cpus import worker_plugins

        settings["plugins"] = worker_plugins(workers, bool(settings["processes"]))
        if settings["processes"]:  # Ctrl-C is this process's to handle (sweep_samples)
            from cosim.execution.sweep_worker import IgnoreInterrupt

            settings["plugins"] = {*settings["plugins"], IgnoreInterrupt()}
    # the scheduler's streams to its workers are made as the workers join, within the block
    with dask.config.set(CLUSTER_CONFIG), _batches_every(distributed.scheduler, BATCH_INTERVAL):
        return LocalCluster(**settings)


# Dask batches the messages of each of its streams, one batch per interval at most (fixed
# in its code): a client's to the scheduler every 10 ms, the scheduler's to a worker every
# 5 ms. A client's first batch (two topic subscriptions) goes out as it connects, so a
# sweep's tasks, submitted a millisecond later, waited ~10 ms on the client before the
# scheduler saw them, and its close as long again; the runs, released when the checks
# finish, waited up to 5 ms more on the scheduler's stream to their worker. A sweep sends
# a few dozen messages: its client's stream, and the worker streams of the cluster it
# starts, batch at most every 1 ms instead (~12 ms less of a 0.3 s sweep on 2 workers).
BATCH_INTERVAL = "1ms"


@contextlib.contextmanager
def _batches_every(module: Any, interval: str) -> Iterator[None]:
    """Within the block, every `BatchedSend` that `module` (distributed.client or
    distributed.scheduler) makes batches at most every `interval`, whatever it asks for."""
    from unittest import mock

    from distributed.batched import BatchedSend

    def batched_send(*_interval_asked: Any, **kwargs: Any) -> BatchedSend:
        kwargs.pop("interval", None)
        return BatchedSend(interval=interval, **kwargs)

    if getattr(module, "BatchedSend", None) is not BatchedSend:  # not Dask's layout: as it is
        yield
        return
    with mock.patch.object(module, "BatchedSend", batched_send):
        yield


def prompt_client(address: Any, **options: Any) -> Any:
    """`distributed.Client(address, **options)` whose stream to the scheduler (made as it
    connects) batches at most every `BATCH_INTERVAL`."""
    import distributed.client
    from distributed import Client

    with _batches_every(distributed.client, BATCH_INTERVAL):
        return Client(address, **options)


SCHEDULER_EXAMPLE = "tcp://127.0.0.1:8786"
_HOST_PORT_SCHEMES = ("tcp", "tls", "ws", "wss")


def check_scheduler(address: str) -> str:
    """A `--scheduler` value that reads as a Dask scheduler address, before anything starts
    (Dask's own check came only as the client connected, as a ValueError's traceback).

    Args:
        address: e.g. "tcp://127.0.0.1:8786", or "127.0.0.1:8786" (tcp implied).
    Raises:
        AnalysisError naming the option, the value and the expected form.
    """
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import get_backend

    problem = (f"--scheduler {address!r}: expected a Dask scheduler address "
               f"PROTOCOL://HOST:PORT (port 1..65535), e.g. {SCHEDULER_EXAMPLE}")
    try:
        scheme, location = parse_address(address)
        get_backend(scheme)
        if scheme in _HOST_PORT_SCHEMES:
            host, port = parse_host_port(location)
            if not host or not 0 < port <= 65535:
                raise ValueError(location)
    except ValueError:
        raise AnalysisError(problem) from None
    return address


def _client(scheduler: str | None, workers: int, cluster_options: dict[str, Any] | None):
    """A Dask client and the local cluster it owns (None when joining a scheduler)."""
    if scheduler:
        try:
            return prompt_client(scheduler, timeout="10s"), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise AnalysisError(f"--scheduler {scheduler}: cannot connect: {exc}") from None
    cluster = local_cluster(workers, **(cluster_options or {}))
    return prompt_client(cluster), cluster


def _threads(client: Any) -> int:
    """The task slots of the client's cluster (its workers' threads), at least 1."""
    workers = client.scheduler_info(n_workers=-1).get("workers", {})
    return max(1, sum(int(w.get("nthreads", 1)) for w in workers.values()))


class SamplesInterrupted(Exception):
    """Ctrl-C during `execute_samples`: `outcomes` holds each job's outcome, None for a
    sample that never started (one that started and did not finish is "interrupted")."""

    def __init__(self, outcomes: list[tuple[str, dict, str] | None]) -> None:
        super().__init__("interrupted")
        self.outcomes = outcomes


def execute_samples(task: Callable[..., tuple[str, dict[str, float], str]],
                    jobs: Sequence[tuple[int, list[str], Path]], scheduler: str | None,
                    cluster_options: dict[str, Any] | None,
                    check: SampleCheck | None = None) -> list[tuple[str, dict, str]]:
    """Run the jobs (index, overrides, run_dir) as Dask tasks; results in job order.

    Each task goes through `cosim.execution.sweep_samples.recorded_task` (its start mark and
    outcome beside its run folder). A task lost with its worker (KilledWorker and the
    like) becomes a failed sample if it had started (its run folder completed), and runs
    again, on the cluster the sweep started, if it had not. `check`, if given, validates
    the samples on the cluster first: every run task depends on the validation tasks and
    runs only if every sample is valid; otherwise the check's refusal (UserError) is raised
    here and no sample has run.

    Raises:
        SamplesInterrupted on Ctrl-C, once the cluster is closed (a cluster the sweep
        started: its worker processes ended) and every outcome read from the disk.
    """
    workers = max(1, min(len(jobs), os.cpu_count() or 1))
    own = scheduler is None
    # a fault report only in worker processes of our own (not threads of this process)
    recorded = partial(recorded_task, task, own and bool((cluster_options or {}).get("processes", True)))
    outcomes: list[tuple[str, dict, str] | None] = [None] * len(jobs)
    client = cluster = None
    try:
        client, cluster = _client(scheduler, workers, cluster_options)
        checks = check.submit(client, _threads(client)) if check is not None else []
        if checks:  # each run task gets the checks' futures as arguments: its dependencies
            futures = client.map(partial(_gated, recorded), [checks] * len(jobs), *zip(*jobs),
                                 pure=False)
        else:
            futures = client.map(recorded, *zip(*jobs), pure=False)
        if check is not None:
            check.refuse(client.gather(checks))  # raises if a sample is invalid: nothing ran
        _outcomes(client, jobs, futures, recorded if own else None, outcomes)
        return outcomes  # type: ignore[return-value]  # every one filled in
    except KeyboardInterrupt:
        with _no_interrupts():  # a second Ctrl-C does not cut the clean-up short
            _end_workers(cluster)
            _close(client, cluster)
            client = cluster = None
            for position, (index, _, run_dir) in enumerate(jobs):
                if outcomes[position] is None:
                    outcomes[position] = lost_outcome(index, run_dir, interrupted=True)
        raise SamplesInterrupted(outcomes) from None
    finally:
        _close(client, cluster)
        remove_marks([run_dir for _, _, run_dir in jobs])


def _end_workers(cluster: Any) -> None:
    """Kill the worker processes of the cluster the sweep started (None: joined, or none yet):
    a cluster's close waits for the running samples to end. What a killed worker leaves
    ends with it: the CSV writer at the end of its input, a Zenoh component process when the
    master's liveliness token goes, an isolated FMU's process by PR_SET_PDEATHSIG."""
    import signal

    if cluster is None:
        return
    for nanny in list(getattr(cluster, "workers", {}).values()):
        pid = getattr(nanny, "pid", None)  # a Nanny's worker process; threads: no pid
        if isinstance(pid, int) and pid != os.getpid():
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)


def _close(client: Any, cluster: Any) -> None:
    """Close the sweep's client and the cluster it started (None: nothing to close)."""
    with contextlib.suppress(Exception):
        if client is not None:
            client.close()
    with contextlib.suppress(Exception):
        if cluster is not None:
            cluster.close()


@contextlib.contextmanager
def _no_interrupts() -> Iterator[None]:
    """Within the block, Ctrl-C (SIGINT) is ignored (in the main thread; elsewhere as is)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _killed_worker(error: BaseException) -> bool:
    """Whether a task's error is Dask's "lost with the workers that ran it"."""
    from distributed.scheduler import KilledWorker

    return isinstance(error, KilledWorker)


def _outcomes(client: Any, jobs: Sequence[tuple[int, list[str], Path]], futures: Sequence[Any],
              again: Callable[..., Any] | None, outcomes: list[tuple[str, dict, str] | None]) -> None:
    """Fill in each job's outcome, once every task is done, in job order.

    A task lost with its worker (KilledWorker and the like) is a failed sample when it had
    started (`lost_outcome`: its run folder completed, the error naming how its process
    died); one that never started (lost with a worker that died running another) is
    submitted again, as `again`, if given (a cluster of the sweep's own), else failed.

    The finished tasks' results come in one gather, after the last: fetched one future at a
    time, each was a round trip through the scheduler, in the client's process (~1 ms of CPU
    each) while the other samples still ran on the cores it shares with the workers.
    """
    from distributed import wait

    pending = list(enumerate(futures))
    for _ in range(len(jobs) + 1):  # each round again follows a sample that killed a worker
        # `wait` goes through the current client: through another one the caller holds (as
        # bench_sweep does) it returned ~2 s after the last task
        with client.as_current():
            wait([future for _, future in pending])
        finished = [future for _, future in pending if future.status == "finished"]
        results = dict(zip((f.key for f in finished), client.gather(finished)))
        retry = []
        for position, future in pending:
            index, _, run_dir = jobs[position]
            if future.key in results:
                outcomes[position] = results[future.key]
                continue
            try:
                outcomes[position] = future.result()
                continue
            except KeyboardInterrupt:
                raise
            except BaseException as exc:  # noqa: BLE001 - the worker died, not the run
                lost = exc
            outcome = lost_outcome(index, run_dir)
            if outcome is None and again is not None and _killed_worker(lost):
                retry.append(position)  # never started: it runs on another worker
                continue
            outcomes[position] = outcome or (
                "failed", {}, f"sample {index}: task lost: {type(lost).__name__}: {lost}")
        if not retry:
            return
        again_jobs = [jobs[position] for position in retry]
        pending = list(zip(retry, client.map(again, *zip(*again_jobs), pure=False)))
    for position, future in pending:  # not reached: a worker died in every round
        outcomes[position] = ("failed", {}, f"sample {jobs[position][0]}: task lost again and again")


def _metric_names(samples: Sequence[SampleResult]) -> list[str]:
    """Every metric some sample has, in table order."""
    from cosim.analysis.metrics import ordered_metric_names

    return ordered_metric_names(set().union(*(s.metrics for s in samples)) if samples else set())


def summarize_samples(samples: Sequence[SampleResult]) -> dict[str, dict[str, float]]:
    """Per metric, the distribution summary over the finished samples (finite values)."""
    summary = {}
    for name in _metric_names(samples):
        values = [s.metrics[name] for s in samples
                  if s.status == "ok" and name in s.metrics and np.isfinite(s.metrics[name])]
        if values:
            summary[name] = summarize(values)
    return summary


def _samples_csv(varies: Sequence[Vary], samples: Sequence[SampleResult]) -> str:
    names = _metric_names(samples)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["sample", *(v.path for v in varies), "status", *names, "error"])
    for s in samples:
        writer.writerow([s.index, *(repr(x) for x in s.values), s.status,
                         *(repr(s.metrics[n]) if n in s.metrics else "" for n in names), s.error])
    return out.getvalue()


def _summary_tables(summary: dict[str, dict[str, float]]) -> tuple[str, str]:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["metric", *STATS])
    md = ["| metric | " + " | ".join(STATS) + " |", "|---|" + "---:|" * len(STATS)]
    for name, stats in summary.items():
        writer.writerow([name, *(repr(stats[k]) for k in STATS)])
        md.append(f"| {name} | {int(stats['n'])} | "
                  + " | ".join(f"{stats[k]:.4g}" for k in STATS[1:]) + " |")
    return out.getvalue(), "\n".join(md) + "\n"


def write_sweep_files(result: SweepResult, settings: dict[str, Any]) -> list[Path]:
    """Write samples.csv, summary.csv, summary.md and sweep.json into result.out_dir."""
    out = result.out_dir
    summary_csv, summary_md = _summary_tables(result.summary)
    files = {"samples.csv": _samples_csv(result.varies, result.samples),
             "summary.csv": summary_csv, "summary.md": summary_md,
             "sweep.json": json.dumps(settings, indent=2) + "\n"}
    for name, text in files.items():
        try:
            (out / name).write_text(text)
        except OSError as exc:
            raise write_failure(out / name, exc) from None
    return [out / name for name in files]


class SweepInterrupted(Exception):
    """Ctrl-C during a sweep: `result` holds every sample (those that did not finish are
    "interrupted"), its index files written; `finished` counts the samples that ran to
    their end (ok or failed)."""

    def __init__(self, result: SweepResult, finished: int) -> None:
        self.result = result
        self.finished = finished
        super().__init__(f"sweep interrupted after {finished} of {len(result.samples)} samples; "
                         f"finished ones indexed in {result.out_dir}")


def _sweep_json(out: Path, settings: dict[str, Any]) -> None:
    """Write sweep.json (settings and status) into the sweep's folder."""
    try:
        (out / "sweep.json").write_text(json.dumps(settings, indent=2) + "\n")
    except OSError as exc:
        raise write_failure(out / "sweep.json", exc) from None


def run_sweep(scenario_path: str | Path, varies: Sequence[str | Vary], samples: int,
              seed: int = 0, scheduler: str | None = None, out_dir: str | Path = "sweep",
              transport: str = "inproc", method: str = "lhs",
              run_fn: RunFunction | None = None,
              cluster_options: dict[str, Any] | None = None,
              sets: Sequence[str] = (), force: bool = False) -> SweepResult:
    """Run a Monte-Carlo sweep of a scenario on Dask (see the module docstring).

    Args:
        scenario_path: the scenario YAML.
        varies: "PATH=LOW:HIGH" strings (or Vary), at least one, paths distinct.
        samples: number of sampled runs.
        seed: sampling seed.
        scheduler: address of a Dask scheduler ("tcp://host:8786"); None: a LocalCluster.
        out_dir: the sweep's output folder (created, with its missing parents).
        transport: transport of each run ("inproc" or "zenoh").
        method: "lhs" or "uniform".
        run_fn: (scenario_path, overrides, run_dir, transport) -> metrics; default
            `run_scenario_sample`. Must be picklable for process workers.
        cluster_options: extra LocalCluster keyword arguments (e.g. processes=False).
        sets: fixed "PATH=VALUE" overrides applied to every sample before the varied ones.
        force: replace an earlier sweep's folder at out_dir (else out_dir must be missing
            or empty).
    Raises:
        UserError: a bad argument (range, count 1..MAX_SAMPLES, seed, method, transport,
            scheduler address, an output folder that is not empty or cannot be made), before
            any sample runs; an invalid sample (see SampleCheck); a scheduler that cannot be
            reached.
        SweepInterrupted: Ctrl-C; the index files are written (see the module docstring).
    """
    from cosim.errors import UserError
    from cosim.execution.run import check_run_options

    parsed = [v if isinstance(v, Vary) else parse_vary(v) for v in varies]
    if not parsed:
        raise AnalysisError("sweep: give at least one --vary PATH=LOW:HIGH")
    paths = [v.path for v in parsed]
    if len(set(paths)) != len(paths):
        raise AnalysisError(f"sweep: a path is varied twice: {paths}")
    scenario_path = Path(scenario_path).resolve()
    if not scenario_path.is_file():
        raise AnalysisError(f"{scenario_path}: scenario file not found")
    check_run_options(transport, None)  # else every sample would fail on it, on the cluster
    if scheduler is not None:
        check_scheduler(scheduler)
    check_samples_count(samples)
    replace = check_sweep_out(out_dir, force)
    points = sample_points(parsed, samples, seed, method)
    if replace:
        empty_folder(Path(out_dir))
    out = make_folder(out_dir)
    make_folder(out / "samples")
    settings = {"scenario": str(scenario_path), "varies": [v.__dict__ for v in parsed],
                "sets": list(sets), "samples": samples, "seed": seed, "method": method,
                "transport": transport, "scheduler": scheduler}
    _sweep_json(out, {**settings, "status": "running"})  # an earlier sweep's, for --force
    jobs = [(i, list(sets) + [format_override(v.path, x) for v, x in zip(parsed, row)],
             (out / "samples" / f"sample_{i:04d}").resolve()) for i, row in enumerate(points)]
    roots = import_roots(scenario_path)
    check = None
    if run_fn is None:  # real runs: refuse a bad scenario or sample before the first one
        # joining a running cluster, nothing is saved by checking a sample here first
        check = SampleCheck(scenario_path, [overrides for _, overrides, _ in jobs], roots,
                            local=0 if scheduler else 1)
        # the worker processes of a cluster of our own run this sweep's samples and no more
        # (threads of this process, processes=False, or a joined cluster's: they may run again)
        own_processes = scheduler is None and (cluster_options or {}).get("processes", True)
        run_fn = partial(run_scenario_sample, runs_in_process=samples if own_processes else None)
    task = partial(_run_task, run_fn, scenario_path, transport, roots)
    interrupted = False
    try:
        outcomes = execute_samples(task, jobs, scheduler, cluster_options, check)
    except SamplesInterrupted as stop:
        interrupted = True
        outcomes = [outcome or ("interrupted", {}, f"sample {i}: not run (the sweep was interrupted)")
                    for i, outcome in enumerate(stop.outcomes)]
    except UserError as exc:  # refused (an invalid sample) or no cluster: nothing ran
        _sweep_json(out, {**settings, "status": "refused", "error": str(exc)})
        raise
    results = [SampleResult(i, [float(x) for x in row], status, metrics, error)
               for (i, row), (status, metrics, error) in zip(enumerate(points), outcomes)]
    result = SweepResult(parsed, results, summarize_samples(results), out, [])
    settings["failed"] = sum(s.status == "failed" for s in results)
    if interrupted:
        settings["interrupted"] = sum(s.status == "interrupted" for s in results)
    settings["status"] = "interrupted" if interrupted else "finished"
    result.files = write_sweep_files(result, settings)
    if interrupted:
        raise SweepInterrupted(result, sum(s.status in ("ok", "failed") for s in results))
    return result
