"""Metrics and figures read by role: a run folder whose vehicle, controller and planner
are renamed (with `metrics:` naming them) gives the same metrics and the same figure
bytes, for a lane change and for vehicle following (the lead found through the
renamed planner's wiring)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from cosim.analysis.metrics import compute_metrics
from cosim.analysis.rundata import load_run
from cosim.figures.layouts import build_figure, draw_figures
from tests.helpers.synthetic_runs import lane_change_run, write_run

RENAME = {"vehicle": "car", "controller": "ctl", "planner": "plan"}


def _name(text: str) -> str:
    component, dot, rest = text.partition(".")
    return RENAME.get(component, component) + dot + rest


def renamed_copy(run_dir: Path, to: Path) -> Path:
    """The run folder with its components renamed: columns, arrays, scenario, connections."""
    shutil.copytree(run_dir, to)
    lines = (to / "signals.csv").read_text().split("\n")
    lines[0] = ",".join(_name(c) for c in lines[0].split(","))
    (to / "signals.csv").write_text("\n".join(lines))
    for path in sorted((to / "arrays").glob("*.csv")) if (to / "arrays").is_dir() else []:
        path.rename(path.with_name(_name(path.stem) + ".csv"))
    manifest = json.loads((to / "manifest.json").read_text())
    manifest["connections"] = [" -> ".join(_name(e.strip()) for e in c.split("->"))
                               for c in manifest.get("connections", [])]
    scenario = manifest["scenario"]
    scenario["components"] = {_name(n): s for n, s in scenario.get("components", {}).items()}
    scenario["metrics"] = {**scenario.get("metrics", {}), **RENAME}
    (to / "manifest.json").write_text(json.dumps(manifest))
    return to


def _following_run(path: Path) -> Path:
    """A follower closing on a lead at 2 m/s into a contact (gap 1 - 2 t: 1 m down to -3 m)."""
    t = np.arange(0, 201) * 0.01
    zeros = np.zeros_like(t)
    follower_x = 50.0 + 12.0 * t
    lead_x = follower_x + 4.5 + 1.0 - 2.0 * t
    columns = {"vehicle.x": follower_x, "vehicle.y": zeros, "vehicle.psi": zeros,
               "vehicle.vx": np.full_like(t, 12.0), "lead.x": lead_x, "lead.y": zeros,
               "lead.psi": zeros, "lead.vx": np.full_like(t, 10.0),
               "planner.gap": lead_x - follower_x - 4.5, "planner.gap_ref": np.full_like(t, 2.0),
               "controller.delta": 0.01 * np.sin(t), "controller.yL": 0.1 * np.cos(t)}
    return write_run(path, t, columns, {"name": "follow", "components": {
        "vehicle": {}, "controller": {}, "planner": {}, "lead": {}}},
        connections=["lead.x -> planner.lead_x", "vehicle -> planner"])


@pytest.mark.parametrize("make, layout", [(lane_change_run, "manoeuvre"),
                                          (_following_run, "following")])
def test_renamed_run_gives_the_same_metrics_and_figure(tmp_path, make, layout):
    original = make(tmp_path / "a" / "run")
    renamed = renamed_copy(original, tmp_path / "b" / "run")   # same folder name: same legends
    metrics = compute_metrics(original)
    assert len(metrics) >= 8
    assert compute_metrics(renamed) == metrics
    first, second = draw_figures(original), draw_figures(renamed)
    assert [p.name for p in first] == [p.name for p in second] == [f"figure_{layout}.png"]
    assert first[0].read_bytes() == second[0].read_bytes()


def test_following_metrics_come_through_the_renamed_planner(tmp_path):
    renamed = renamed_copy(_following_run(tmp_path / "a"), tmp_path / "b")
    m = compute_metrics(renamed)
    assert m["collisions"] == 1 and m["gap_overshoot"] == pytest.approx(2.0 + 3.0)  # gap_ref - min gap
    assert m["min_ttc"] == 0.0


def test_without_the_roles_the_renamed_run_is_not_a_vehicle_run(tmp_path):
    renamed = renamed_copy(lane_change_run(tmp_path / "a"), tmp_path / "b")
    manifest = json.loads((renamed / "manifest.json").read_text())
    for role in RENAME:
        del manifest["scenario"]["metrics"][role]
    (renamed / "manifest.json").write_text(json.dumps(manifest))
    run = load_run(renamed)
    assert run.roles == {"vehicle": None, "controller": None, "planner": None}
    m = compute_metrics(renamed)
    assert "mu_true_final" not in m and m["max(car.x)"] == 60.0
    assert build_figure([run])[1] == "signals"


def test_a_role_left_out_defaults_to_the_component_of_its_name(tmp_path):
    run_dir = lane_change_run(tmp_path / "a")
    manifest = json.loads((run_dir / "manifest.json").read_text())
    manifest["scenario"]["metrics"] = {"planner": "plan"}   # no such component: nothing to read
    (run_dir / "manifest.json").write_text(json.dumps(manifest))
    run = load_run(run_dir)
    assert run.roles == {"vehicle": "vehicle", "controller": "controller", "planner": "plan"}
    assert np.array_equal(run.role_signal("vehicle", "vx"), run.columns["vehicle.vx"])
    assert run.array(run.role_column("planner", "ref_x")) is None
