"""Metrics against synthetic run folders with analytic values."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from tests.helpers.synthetic_runs import write_run  # noqa: E402

from cosim.figures.compare import run_metrics  # noqa: E402
from cosim.analysis.metrics import compute_metrics, ordered_metric_names, rms, write_metrics  # noqa: E402
from cosim.analysis.cones import cone_hits, cones_inside  # noqa: E402
from cosim.analysis import rundata  # noqa: E402
from cosim.analysis.rundata import AnalysisError, load_run, read_csv_table  # noqa: E402

T = np.arange(0, 201) * 0.01  # 0..2 s inclusive: two whole periods of 1 Hz


def test_rms_of_sine_over_whole_periods_is_amplitude_over_sqrt2(tmp_path):
    a = 0.3
    yc = a * np.sin(2 * np.pi * T)
    run = write_run(tmp_path / "r", T, {"controller.yc": yc, "controller.yL": 2 * yc,
                                        "controller.psiL": np.cos(2 * np.pi * T)})
    m = compute_metrics(run)
    assert m["rms_yc"] == pytest.approx(a / math.sqrt(2), rel=1e-12)
    assert m["rms_yL"] == pytest.approx(2 * a / math.sqrt(2), rel=1e-12)
    assert m["rms_psiL"] == pytest.approx(1 / math.sqrt(2), rel=1e-12)
    assert m["max_abs_yc"] == pytest.approx(a, rel=1e-12)  # t = 0.25 s is on the grid
    assert m["max_abs_psiL"] == 1.0


def test_rms_single_sample_and_constant():
    assert rms(np.array([0.0]), np.array([-2.5])) == 2.5
    assert rms(np.array([1.0, 1.0]), np.array([3.0, -4.0])) == pytest.approx(math.sqrt(12.5))
    assert rms(np.array([0.0, 0.3, 1.0]), np.array([-2.0, -2.0, -2.0])) == pytest.approx(2.0)


def test_delta_ramp_gives_its_rate(tmp_path):
    delta = np.minimum(0.1 * T, 0.05) - 0.2 * np.maximum(T - 1.5, 0.0)
    run = write_run(tmp_path / "r", T, {"controller.delta": delta})
    m = compute_metrics(run)
    assert m["max_abs_delta_rate"] == pytest.approx(0.2, rel=1e-9)
    assert m["max_abs_delta"] == pytest.approx(abs(0.05 - 0.2 * 0.5), rel=1e-12)


def test_delta_rate_at_controller_period_ignores_hold_steps(tmp_path):
    # the controller runs every 5 ticks and holds delta = 0.1 t in between
    held = 0.1 * T[(np.arange(len(T)) // 5) * 5]
    scenario = {"tick": 0.01, "components": {"controller": {"period": 0.05}}}
    run = write_run(tmp_path / "r", T, {"controller.delta": held}, scenario)
    assert compute_metrics(run)["max_abs_delta_rate"] == pytest.approx(0.1, rel=1e-9)
    # read tick by tick, the same trace looks five times faster
    run2 = write_run(tmp_path / "r2", T, {"controller.delta": held})
    assert compute_metrics(run2)["max_abs_delta_rate"] == pytest.approx(0.5, rel=1e-9)


def test_speed_error_falls_back_to_vx_minus_reference(tmp_path):
    run = write_run(tmp_path / "r", T, {"vehicle.vx": np.full_like(T, 10.3),
                                        "controller.vx_ref": np.full_like(T, 10.0)})
    m = compute_metrics(run)
    assert m["rms_ex"] == pytest.approx(0.3, rel=1e-12)
    assert m["max_abs_ex"] == pytest.approx(0.3, rel=1e-12)


def test_yc_derived_from_yl_and_psil_with_scenario_ls(tmp_path):
    scenario = {"components": {"controller": {"parameters": {"ls": 4.0}}}}
    run = write_run(tmp_path / "r", T, {"controller.yL": np.full_like(T, 1.0),
                                        "controller.psiL": np.full_like(T, 0.1)}, scenario)
    assert compute_metrics(run)["max_abs_yc"] == pytest.approx(0.6, rel=1e-12)


def test_true_mu_follows_the_connection_to_its_source_column(tmp_path):
    mu = np.where(T < 1.0, 1.0, 0.5)
    cols = {"road_friction.value": mu, "controller.mu_hat": 0.9 - 0.1 * T}
    run = write_run(tmp_path / "r", T, cols,
                    {"components": {"vehicle": {"parameters": {"mu": 0.7}}}},
                    connections=["road_friction.value -> vehicle.mu",
                                 "controller.delta -> vehicle.delta"])
    m = compute_metrics(run)
    assert m["mu_true_final"] == 0.5
    assert m["mu_hat_final"] == pytest.approx(0.7)


def test_true_mu_follows_scenario_connections_and_short_forms(tmp_path):
    cols = {"friction.value": np.full_like(T, 0.4), "wet.mu": np.full_like(T, 0.6),
            "other.mu": np.full_like(T, 0.2)}
    explicit = [{"from": "wet", "to": "vehicle", "delay": 0},
                {"from": "friction.value", "to": "vehicle.mu", "delay": 0}]
    run = write_run(tmp_path / "a", T, cols, {"connections": explicit})
    assert compute_metrics(run)["mu_true_final"] == 0.4  # explicit beats the short form
    short = write_run(tmp_path / "b", T, cols, {"connections": ["wet -> vehicle"]})
    assert compute_metrics(short)["mu_true_final"] == 0.6
    single_output = write_run(tmp_path / "c", T, cols,
                              {"connections": [{"from": "friction", "to": "vehicle.mu"}]})
    assert compute_metrics(single_output)["mu_true_final"] == 0.4


def test_true_mu_unconnected_uses_vehicle_parameter_then_one(tmp_path):
    cols = {"vehicle.x": T}
    with_param = write_run(tmp_path / "a", T, cols,
                           {"components": {"vehicle": {"parameters": {"mu": 0.35}}}})
    assert compute_metrics(with_param)["mu_true_final"] == 0.35
    no_manifest_connections = write_run(tmp_path / "b", T, cols, {"name": "x"})
    assert compute_metrics(no_manifest_connections)["mu_true_final"] == 1.0


def test_skip_s_excludes_the_transient(tmp_path):
    yc = np.where(T < 0.5, 5.0, 0.1)
    run = write_run(tmp_path / "r", T, {"controller.yc": yc}, {"metrics": {"skip_s": 0.5}})
    m = compute_metrics(run)
    assert m["max_abs_yc"] == 0.1 and m["rms_yc"] == pytest.approx(0.1, rel=1e-12)
    assert compute_metrics(run, skip_s=0.0)["max_abs_yc"] == 5.0


def test_missing_signals_leave_metrics_out_with_notes(tmp_path):
    run = write_run(tmp_path / "r", T, {"vehicle.ay": -2.0 * np.sin(np.pi * T)})
    report = write_metrics(run)
    assert set(report.values) == {"max_abs_ay", "mu_true_final"}
    assert report.values["max_abs_ay"] == pytest.approx(2.0, rel=1e-12)
    notes = (run / "metrics_notes.txt").read_text()
    assert "controller.mu_hat not recorded" in notes and "controller.delta" in notes


def test_non_finite_signal_is_left_out_with_its_time(tmp_path):
    yc = 0.1 * np.ones_like(T)
    yc[50] = np.nan
    run = write_run(tmp_path / "r", T, {"controller.yc": yc, "vehicle.ay": yc})
    report = write_metrics(run)
    assert "rms_yc" not in report.values and "max_abs_ay" not in report.values
    assert any("nan" in n and "t=0.5 s" in n for n in report.notes)


def test_write_metrics_merges_and_is_deterministic(tmp_path):
    run = write_run(tmp_path / "r", T, {"controller.yc": 0.2 * np.ones_like(T)})
    (run / "metrics.json").write_text(json.dumps({"planner_steps": 20, "rms_yc": 99.0,
                                                 "max_abs_delta": 3.0}))
    write_metrics(run)
    first = (run / "metrics.json").read_bytes()
    data = json.loads(first)
    assert data["planner_steps"] == 20
    assert data["rms_yc"] == pytest.approx(0.2, rel=1e-12)
    assert "max_abs_delta" not in data  # ours, and not computable any more
    write_metrics(run)
    assert (run / "metrics.json").read_bytes() == first


@pytest.mark.parametrize("name", ["manifest.json", "metrics.json"])
@pytest.mark.parametrize("text, message", [
    ('{"a": 1,\n "b": }', r":2: not valid JSON: Expecting value"),
    ("[1, 2]", r": expected a JSON object at the top level, found list"),
])
def test_bad_json_files_of_a_run_are_named_by_every_reader(tmp_path, name, text, message):
    """load_run, write_metrics and compare's run_metrics share one reading rule."""
    run = write_run(tmp_path / "r", T, {"controller.yc": 0.1 * T})
    (run / name).write_text(text)
    path = str(run / name)
    readers = [lambda: run_metrics(load_run(run)), lambda: write_metrics(run)]
    if name == "manifest.json":
        readers.append(lambda: load_run(run))
    for reader in readers:
        with pytest.raises(AnalysisError, match="^" + re.escape(path) + message):
            reader()


