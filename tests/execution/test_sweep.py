"""Monte-Carlo sweeps: sampling, override formatting, aggregation, and the Dask path."""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
import yaml

from cosim.analysis.rundata import AnalysisError
from cosim.execution.sweep import (Vary, format_override, parse_vary, run_sweep, sample_points,
                         summarize, summarize_samples)
from tests.helpers.paths import SCENARIOS_DIR

VARIES = [Vary("components.vehicle.uncertainty.m.scale", 0.7, 1.3),
          Vary("components.vehicle.parameters.mu", 0.3, 1.0),
          Vary("sources.wind.amplitude", -500.0, 500.0)]


def test_parse_vary_and_its_errors():
    assert parse_vary("a.b.c=-1.5:2e3") == Vary("a.b.c", -1.5, 2000.0)
    for text, message in [("a.b", "expected PATH=LOW:HIGH"), ("a=1", "expected PATH=LOW:HIGH"),
                          ("a=x:2", "must be numbers"), ("a=2:1", "LOW 2 is above HIGH 1"),
                          ("a=1:inf", "must be finite"), ("=1:2", "expected PATH=LOW:HIGH")]:
        with pytest.raises(AnalysisError, match=message):
            parse_vary(text)


@pytest.mark.parametrize("method", ["lhs", "uniform"])
def test_sampling_is_deterministic_and_within_bounds(method):
    a = sample_points(VARIES, 50, seed=7, method=method)
    assert a.shape == (50, 3)
    np.testing.assert_array_equal(a, sample_points(VARIES, 50, seed=7, method=method))
    assert not np.array_equal(a, sample_points(VARIES, 50, seed=8, method=method))
    for j, v in enumerate(VARIES):
        assert np.all((a[:, j] >= v.low) & (a[:, j] <= v.high))


def test_latin_hypercube_puts_one_point_in_each_stratum():
    n = 40
    points = sample_points(VARIES, n, seed=3)
    for j, v in enumerate(VARIES):
        strata = np.floor((points[:, j] - v.low) / (v.high - v.low) * n).astype(int)
        assert sorted(strata.tolist()) == list(range(n))


def test_sampling_errors_and_constant_range():
    with pytest.raises(AnalysisError, match="--samples 0"):
        sample_points(VARIES, 0, seed=1)
    with pytest.raises(AnalysisError, match="--method 'sobol'"):
        sample_points(VARIES, 3, seed=1, method="sobol")
    const = sample_points([Vary("x", 2.5, 2.5)], 4, seed=1)
    assert const.ravel().tolist() == [2.5] * 4


@pytest.mark.parametrize("value", [1e-05, 0.1, 1.3, 1e20, -2.5e-07, 0.7000000000000001])
def test_override_value_reads_back_as_the_same_float_in_yaml(value):
    path, _, text = format_override("components.vehicle.parameters.m", value).partition("=")
    assert path == "components.vehicle.parameters.m"
    parsed = yaml.safe_load(text)
    assert isinstance(parsed, float) and parsed == value


def test_summary_statistics_exact():
    values = list(range(1, 102))  # 1..101
    s = summarize(values[::-1])
    assert s == {"n": 101.0, "mean": 51.0, "std": math.sqrt(101 * 102 / 12), "min": 1.0,
                 "p5": 6.0, "p50": 51.0, "p95": 96.0, "max": 101.0}
    assert summarize([4.0])["std"] == 0.0


def fake_run(scenario_path: Path, overrides, run_dir: Path, transport: str) -> dict[str, float]:
    """A cheap stand-in for a run: metrics are analytic functions of the overrides."""
    assert overrides[0] == "duration=1"
    values = {k: yaml.safe_load(v) for k, v in (o.split("=", 1) for o in overrides[1:])}
    scale = values["components.vehicle.uncertainty.m.scale"]
    if scale > 1.25:
        raise RuntimeError(f"diverged at scale {scale}")
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "marker.txt").write_text(transport)
    return {"rms_yc": 2.0 * scale, "max_abs_ex": values["components.vehicle.parameters.mu"],
            "controller.iterations": 3.0}


def _read_csv(path: Path) -> list[dict[str, str]]:
    with open(path) as f:
        return list(csv.DictReader(f))


