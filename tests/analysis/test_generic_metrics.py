"""A run that is not a vehicle run: the BouncingBall test FMU gets the statistics of its
signals (held against its recorded data and the analytic bounce) and a signals figure,
never vehicle metrics; `cosim plot --signals` and `Run.plot(signals=)` draw any signals."""

from __future__ import annotations

import json

import numpy as np
import pytest

import cosim
from cosim.analysis.generic import STATISTICS, statistic_name
from cosim.analysis.metrics import METRIC_NAMES, compute_metrics, write_metrics
from cosim.analysis.rundata import AnalysisError, load_run
from cosim.analysis.stats import rms
from cosim.cli.app import main
from cosim.figures.layouts import build_figure, draw_figures
from cosim.fmu import build as fmu_build
from tests.fmu.test_model_exchange_fmu import DEFAULTS, analytic
from tests.helpers.paths import TEST_FMUS_DIR
from tests.helpers.synthetic_runs import write_run

DURATION = 5.0
#: its outputs: the two continuous states, then the Integer and Boolean ones (recorded too)
BALL_SIGNALS = ["ball.h", "ball.v", "ball.bounces", "ball.resting", "ball.kicked"]
STATE_TOL = 1e-8     # m, m/s: the framework's RK4 with bisected events against the analytic ball


@pytest.fixture(scope="module")
def ball_run(tmp_path_factory) -> cosim.Run:
    """BouncingBall (co-simulation, FMI 2.0) alone for 5 s at 10 ms: the API's run and metrics."""
    folder = tmp_path_factory.mktemp("ball")
    fmu = fmu_build.build_fmu_from(TEST_FMUS_DIR / "BouncingBall", 2, folder)
    scenario = {"name": "ball", "duration": DURATION, "tick": 0.01,
                "components": {"ball": {"fmu": str(fmu)}}}
    run = cosim.run(scenario, out=folder / "run")
    assert run.status == "ok", run.error
    return run


def test_a_ball_gets_signal_statistics_and_no_vehicle_metric(ball_run):
    metrics = ball_run.metrics
    assert not set(metrics) & set(METRIC_NAMES)          # no mu_true_final = 1 from nowhere
    data = load_run(ball_run.path)
    assert list(data.columns) == BALL_SIGNALS
    for name, v in data.columns.items():
        assert metrics[statistic_name("min", name)] == np.min(v)
        assert metrics[statistic_name("max", name)] == np.max(v)
        assert metrics[statistic_name("rms", name)] == rms(data.time, v)
        assert metrics[statistic_name("final", name)] == v[-1]
    generic = {k for k in metrics if "(" in k}
    assert generic == {statistic_name(s, n) for s in STATISTICS for n in data.columns}
    notes = (ball_run.path / "metrics_notes.txt").read_text()
    assert "no vehicle, controller or planner" in notes


def test_the_statistics_are_those_of_the_analytic_bounce(ball_run):
    metrics = ball_run.metrics
    t = load_run(ball_run.path).time
    # (h, v) at every tick, just after it: the kick at 3 s is on a tick, and the FMU's
    # output there is the state after the event
    exact = np.array([analytic(float(tk) + 1e-12)[1][:2] for tk in t])
    h, v = exact[:, 0], exact[:, 1]
    assert metrics["max(ball.h)"] == DEFAULTS["h0"]            # dropped from h0: the first tick
    assert metrics["min(ball.h)"] == 0.0                       # lying on the floor from 2.05 s to 3 s
    assert metrics["max(ball.v)"] == DEFAULTS["v_kick"]        # the kick at 3 s, from rest
    # the fastest fall is the last tick before the first impact (0.4515 s): v = -g 0.45
    assert metrics["min(ball.v)"] == pytest.approx(-DEFAULTS["g"] * 0.45, abs=STATE_TOL)
    assert metrics["min(ball.v)"] == pytest.approx(np.min(v), abs=STATE_TOL)
    assert metrics["final(ball.h)"] == pytest.approx(h[-1], abs=STATE_TOL)
    assert metrics["final(ball.v)"] == pytest.approx(v[-1], abs=STATE_TOL)
    assert metrics["rms(ball.h)"] == pytest.approx(rms(t, h), abs=STATE_TOL)
    assert metrics["rms(ball.v)"] == pytest.approx(rms(t, v), abs=STATE_TOL)
    assert (metrics["min(ball.kicked)"], metrics["final(ball.kicked)"]) == (0.0, 1.0)  # at 3 s