def test_metric_table_order_is_the_platform_order_then_the_rest_sorted():
    names = {"planner_steps", "rms_ex", "cone_hits", "a_custom", "rms_yc"}
    assert ordered_metric_names(names) == ["rms_yc", "rms_ex", "cone_hits", "a_custom", "planner_steps"]
    assert ordered_metric_names(set()) == []


def test_cone_inside_rotated_rectangle_exact_geometry():
    psi = math.pi / 6
    c, s = math.cos(psi), math.sin(psi)

    def world(lon, lat):  # body frame -> world, CG at (10, 20)
        return [10 + c * lon - s * lat, 20 + s * lon + c * lat]

    eps = 1e-6
    cones = np.array([world(2.25 - eps, 0), world(2.25 + eps, 0), world(-2.25 + eps, 0.9 - eps),
                      world(-2.25 - eps, 0), world(0, -0.9 - eps), world(1.0, -0.9 + eps),
                      world(0.9, 2.0)])
    inside = cones_inside(10, 20, psi, cones, length=4.5, width=1.8)
    assert inside.tolist() == [True, False, True, False, False, True, False]
    # CG 1 m behind the centre: front bumper 3.25 m ahead, rear 1.25 m behind
    inside = cones_inside(10, 20, psi, np.array([world(3.2, 0), world(-1.3, 0)]),
                          length=4.5, width=1.8, front=3.25)
    assert inside.tolist() == [True, False]