def test_sweep_on_a_local_dask_cluster_aggregates_exactly(tmp_path):
    scenario = tmp_path / "s.yaml"
    scenario.write_text("name: s\n")
    varies = ["components.vehicle.uncertainty.m.scale=0.7:1.3",
              "components.vehicle.parameters.mu=0.3:1.0"]
    options = {"processes": False, "n_workers": 1, "threads_per_worker": 1}
    result = run_sweep(scenario, varies, samples=12, seed=5, out_dir=tmp_path / "out",
                       run_fn=fake_run, cluster_options=options, sets=["duration=1"])
    points = sample_points([parse_vary(v) for v in varies], 12, 5)
    failed = points[:, 0] > 1.25
    assert failed.any() and not failed.all()
    assert [s.status for s in result.samples] == ["failed" if f else "ok" for f in failed]
    assert all("RuntimeError: diverged" in s.error for s in result.failures)
    ok = points[~failed]
    assert result.summary["rms_yc"] == summarize(2.0 * ok[:, 0])
    assert result.summary["max_abs_ex"] == summarize(ok[:, 1])
    rows = _read_csv(tmp_path / "out" / "samples.csv")
    assert [float(r["components.vehicle.uncertainty.m.scale"]) for r in rows] == points[:, 0].tolist()
    assert [r["rms_yc"] for r in rows] == ["" if f else repr(float(2.0 * x))
                                          for f, x in zip(failed, points[:, 0])]
    summary = {r["metric"]: r for r in _read_csv(tmp_path / "out" / "summary.csv")}
    assert float(summary["rms_yc"]["p95"]) == result.summary["rms_yc"]["p95"]
    assert int(float(summary["controller.iterations"]["n"])) == int((~failed).sum())
    assert (tmp_path / "out" / "samples" / "sample_0000" / "marker.txt").read_text() == "inproc"
    settings = json.loads((tmp_path / "out" / "sweep.json").read_text())
    assert settings["failed"] == int(failed.sum()) and settings["seed"] == 5
    assert settings["sets"] == ["duration=1"]

    again = run_sweep(scenario, varies, samples=12, seed=5, out_dir=tmp_path / "again",
                      run_fn=fake_run, cluster_options=options, sets=["duration=1"])
    for name in ("samples.csv", "summary.csv", "summary.md"):
        assert (tmp_path / "again" / name).read_bytes() == (tmp_path / "out" / name).read_bytes()
    assert again.summary == result.summary


def test_sweep_input_errors(tmp_path):
    scenario = tmp_path / "s.yaml"
    scenario.write_text("name: s\n")
    with pytest.raises(AnalysisError, match="at least one --vary"):
        run_sweep(scenario, [], 3, run_fn=fake_run, out_dir=tmp_path / "o")
    with pytest.raises(AnalysisError, match="varied twice"):
        run_sweep(scenario, ["a=0:1", "a=1:2"], 3, run_fn=fake_run, out_dir=tmp_path / "o")
    with pytest.raises(AnalysisError, match="scenario file not found"):
        run_sweep(tmp_path / "none.yaml", ["a=0:1"], 3, run_fn=fake_run, out_dir=tmp_path / "o")


def test_cli_sweep_reports_bad_vary_without_traceback(tmp_path):
    import typer
    from typer.testing import CliRunner

    from cosim.cli.analysis import register

    app = typer.Typer()
    register(app)
    scenario = tmp_path / "s.yaml"
    scenario.write_text("name: s\n")
    result = CliRunner().invoke(app, ["sweep", str(scenario), "--vary", "a=3:1", "--samples", "2",
                                      "--out", str(tmp_path / "o")])
    assert result.exit_code == 2
    assert "--vary 'a=3:1': LOW 3 is above HIGH 1" in result.output


SCENARIO = SCENARIOS_DIR / "satory_nominal.yaml"


@pytest.mark.integration
@pytest.mark.skipif(not SCENARIO.is_file(), reason="scenarios/satory_nominal.yaml not present")
def test_real_runs_through_the_default_run_function(tmp_path):
    from cosim.analysis.metrics import compute_metrics

    result = run_sweep(SCENARIO, ["components.vehicle.uncertainty.Iz.scale=0.9:1.1"], samples=2,
                       seed=2, out_dir=tmp_path / "out", sets=["duration=2"],
                       cluster_options={"processes": False, "n_workers": 1})
    assert [s.status for s in result.samples] == ["ok", "ok"], result.failures
    for sample in result.samples:
        run_dir = tmp_path / "out" / "samples" / f"sample_{sample.index:04d}"
        manifest = json.loads((run_dir / "manifest.json").read_text())
        assert manifest["scenario"]["duration"] == 2.0
        iz = manifest["scenario"]["components"]["vehicle"]["uncertainty"]["Iz"]["scale"]
        assert iz == sample.values[0]
        for name, value in compute_metrics(run_dir).items():
            assert sample.metrics[name] == value


