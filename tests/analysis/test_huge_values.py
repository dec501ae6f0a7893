"""Signals near the largest float (1.8e308), finite but whose squares, differences or
axis spans overflow: the metrics are computed or left out with a note naming them, the
figures are drawn with the axes clipped, and `cosim run`, `plot` and `compare` end
without a traceback."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cosim.analysis.metrics import analyse_run
from cosim.analysis.rundata import load_run
from cosim.analysis.stats import rms
from cosim.cli.app import main
from cosim.figures.layouts import build_figure, save_png
from cosim.figures.sweep import sweep_figure
from cosim.figures.thin import AXIS_LIMIT
from tests.helpers.synthetic_runs import lane_change_run, write_run

BIG = 1.7e308
HUGE_RAMP = """\
name: huge
duration: 0.5
tick: 0.01
components:
  gain:
    python: tests.helpers.components:Gain
    parameters: {k: 1.7e308}
sources:
  ramp: {kind: ramp, start: -1.0, end: 1.0, t_start: 0.0, t_end: 0.5}
connections:
  - {from: ramp.value, to: gain.x}
"""


@pytest.mark.parametrize("values, expected", [
    ([BIG, BIG, BIG], BIG),
    ([-BIG, BIG, -BIG], BIG),
    ([1e200, 1e200, 1e200], 1e200),
])
def test_rms_of_values_whose_squares_overflow(values, expected):
    assert rms(np.array([0.0, 1.0, 2.0]), np.array(values)) == expected


def test_a_metric_that_overflows_is_left_out_with_a_note_naming_it(tmp_path):
    t = np.arange(10) * 0.1
    delta = np.where(np.arange(10) % 2 == 0, BIG, -BIG)  # finite, its rate is not
    run = write_run(tmp_path / "run", t, {"controller.delta": delta},
                    {"name": "r", "tick": 0.1, "components": {"controller": {}}})
    report = analyse_run(load_run(run))
    assert report.values["max_abs_delta"] == BIG
    assert "max_abs_delta_rate" not in report.values
    assert ("max_abs_delta_rate: inf, not a finite number (the computation overflowed: "
            "signal values near the largest float); left out") in report.notes


def test_figures_of_huge_signals_are_drawn_with_the_axes_clipped(tmp_path):
    run = lane_change_run(tmp_path / "run")
    signals = (run / "signals.csv").read_text().splitlines()
    header = signals[0].split(",")
    yc = header.index("controller.yc")
    rows = [line.split(",") for line in signals[1:]]
    for k, row in enumerate(rows):
        row[yc] = repr(BIG if k % 2 else -BIG)
    (run / "signals.csv").write_text("\n".join([signals[0]] + [",".join(r) for r in rows]) + "\n")
    fig, layout = build_figure([load_run(run)], "track")
    save_png(fig, tmp_path / "track.png")
    panel = next(ax for ax in fig.axes if ax.get_title() == "lateral error at CG")
    assert panel.get_ylim() == (-AXIS_LIMIT, AXIS_LIMIT)
    assert [t.get_text() for t in panel.texts] == ["y beyond +-1e+300 not shown"]
    zoom = next(ax for ax in fig.axes if ax.get_title().startswith("zoom on tracking"))
    assert zoom.texts[0].get_text().startswith("|yc_cg| = 1.7e+308 m at x = ")
    assert zoom.texts[0].get_text().endswith("beyond what an axis can show")


def test_a_sweep_histogram_of_huge_values_says_so_instead(tmp_path):
    from cosim.execution.sweep import summarize

    samples = {"m": [BIG, -BIG, 1.0], "k": [1.0, 2.0, 3.0]}
    fig = sweep_figure(samples, {name: summarize(v) for name, v in samples.items()})
    save_png(fig, tmp_path / "h.png")
    assert fig.axes[0].texts[0].get_text() == "values beyond +-1e+300: no histogram\n(see summary.csv)"
    assert len(fig.axes[1].patches) == 3  # the other metric's bars


def test_run_plot_and_compare_of_a_huge_but_finite_run(tmp_path, capsys):
    scenario = tmp_path / "huge.yaml"
    scenario.write_text(HUGE_RAMP)
    runs = []
    for name in ("a", "b"):
        runs.append(tmp_path / name)
        assert main(["run", str(scenario), "--transport", "inproc", "--out", str(runs[-1])]) == 0
        captured = capsys.readouterr()
        assert "not computed" not in captured.out + captured.err
        assert "not drawn" not in captured.out + captured.err
    metrics = json.loads((runs[0] / "metrics.json").read_text())
    assert metrics["max(gain.y)"] == BIG and metrics["min(gain.y)"] == -BIG
    assert 0 < metrics["rms(gain.y)"] < BIG
    assert (runs[0] / "figure_signals.png").is_file()
    assert main(["plot", str(runs[0]), "--out", str(tmp_path / "big.png")]) == 0
    assert capsys.readouterr().out == f"figure: {tmp_path / 'big.png'}\n"
    assert main(["compare", *map(str, runs), "--out", str(tmp_path / "cmp")]) == 0
    captured = capsys.readouterr()
    assert "| rms(gain.y) |" in captured.out and captured.err == ""