def test_cone_hits_counts_each_cone_once(tmp_path):
    t = np.arange(0, 501) * 0.01
    cols = {"vehicle.x": 10.0 * t, "vehicle.y": np.zeros_like(t), "vehicle.psi": np.zeros_like(t)}
    cones = [[20.0, 0.85], [20.0, -0.85], [30.0, 0.95], [30.0, -0.95], [80.0, 0.0]]
    run = write_run(tmp_path / "r", t, cols, {"metrics": {"cones": cones}})
    assert compute_metrics(run)["cone_hits"] == 2
    hits = cone_hits(cols["vehicle.x"], cols["vehicle.y"], cols["vehicle.psi"], cones,
                     width=2.0, chunk=7)
    assert hits.tolist() == [True, True, True, True, False]
    planner_cones = write_run(tmp_path / "p", t, cols, {"components": {"planner": {
        "parameters": {"cones": cones}}}, "metrics": {"vehicle_width": 2.0}})
    assert compute_metrics(planner_cones)["cone_hits"] == 4


def test_empty_cone_list_means_no_cone_metric(tmp_path):
    run = write_run(tmp_path / "r", T, {"vehicle.x": T, "vehicle.y": T, "vehicle.psi": T},
                    {"metrics": {"skip_s": 0.0, "cones": []}})
    assert "cone_hits" not in compute_metrics(run)