def test_sweep_joins_an_existing_scheduler_by_address(tmp_path):
    from distributed import LocalCluster

    scenario = tmp_path / "s.yaml"
    scenario.write_text("name: s\n")
    varies = ["components.vehicle.uncertainty.m.scale=0.7:1.2",
              "components.vehicle.parameters.mu=0.3:1.0"]
    with LocalCluster(processes=False, n_workers=1, threads_per_worker=1,
                      dashboard_address=None) as cluster:
        result = run_sweep(scenario, varies, samples=3, seed=1, out_dir=tmp_path / "out",
                           scheduler=cluster.scheduler_address, run_fn=fake_run,
                           sets=["duration=1"])
        assert len(cluster.scheduler.workers) == 1  # the cluster outlives the sweep
    points = sample_points([parse_vary(v) for v in varies], 3, 1)
    assert [s.metrics["rms_yc"] for s in result.samples] == (2.0 * points[:, 0]).tolist()
    assert json.loads((tmp_path / "out" / "sweep.json").read_text())["scheduler"].startswith("inproc://")


def test_sweep_histograms_one_panel_per_metric(tmp_path):
    from cosim.figures.sweep import sweep_figure

    samples = {"rms_yc": [0.1, 0.2, 0.4], "max_abs_ex": [1.0, 2.0, 3.0], "cone_hits": [0, 1, 1],
               "mu_hat_final": [0.5, 0.6, 0.7], "max_abs_ay": [2.0, 2.5, 2.2]}
    summary = {name: summarize(values) for name, values in samples.items()}
    fig = sweep_figure(samples, summary, "sweep: 3 samples, 0 failed")
    assert fig.get_suptitle() == "sweep: 3 samples, 0 failed"
    visible = [ax for ax in fig.axes if ax.get_visible()]
    assert [ax.get_title() for ax in visible] == [f"{n} (n=3)" for n in samples]
    p95 = [line for line in visible[0].get_lines() if line.get_label() == "p95"][0]
    assert p95.get_xdata()[0] == summary["rms_yc"]["p95"]
    assert sum(patch.get_height() for patch in visible[2].patches) == 3


def _many_samples(name_length: int) -> dict[str, list[float]]:
    """Three metrics of 120,000 samples (bins of ~2x10^4: counts labelled 20k) whose names
    are `name_length` characters long, separated by dots and underscores only."""
    stem = "controller.lateral_error_rms_over_the_whole_manoeuvre_in_metres"
    values = np.random.default_rng(3).normal(size=120_000).tolist()
    return {f"{i}{stem}"[:name_length]: values for i in range(3)}


def _sweep_figure_boxes(samples):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from cosim.figures.sweep import sweep_figure

    summary = {name: summarize(values) for name, values in samples.items()}
    fig = sweep_figure(samples, summary)
    renderer = FigureCanvasAgg(fig).get_renderer()
    title = fig.get_suptitle() and fig._suptitle.get_window_extent(renderer)
    return fig, [title] + [ax.get_tightbbox(renderer) for ax in fig.axes if ax.get_visible()]


@pytest.mark.parametrize("panels", [1, 3, 5, 15])
def test_sweep_histogram_panels_and_their_labels_neither_overlap_nor_leave_the_figure(panels):
    samples = {f"controller.metric_{i}_rms": [10.0 ** (i % 7 - 3) * v for v in (-1.5, 0.2, 2.5)]
               for i in range(panels)}
    fig, boxes = _sweep_figure_boxes(samples)
    _assert_inside_and_apart(fig, boxes, panels)


def test_a_title_wraps_after_separators_and_cuts_a_part_longer_than_a_line():
    from cosim.figures.sweep import wrapped_title

    assert wrapped_title("controller.rms_yc (n=3)") == "controller.rms_yc (n=3)"
    assert wrapped_title("planner.lateral_offset_max", width=12) == "planner.\nlateral_\noffset_max"
    assert wrapped_title("x" * 30 + ".rms", width=12) == "x" * 12 + "\n" + "x" * 12 + "\n" + "x" * 6 + ".rms"


