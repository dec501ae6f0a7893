"""The closing summary of `cosim run`: run table and metrics table."""

from __future__ import annotations

from pathlib import Path

from rich.console import Console

from cosim.analysis.metrics import METRIC_NAMES
from cosim.execution.run import RunResult
from cosim.cli.summary import METRIC_INFO, format_value, metric_rows, print_summary


def test_every_metric_of_cosim_metrics_has_a_unit_and_meaning_in_its_order():
    assert list(METRIC_INFO) == sorted(METRIC_NAMES, key=list(METRIC_INFO).index)
    assert set(METRIC_INFO) == set(METRIC_NAMES)


def test_format_value():
    assert format_value(3) == "3"
    assert format_value(4501.0) == "4501"
    assert format_value(0.0034863380946407495) == "0.003486"
    assert format_value(1.8385149159646166) == "1.839"
    assert format_value(float("nan")) == "nan"
    assert format_value("n/a") == "n/a"


def test_metric_rows_known_first_in_canonical_order_then_component_metrics():
    metrics = {"controller.steps": 51.0, "mu_hat_final": 0.8953505735434943,
               "rms_ex": 0.023057135773015932, "max_abs_yc": 0.013461630748348052,
               "zeta": 2.5}
    assert metric_rows(metrics) == [
        ("max_abs_yc", "0.01346", "m", "lateral error at the CG, yL - ls psiL (paper, Fig. 4.7)"),
        ("rms_ex", "0.02306", "m/s", "speed error vx - vx_ref"),
        ("mu_hat_final", "0.8954", "1", "friction estimate at the end"),
        ("controller.steps", "51", "", "reported by controller"),
        ("zeta", "2.5", "", ""),
    ]


def test_signal_statistics_come_by_signal_with_the_signals_unit():
    metrics = {"max(ball.v)": 4.0, "ball.state_events": 6.0, "min(ball.h)": 0.0,
               "final(ball.h)": 0.5, "min(ball.v)": -4.5}
    assert metric_rows(metrics, {"ball.h": "m", "ball.v": "m/s"}) == [
        ("min(ball.h)", "0", "m", "smallest value of ball.h"),
        ("final(ball.h)", "0.5", "m", "value at the last tick of ball.h"),
        ("min(ball.v)", "-4.5", "m/s", "smallest value of ball.v"),
        ("max(ball.v)", "4", "m/s", "largest value of ball.v"),
        ("ball.state_events", "6", "", "reported by ball"),
    ]


def test_print_summary_shows_both_tables(tmp_path: Path):
    result = RunResult(tmp_path, "ok", None, 4500, 45.0, 2.25, 20.0,
                       {"rms_yc": 0.0034863380946407495, "controller.steps": 4501.0},
                       {"factor": 1.0, "deadline_misses": 2}, 0.9345, {"origin": "process start"},
                       loop_time_s=1.25, lockstep_cpu=1)
    console = Console(record=True, width=100)
    print_summary(result, console)
    text = console.export_text()
    lines = [" ".join(line.replace("│", " ").split()) for line in text.splitlines()]
    assert lines[0] == "run ok"
    for expected in (f"folder {tmp_path}", "ticks 4500", "sim time 45 s", "wall time 2.25 s",
                     "real-time factor 20",
                     "time to tick 0 0.934 s", "loop time (ticks 1..N) 1.25 s", "loop real-time factor 36",
                     "lockstep CPU 1",
                     "realtime.factor 1", "realtime.deadline_misses 2",
                     "rms_yc 0.003486 m lateral error at the CG, yL - ls psiL (paper, Fig. 4.7)",
                     "controller.steps 4501 reported by controller"):
        assert expected in lines, (expected, text)
    assert lines.index("ticks 4500") < lines.index("metrics") < lines.index(
        "rms_yc 0.003486 m lateral error at the CG, yL - ls psiL (paper, Fig. 4.7)")