def test_bad_cones_field_names_the_field(tmp_path):
    run = write_run(tmp_path / "r", T, {"vehicle.x": T}, {"metrics": {"cones": [[1, 2, 3]]}})
    with pytest.raises(AnalysisError, match=r"scenario\.metrics\.cones: expected a list"):
        compute_metrics(run)


def test_bad_csv_value_names_file_line_and_value(tmp_path):
    run = write_run(tmp_path / "r", T[:5], {"vehicle.x": T[:5]})
    text = (run / "signals.csv").read_text().splitlines()
    text[3] = text[3].split(",")[0] + ",abc"
    (run / "signals.csv").write_text("\n".join(text) + "\n")
    with pytest.raises(AnalysisError, match=r"signals\.csv:4: value 'abc' is not a number"):
        compute_metrics(run)


def test_partial_last_row_is_dropped_and_missing_folder_is_clear(tmp_path):
    run = write_run(tmp_path / "r", T[:5], {"vehicle.x": T[:5], "vehicle.y": T[:5]})
    with open(run / "signals.csv", "a") as f:
        f.write("0.05,0.0")  # interrupted mid-row
    assert len(load_run(run).time) == 5
    with pytest.raises(AnalysisError, match="signals.csv is missing"):
        compute_metrics(tmp_path)
    with pytest.raises(AnalysisError, match="no such run folder"):
        compute_metrics(tmp_path / "nope")


# --- signals.csv parsing: numpy's reader against float() -------------------------------------

TRICKY_TEXTS = ["-0.0", "0.0", "1e-300", "5e-324", "-5e-324", "2.225073858507201e-308",
                "2.2250738585072014e-308", "1.7976931348623157e308", "-1.7976931348623157e308",
                "0.30000000000000004", "1.0000000000000002", "0.1", "123456789.12345679",
                "9007199254740993", "2.4703282292062328e-324", "2.4703282292062327e-324",
                "0.1000000000000000055511151231257827", "1e400", "-1e-400", "inf", "-inf",
                "nan", "-nan", "4.9406564584124654e-324", "8.98846567431158e307"]