@pytest.mark.parametrize("name_length", [12, 41, 64])
def test_large_counts_and_long_metric_names_stay_inside_their_panels(name_length):
    fig, boxes = _sweep_figure_boxes(_many_samples(name_length))
    _assert_inside_and_apart(fig, boxes, 3)
    counts = [label.get_text() for label in fig.axes[0].get_yticklabels()]
    assert "0" in counts and "10k" in counts, counts
    titles = [ax.get_title() for ax in fig.axes if ax.get_visible()]
    assert all("".join(t.split("\n")).startswith(n) for t, n in zip(titles, _many_samples(name_length)))


def _assert_inside_and_apart(fig, boxes, panels):
    page = fig.bbox
    assert len(boxes) == 1 + panels  # the figure's title, then the panels
    for box in boxes:
        assert page.x0 <= box.x0 and box.x1 <= page.x1 and page.y0 <= box.y0 and box.y1 <= page.y1
    for i, first in enumerate(boxes):
        for second in boxes[i + 1:]:
            assert not first.overlaps(second)


def test_sweep_summary_prints_failures_verbatim(tmp_path, capsys):
    from cosim.cli.analysis import _print_summary
    from cosim.execution.sweep import SampleResult, SweepResult

    error = "sample 1: ComponentFailure: output 'ref_x' = [nan 1.0] at omega[fl]"
    samples = [SampleResult(0, [1.0], "ok", {"rms_yc": 0.5}), SampleResult(1, [2.0], "failed", {}, error)]
    result = SweepResult([parse_vary("a=0:3")], samples, summarize_samples(samples), tmp_path, [])
    _print_summary(result)
    out = capsys.readouterr().out
    assert f"failed: {error}\n" in out
    assert "sweep: 2 samples, 1 failed" in out


@pytest.mark.integration
@pytest.mark.skipif(not SCENARIO.is_file(), reason="scenarios/satory_nominal.yaml not present")
def test_samples_in_one_worker_give_the_runs_of_each_sample_alone(tmp_path):
    """Samples that follow each other in one worker (classes imported once, FMU cache and
    modules reused) give each sample's own run, signals and metrics bit for bit."""
    from cosim.execution.finish import analyse_run_folder
    from cosim.execution.run import run_scenario
    from cosim.scenario.loader import load_scenario

    vary = "components.controller.parameters.ke=3.0:5.0"
    result = run_sweep(SCENARIO, [vary], samples=3, seed=4, out_dir=tmp_path / "out",
                       sets=["duration=2"], cluster_options={"processes": False, "n_workers": 1})
    assert [s.status for s in result.samples] == ["ok"] * 3, result.failures
    for sample in result.samples:
        overrides = ["duration=2", f"components.controller.parameters.ke={sample.values[0]!r}"]
        alone = tmp_path / f"alone_{sample.index}"
        outcome = run_scenario(load_scenario(SCENARIO, overrides), out_dir=alone, progress=False)
        assert outcome.status == "ok"
        analyse_run_folder(outcome, figures=False)  # metrics.json as `cosim run` leaves it
        swept = tmp_path / "out" / "samples" / f"sample_{sample.index:04d}"
        assert (swept / "signals.csv").read_bytes() == (alone / "signals.csv").read_bytes()
        alone_metrics = json.loads((alone / "metrics.json").read_text())
        assert sample.metrics and set(sample.metrics) == set(alone_metrics)
        for name, value in sample.metrics.items():
            assert alone_metrics[name] == value


class _InlineClient:
    """A stand-in for a Dask client: `submit` runs the function now and records its items."""

    def __init__(self):
        self.submitted: list[list[list[str]]] = []

    def submit(self, function, *args, pure=True):
        self.submitted.append(args[-1])
        return function(*args)