def test_the_default_figure_of_a_ball_is_its_signals_with_units(ball_run, tmp_path):
    run = load_run(ball_run.path)
    fig, layout = build_figure([run])
    assert layout == "signals"
    axes = [ax for ax in fig.axes if ax.axison]
    assert [ax.get_ylabel() for ax in axes] == ["h (m)", "v (m/s)", "bounces", "resting",
                                                 "kicked"]
    for ax, name in zip(axes, BALL_SIGNALS, strict=True):
        (line,) = ax.get_lines()
        assert np.array_equal(line.get_xdata(), run.time)       # 500 ticks: drawn as they are
        assert np.array_equal(line.get_ydata(), run.columns[name])
    folder = tmp_path / "copy"
    folder.mkdir()
    for name in ("signals.csv", "manifest.json"):
        (folder / name).write_bytes((ball_run.path / name).read_bytes())
    assert draw_figures(folder) == [folder / "figure_signals.png"]
    assert not (folder / "figure_track.png").exists()


def test_cli_plot_signals_writes_the_png_it_prints(ball_run, tmp_path, capsys):
    out = tmp_path / "ball.png"
    assert main(["plot", str(ball_run.path), "--signals", "ball.*", "--out", str(out)]) == 0
    assert capsys.readouterr().out.strip() == f"figure: {out}"
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["plot", str(ball_run.path), "--signals", "*.v", "--signals", "ball.h"]) == 0
    assert capsys.readouterr().out.strip() == f"figure: {ball_run.path / 'figure_signals.png'}"


def test_cli_plot_pattern_matching_nothing_is_one_line_exit_2(ball_run, capsys):
    assert main(["plot", str(ball_run.path), "--signals", "ball.*", "--signals", "car.*"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"error: {ball_run.path}: signal pattern 'car.*' matches no recorded signal "
                   f"(recorded: {', '.join(BALL_SIGNALS)})")


def test_run_plot_signals_draws_the_chosen_signals_in_pattern_order(ball_run):
    fig = ball_run.plot(signals=["*.v", "ball.*"])
    assert [ax.get_title() for ax in fig.axes if ax.axison] == [
        "ball.v: vertical velocity (continuous state)", "ball.h: height (continuous state)",
        "ball.bounces: number of floor impacts", "ball.resting: the ball lies on the floor",
        "ball.kicked: the kick at t_kick has happened"]
    assert len(ball_run.plot(signals="ball.h").axes) == 1
    with pytest.raises(AnalysisError, match=r"'x\*' matches no recorded signal"):
        ball_run.plot(signals="x*")


def test_non_finite_signal_gets_no_statistics_and_a_note(tmp_path):
    t = np.arange(0, 101) * 0.01
    bad = np.sin(t)
    bad[40] = np.inf
    run = write_run(tmp_path / "r", t, {"lag.y": 1.0 - np.exp(-t), "lag.u": bad})
    report = write_metrics(run)
    assert "max(lag.u)" not in report.values and report.values["max(lag.y)"] == 1.0 - np.exp(-1.0)
    assert any("max(lag.u)" in n and "inf" in n and "t=0.4 s" in n for n in report.notes)


def test_skip_s_applies_to_the_statistics_but_final_is_the_last_tick(tmp_path):
    t = np.arange(0, 201) * 0.01
    run = write_run(tmp_path / "r", t, {"lag.y": np.where(t < 0.5, 9.0, t)},
                    {"name": "lag", "metrics": {"skip_s": 0.5}})
    m = compute_metrics(run)
    assert (m["min(lag.y)"], m["max(lag.y)"], m["final(lag.y)"]) == (0.5, 2.0, 2.0)


def test_a_plant_shaped_component_without_roles_is_named_in_the_note(tmp_path):
    t = np.arange(0, 11) * 0.1
    cols = {f"car.{s}": t for s in ("x", "y", "psi", "vx")}
    run = write_run(tmp_path / "r", t, cols, {"name": "car", "components": {"car": {"fmu": "Bicycle"}}})
    report = write_metrics(run)
    assert "mu_true_final" not in report.values and report.values["final(car.vx)"] == 1.0
    assert "`metrics: {vehicle: car}` makes it the vehicle" in report.notes[0]
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics == report.values


def test_rms_of_values_whose_squares_overflow_is_finite_and_exact_in_scale(recwarn):
    t = np.array([0.0, 1.0, 2.0])
    assert rms(t, np.full(3, 3e200)) == pytest.approx(3e200, rel=1e-15)
    assert rms(np.array([0.0]), np.array([-1e300])) == pytest.approx(1e300, rel=1e-15)
    assert rms(t, np.array([1e200, np.inf, 0.0])) == np.inf   # a non-finite input stays so
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