def _write_table(path: Path, rows: list[list[str]]) -> Path:
    header = ",".join(["time"] + [f"c{i}" for i in range(len(rows[0]) - 1)])
    path.write_text(header + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
    return path


def _no_slow_path(monkeypatch):
    """Make a fallback to the line-by-line parse fail the test: the fast path must read it."""
    def refuse(*args):
        raise AssertionError("fell back to the line-by-line parse")
    monkeypatch.setattr(rundata, "_parse_rows_slowly", refuse)


def test_fast_parse_is_bit_identical_to_float_on_tricky_values(tmp_path, monkeypatch):
    rows = [[str(i), text, text.lstrip("-")] for i, text in enumerate(TRICKY_TEXTS)]
    path = _write_table(tmp_path / "signals.csv", rows)
    expected = np.array([[float(f) for f in row] for row in rows])
    _no_slow_path(monkeypatch)
    header, data = read_csv_table(path)
    assert header == ["time", "c0", "c1"]
    assert data.tobytes() == expected.tobytes()  # bits: -0.0, NaN signs and subnormals included
    assert np.signbit(data[0, 1]) and data[3, 1] == 5e-324 and data[7, 1] == 1.7976931348623157e308


def test_fast_parse_round_trips_every_repr_of_random_bit_patterns(tmp_path, monkeypatch):
    rng = np.random.default_rng(20)
    values = rng.integers(0, 2**64, size=(3000, 4), dtype=np.uint64, endpoint=False).view(np.float64)
    values = np.where(np.isfinite(values), values, -0.0)
    values[:, 0] = rng.uniform(-300.0, 300.0, size=3000)  # the usual magnitudes of a run
    rows = [[repr(float(v)) for v in row] for row in values]
    path = _write_table(tmp_path / "signals.csv", rows)
    slow = rundata._parse_rows_slowly(path, [",".join(r) for r in rows], 4)
    _no_slow_path(monkeypatch)
    _, fast = read_csv_table(path)
    assert fast.tobytes() == values.tobytes()
    assert slow.tobytes() == values.tobytes()


@pytest.mark.parametrize("field", [" 1.5", "1.5 ", "\t2", "+1", "1.", ".5", "1_0", "\u0661",
                                   "", "  ", "0x10", "1d3", "e5", "1e", "--1", "True", "#1",
                                   "'1'", '"1"', "1\x00", "1,0", "2.0\r3.0"])
def test_fast_and_slow_parse_agree_on_odd_fields(tmp_path, field):
    """Either the same bits, or the same error naming the file, line and value."""
    path = tmp_path / "signals.csv"
    lines = ["0.0,1.0", "0.01," + field, "0.02,3.0"]

    def outcome(parse):
        try:
            return parse(path, lines, 2).tobytes()
        except AnalysisError as error:
            return str(error)

    fast, slow = outcome(rundata._parse_rows), outcome(rundata._parse_rows_slowly)
    assert fast == slow
    if isinstance(slow, str):
        assert slow.startswith(f"{path}:3: ")


def test_blank_line_and_bad_value_deep_in_a_long_file_are_named(tmp_path):
    rows = [[repr(0.01 * i), repr(float(i))] for i in range(2000)]
    lines = [",".join(r) for r in rows]
    path = tmp_path / "signals.csv"
    path.write_text("time,a\n" + "\n".join(lines[:1500] + [""] + lines[1500:]) + "\n")
    with pytest.raises(AnalysisError, match=re.escape(f"{path}:1502: expected 2 fields, found 1")):
        read_csv_table(path)
    lines[1700] = "17.0,0.5.1"
    path.write_text("time,a\n" + "\n".join(lines) + "\n")
    with pytest.raises(AnalysisError, match=re.escape(f"{path}:1702: value '0.5.1' is not a number")):
        read_csv_table(path)


def test_header_only_file_reads_as_no_rows(tmp_path):
    path = tmp_path / "signals.csv"
    path.write_text("time,a,b\n")
    header, data = read_csv_table(path)
    assert header == ["time", "a", "b"] and data.shape == (0, 3)


def test_write_metrics_with_a_loaded_run_does_not_read_the_csv_again(tmp_path):
    run_dir = write_run(tmp_path / "r", T, {"controller.yc": 0.3 * np.sin(2 * np.pi * T),
                                            "controller.delta": 0.1 * T})
    write_metrics(run_dir)
    from_disk = (run_dir / "metrics.json").read_bytes()
    run = load_run(run_dir)
    (run_dir / "signals.csv").unlink()
    (run_dir / "metrics.json").unlink()
    write_metrics(run_dir, run=run)
    assert (run_dir / "metrics.json").read_bytes() == from_disk
    other = write_run(tmp_path / "other", T, {"controller.yc": T})
    with pytest.raises(AnalysisError, match="loaded from another folder"):
        write_metrics(other, run=run)


# ---- vehicle following ------------------------------------------------------------
FOLLOWING_LINKS = ["lead.x -> planner.lead_x", "lead.y -> planner.lead_y", "lead.vx -> planner.lead_vx"]


def _following_run(path, lead_x, follower_x, lead_v, follower_v, gap_ref, lead_y=None, lead_psi=None):
    """Two cars on the x axis; the planner's gap is the bumper-to-bumper distance (4.5 m bodies)."""
    n = len(lead_x)
    zeros = np.zeros(n)
    columns = {"vehicle.x": follower_x, "vehicle.y": zeros, "vehicle.psi": zeros, "vehicle.vx": follower_v,
               "lead.x": lead_x, "lead.y": zeros if lead_y is None else lead_y,
               "lead.psi": zeros if lead_psi is None else lead_psi, "lead.vx": lead_v,
               "planner.gap": lead_x - follower_x - 4.5, "planner.gap_ref": gap_ref}
    return write_run(path, T[:n], columns, connections=FOLLOWING_LINKS)


def test_following_metrics_on_an_analytic_approach(tmp_path):
    """Follower at 12 m/s closes on a lead at 10 m/s from a 30 m gap: gap(t) = 30 - 2 t."""
    gap = 30.0 - 2.0 * T
    lead_x = 100.0 + 10.0 * T
    run = _following_run(tmp_path / "r", lead_x, lead_x - 4.5 - gap, np.full(T.size, 10.0),
                         np.full(T.size, 12.0), np.full(T.size, 21.0))
    m = compute_metrics(run)
    error = gap - 21.0
    assert m["max_abs_gap_error"] == pytest.approx(9.0)
    assert m["rms_gap_error"] == pytest.approx(rms(T, error), rel=1e-12)
    assert m["min_time_gap"] == pytest.approx(26.0 / 12.0)           # at t = 2 s
    assert m["min_ttc"] == pytest.approx(26.0 / 2.0)
    assert m["gap_overshoot"] == 0.0                                  # never closer than 21 m
    assert m["collisions"] == 0


def test_gap_overshoot_ttc_and_collisions_count_contacts(tmp_path):
    """The gap dips through zero twice: two contacts, overshoot = gap_ref - min gap."""
    gap = 1.0 - 2.0 * np.abs(np.sin(np.pi * T))      # 1 m, down to -1 m at t = 0.5 and 1.5 s
    follower_v = 5.0 + np.cos(np.pi * T)
    run = _following_run(tmp_path / "r", 50.0 + gap + 4.5, np.full(T.size, 50.0), np.full(T.size, 5.0),
                         follower_v, np.full(T.size, 2.0))
    m = compute_metrics(run)
    assert m["collisions"] == 2
    assert m["gap_overshoot"] == pytest.approx(3.0)
    assert m["min_ttc"] == 0.0                       # closing while touching


def test_side_by_side_cars_do_not_collide_and_a_turned_car_does(tmp_path):
    from cosim.analysis.collisions import bodies_overlap
    x, zero = np.array([0.0]), np.array([0.0])
    beside = bodies_overlap((x, zero, zero), (x, np.array([1.81]), zero))
    touching = bodies_overlap((x, zero, zero), (x, np.array([1.8]), zero))
    assert not beside[0] and touching[0]
    # nose to nose: clear at 4.6 m CG to CG; turned 90 degrees its half width 0.9 m faces the nose
    assert not bodies_overlap((x, zero, zero), (np.array([4.6]), zero, zero))[0]
    assert not bodies_overlap((x, zero, zero), (np.array([3.2]), zero, np.array([np.pi / 2])))[0]
    assert bodies_overlap((x, zero, zero), (np.array([3.1]), zero, np.array([np.pi / 2])))[0]
    # turned 45 degrees, its rear-left corner (-2.25, 0.9) in its own axes lies at
    # (-(2.25 + 0.9) / sqrt 2, -(2.25 - 0.9) / sqrt 2) from its centre; put that corner on y = 0
    c = 1.0 / np.sqrt(2.0)
    reach, lift = 2.25 + 3.15 * c, 1.35 * c
    for dx, hit in ((-0.01, True), (0.01, False)):
        b = (np.array([reach + dx]), np.array([lift]), np.array([np.pi / 4]))
        assert bodies_overlap((x, zero, zero), b)[0] == hit


def test_runs_without_a_lead_have_no_following_metrics(tmp_path):
    run = write_run(tmp_path / "r", T, {"vehicle.vx": np.ones(T.size), "planner.gap": np.ones(T.size)},
                    connections=["vehicle -> planner"])
    m = compute_metrics(run)
    assert not {"collisions", "min_ttc", "rms_gap_error"} & set(m)


def test_lead_that_never_closes_in_gets_a_note_not_a_ttc(tmp_path):
    lead_x = 100.0 + 12.0 * T
    run = _following_run(tmp_path / "r", lead_x, 10.0 * T, np.full(T.size, 12.0), np.full(T.size, 10.0),
                         np.full(T.size, 18.0))
    from cosim.analysis.metrics import analyse_run
    report = analyse_run(load_run(run))
    assert "min_ttc" not in report.values
    assert any("never closes in" in note for note in report.notes)