def test_samples_after_the_first_are_validated_on_the_cluster_in_one_task_per_thread(tmp_path):
    from cosim.errors import UserError
    from cosim.execution.sweep import SampleCheck
    from tests.helpers.components import GOOD

    scenario = tmp_path / "gain.yaml"
    scenario.write_text(GOOD)
    samples = [["duration=0.5"], ["duration=0.505"], ["duration=0.3"], ["duration=0.2"]]
    check = SampleCheck(scenario, samples, ())  # the first is valid: nothing raised yet
    client = _InlineClient()
    found = check.submit(client, threads=2)
    assert client.submitted == [[samples[1], samples[3]], [samples[2]]]
    with pytest.raises(UserError) as refused:
        check.refuse(found)
    lines = str(refused.value).splitlines()
    assert lines[0] == f"{scenario}: sweep refused before its first run: 1 of 4 samples are invalid:"
    assert lines[1].startswith("sample 1 (duration=0.505): ") and len(lines) == 2
    assert "whole number of ticks" in lines[1]
    # a first sample that is invalid: refused at once, every sample checked here
    with pytest.raises(UserError, match="2 of 3 samples are invalid"):
        SampleCheck(scenario, [samples[1], samples[0], ["duration=0.111"]], ())
    valid = SampleCheck(scenario, samples[:1] + samples[2:], ())
    valid.refuse(valid.submit(_InlineClient(), threads=8))  # all valid: no error
    # joining a running cluster: every sample is checked there, none here
    remote = SampleCheck(scenario, samples, (), local=0)
    client = _InlineClient()
    with pytest.raises(UserError, match="1 of 4 samples are invalid:\nsample 1 "):
        remote.refuse(remote.submit(client, threads=3))
    assert client.submitted == [[samples[0], samples[3]], [samples[1]], [samples[2]]]


@pytest.mark.parametrize("count", [1, 2, 3, 7])
def test_chunks_deal_every_index_once(count):
    from cosim.execution.sweep import chunks

    dealt = chunks(list("abcde"), count)
    assert sorted(i for chunk in dealt for i in chunk) == list(range(5))
    assert len(dealt) == min(count, 5) and all(dealt)
    assert max(map(len, dealt)) - min(map(len, dealt)) <= 1
    assert chunks([], count) == []


PICKY = """\
from cosim.component import Component, ComponentError, Port


class Picky(Component):
    inputs = (Port("x"),)
    outputs = (Port("y"),)

    def __init__(self, k):
        if k > 2.0:
            raise ComponentError(f"k = {k} is above 2")
        self.k = k

    def step(self, t, inputs):
        return {"y": self.k * inputs["x"]}
"""


def test_an_invalid_sample_on_the_cluster_stops_every_run(tmp_path):
    """The runs wait, on the cluster, for the workers' validation: one sample invalid there,
    and no sample runs."""
    from distributed import LocalCluster

    from cosim.errors import UserError
    from tests.helpers.components import GOOD

    (tmp_path / "picky_gain.py").write_text(PICKY)
    scenario = tmp_path / "picky.yaml"
    scenario.write_text(GOOD.replace("tests.helpers.components:Gain", "picky_gain:Picky"))
    points = sample_points([parse_vary("components.gain.parameters.k=0:3")], 3, seed=1)[:, 0]
    invalid = [i for i, k in enumerate(points) if k > 2.0]
    assert len(invalid) == 1  # one point per third of the range
    with LocalCluster(processes=False, n_workers=2, threads_per_worker=1,
                      dashboard_address=None) as cluster:
        with pytest.raises(UserError, match=f"1 of 3 samples are invalid:\\nsample {invalid[0]} "):
            run_sweep(scenario, ["components.gain.parameters.k=0:3"], 3, seed=1,
                      scheduler=cluster.scheduler_address, out_dir=tmp_path / "out")
    assert not list((tmp_path / "out" / "samples").iterdir())


def test_the_cluster_a_sweep_starts_slows_dask_periodic_work():
    """The scheduler and the workers of `local_cluster` tick every second, not every 20 ms
    (CPU the client's process would take from busy workers), and its worker processes do not
    profile their tasks; Dask's own defaults are untouched."""
    import dask
    from distributed import Client

    from cosim.execution.sweep import local_cluster

    def profiling() -> bool:
        return dask.config.get("distributed.worker.profile.enabled")

    with local_cluster(1, processes=False) as cluster:
        assert cluster.scheduler._tick_interval == 1.0
        assert [w._tick_interval for w in cluster.workers.values()] == [1.0]
    with local_cluster(1) as cluster, Client(cluster) as client:  # a worker process
        assert list(client.run(profiling).values()) == [False]
    assert dask.config.get("distributed.admin.tick.interval") == "20ms" and profiling()


def test_a_sweeps_client_and_cluster_batch_their_messages_every_millisecond():
    """The client a sweep makes and the scheduler of the cluster it starts send their
    batches to the scheduler and to the workers at most 1 ms apart (Dask's fixed 10 and
    5 ms held a sweep's tasks back); clients and clusters made otherwise keep Dask's."""
    from distributed import Client

    from cosim.execution.sweep import local_cluster, prompt_client

    with local_cluster(2, processes=False) as cluster:
        assert {c.interval for c in cluster.scheduler.stream_comms.values()} == {0.001}
        with prompt_client(cluster) as client:
            assert client.scheduler_comm.interval == 0.001
            assert client.submit(sum, [1, 2], pure=False).result() == 3
        with Client(cluster) as client:
            assert client.scheduler_comm.interval == 0.01


