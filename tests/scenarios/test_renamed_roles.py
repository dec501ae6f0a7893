"""lane_change with its components renamed (`metrics:` naming them) gives the original's
signals, metrics and figure exactly: metrics and figures read by role, not by name."""

from __future__ import annotations

import copy

import pytest
import yaml

import cosim
from cosim.analysis.metrics import METRIC_NAMES
from cosim.figures.layouts import draw_figures
from cosim.scenario.shipped import resolve_scenario

RENAME = {"vehicle": "car", "controller": "ctl", "planner": "plan"}


def _endpoint(text: str) -> str:
    component, dot, port = text.strip().partition(".")
    return RENAME.get(component, component) + dot + port


def renamed(document: dict) -> dict:
    """The scenario with its vehicle, controller and planner renamed, and `metrics:` naming them."""
    doc = copy.deepcopy(document)
    doc["components"] = {RENAME.get(n, n): spec for n, spec in doc["components"].items()}
    connections = []
    for item in doc["connections"]:
        src, dst = item.split("->")
        connections.append(f"{_endpoint(src)} -> {_endpoint(dst)}")
    doc["connections"] = connections
    doc["metrics"] = {**doc.get("metrics", {}), **RENAME}
    return doc


def _renamed_column(name: str) -> str:
    component, dot, rest = name.partition(".")
    return RENAME.get(component, component) + dot + rest if dot else name


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    document = yaml.safe_load(resolve_scenario("lane_change").read_text())
    assert set(RENAME) <= set(document["components"])
    runs = {}
    for kind, doc in (("original", document), ("renamed", renamed(document))):
        run = cosim.run(doc, out=tmp_path_factory.mktemp(kind) / "run")  # same folder name: same legends
        assert run.status == "ok", run.error
        runs[kind] = run
    return runs["original"], runs["renamed"]


def test_renamed_components_record_the_same_signals(both):
    original, renamed_run = both
    expected = original.signals.rename(columns=_renamed_column)
    assert list(renamed_run.signals.columns) == list(expected.columns)
    assert renamed_run.signals.equals(expected)


def test_renamed_components_give_the_same_metrics_exactly(both):
    original, renamed_run = both
    platform = {k: v for k, v in original.metrics.items() if k in METRIC_NAMES}
    assert {"rms_yc", "max_abs_yc", "rms_ex", "max_abs_delta_rate", "max_abs_ay",
            "mu_true_final", "mu_hat_final"} <= set(platform)
    assert renamed_run.metrics == {_renamed_column(k): v for k, v in original.metrics.items()}
    # every metric computed, in both: no note on a signal that was not found
    assert not (original.path / "metrics_notes.txt").exists()
    assert not (renamed_run.path / "metrics_notes.txt").exists()


def test_renamed_components_draw_the_same_figure(both):
    original, renamed_run = both
    first, second = draw_figures(original.path), draw_figures(renamed_run.path)
    assert [p.name for p in first] == [p.name for p in second] == ["figure_manoeuvre.png"]
    assert first[0].read_bytes() == second[0].read_bytes()