def _done_or_lost(index, overrides, run_dir):
    """A run task whose sample 1 is lost (its task raises, as with a dead worker)."""
    if index == 1:
        raise RuntimeError("worker gone")
    return "ok", {"x": float(index)}, ""


def test_finished_samples_come_back_in_one_gather_and_a_lost_one_fails(tmp_path, monkeypatch):
    """The results of the finished tasks are fetched together once all are done (not one
    round trip per sample); a task that did not finish is a failed sample, in job order."""
    from distributed import Client

    from cosim.execution.sweep import execute_samples

    gathered = []
    real_gather = Client.gather

    def gather(self, futures, *args, **kwargs):
        gathered.append(len(futures))
        return real_gather(self, futures, *args, **kwargs)

    monkeypatch.setattr(Client, "gather", gather)
    jobs = [(i, [], tmp_path / f"s{i}") for i in range(4)]
    outcomes = execute_samples(_done_or_lost, jobs, None, {"processes": False, "n_workers": 1})
    assert outcomes == [("ok", {"x": 0.0}, ""),
                        ("failed", {}, "sample 1: task lost: RuntimeError: worker gone"),
                        ("ok", {"x": 2.0}, ""), ("ok", {"x": 3.0}, "")]
    assert gathered == [3]


def test_the_samples_are_awaited_through_the_sweeps_own_client(tmp_path, monkeypatch):
    """`distributed.wait` uses the current client: with one of the caller's open (made
    after the sweep's cluster, so the default), the sweep still waits through its own
    (through the caller's, the wait ended ~2 s after the last task, on a tick)."""
    import distributed
    from distributed import Client, default_client

    from cosim.execution.sweep import execute_samples, local_cluster

    waited_with = []
    real_wait = distributed.wait

    def wait(futures, *args, **kwargs):
        waited_with.append((default_client(), {f.client for f in futures}))
        return real_wait(futures, *args, **kwargs)

    monkeypatch.setattr(distributed, "wait", wait)
    jobs = [(i, [], tmp_path / f"s{i}") for i in (0, 2)]
    with local_cluster(1, processes=False) as cluster, Client(cluster) as callers:
        outcomes = execute_samples(_done_or_lost, jobs, cluster.scheduler_address, None)
        [(current, owners)] = waited_with
        assert current is not callers and owners == {current}
    assert outcomes == [("ok", {"x": 0.0}, ""), ("ok", {"x": 2.0}, "")]


ALLOWED_CPUS = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []


@pytest.mark.skipif(len(ALLOWED_CPUS) < 2, reason="needs Linux and two CPUs this process may use")
def test_each_worker_process_of_a_sweeps_cluster_runs_on_its_own_cpu():
    from distributed import Client

    from cosim.execution.sweep import local_cluster

    def cpus() -> list[int]:
        import threading
        return sorted(os.sched_getaffinity(threading.get_native_id()))

    with local_cluster(2) as cluster, Client(cluster) as client:
        by_worker = client.run(cpus)                         # the worker's own thread
        in_tasks = client.gather(client.map(lambda _: cpus(), range(6), pure=False))
    assert sorted(map(tuple, by_worker.values())) == [(ALLOWED_CPUS[0],), (ALLOWED_CPUS[1],)]
    assert {tuple(c) for c in in_tasks} <= {(ALLOWED_CPUS[0],), (ALLOWED_CPUS[1],)}
    assert sorted(os.sched_getaffinity(0)) == ALLOWED_CPUS  # the sweep's own process keeps them all


def test_a_cpu_per_worker_only_for_worker_processes_that_fit_the_cpus():
    from cosim.execution.worker_cpus import OwnCpu, worker_plugins

    assert worker_plugins(2, processes=False) == set()      # threads of this process: never
    assert worker_plugins(1, processes=True) == set()       # one worker: nothing to keep apart
    assert worker_plugins(len(ALLOWED_CPUS) + 1, processes=True) == set()
    if len(ALLOWED_CPUS) >= 2:
        (plugin,) = worker_plugins(2, processes=True)
        assert isinstance(plugin, OwnCpu) and plugin.cpus == ALLOWED_CPUS
