"""Figures and run comparison on synthetic run folders: layouts, plotted data, outputs."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PIL import Image

from tests.helpers.synthetic_runs import lane_change_run, write_run  # noqa: E402

from cosim.figures import signals as sig  # noqa: E402
from cosim.figures.compare import run_labels  # noqa: E402
from cosim.figures.layouts import DPI, build_figure, choose_layout, draw_figures, save_png  # noqa: E402
from cosim.figures.envelope import BUCKETS, bucket_edges, envelope, envelope_indices  # noqa: E402
from cosim.analysis.metrics import compute_metrics  # noqa: E402
from cosim.analysis.rundata import AnalysisError, load_run  # noqa: E402


def _axes_by_title(fig):
    return {ax.get_title(): ax for ax in fig.axes}


def _lines(ax):
    return {line.get_label(): line for line in ax.get_lines()}


def test_track_layout_has_eleven_panels_with_the_run_data(tmp_path):
    run = load_run(lane_change_run(tmp_path / "r"))
    fig, layout = build_figure([run], "track")
    assert layout == "track" and len([ax for ax in fig.axes if ax.axison]) == 11
    for title in ("speed error", "external forces", "steering angle"):
        assert title in _axes_by_title(fig)
    axes = _axes_by_title(fig)
    yc = _lines(axes["lateral error at CG"])["yc"]
    np.testing.assert_array_equal(yc.get_ydata(), run.signal("controller.yc"))
    mu = _lines(axes["friction estimate"])
    np.testing.assert_array_equal(mu["mu (true)"].get_ydata(), run.signal("road_friction.value"))
    np.testing.assert_array_equal(mu["mu_hat"].get_ydata(), run.signal("controller.mu_hat"))
    speed = _lines(axes["speed tracking"])
    assert set(speed) == {"vx", "vx_ref"}
    assert all(ax.get_xlabel() and ax.get_ylabel() for ax in fig.axes if ax.axison)


def test_manoeuvre_layout_has_nine_panels_with_both_trajectories(tmp_path):
    run = load_run(lane_change_run(tmp_path / "r"))
    fig, layout = build_figure([run])
    assert layout == "manoeuvre" and len(fig.axes) == 9
    axes = _axes_by_title(fig)
    road = axes["road and planned trajectories"]
    alt = [line for line in road.get_lines() if line.get_color() == "tab:orange"]
    assert alt and all(np.all(line.get_ydata() == 3.5) for line in alt)
    force_axes = axes["reference acceleration force"]
    force = _lines(force_axes)["m·a_ref"]
    np.testing.assert_allclose(force.get_ydata(), 1500.0 * 0.2)
    assert force_axes.get_ylabel() == "reference acceleration force m·a_ref (N)"


def test_reference_acceleration_takes_the_window_point_nearest_the_vehicle(tmp_path):
    t = np.array([0.0, 1.0, 2.0])
    cols = {"vehicle.x": np.array([0.0, 3.2, 7.9]), "vehicle.y": np.zeros(3)}
    px = np.tile(np.arange(10.0), (3, 1))
    arrays = {"planner.ref_x": (t, px), "planner.ref_y": (t, np.zeros_like(px)),
              "planner.ref_a": (t, 0.1 * px)}
    run = load_run(write_run(tmp_path / "r", t, cols, arrays=arrays))
    times, a_ref = sig.reference_acceleration(run)
    np.testing.assert_array_equal(times, t)
    np.testing.assert_allclose(a_ref, [0.0, 0.3, 0.8])


def test_layout_choice_rules(tmp_path):
    t = np.arange(3.0)
    assert choose_layout(load_run(write_run(tmp_path / "a", t, {"vehicle.x": t},
                                            {"name": "satory_nominal"}))) == "track"
    assert choose_layout(load_run(write_run(tmp_path / "b", t, {"vehicle.x": t},
                                            {"name": "ISO3888_2"}))) == "manoeuvre"
    hinted = write_run(tmp_path / "c", t, {"vehicle.x": t},
                       {"name": "lane_keeping", "metrics": {"figures": "track"}})
    assert choose_layout(load_run(hinted)) == "track"
    bad = write_run(tmp_path / "d", t, {"vehicle.x": t}, {"metrics": {"figures": "fig4"}})
    with pytest.raises(AnalysisError, match=r"scenario\.metrics\.figures: .* found 'fig4'"):
        choose_layout(load_run(bad))
    px = np.ones((3, 4))
    alt_differs = {"planner.ref_x": (t, px), "planner.ref_y": (t, 0 * px),
                   "planner.alt_x": (t, px), "planner.alt_y": (t, 0 * px + 3.5)}
    keeping = write_run(tmp_path / "e", t, {"planner.lateral_offset": 0 * t}, {"name": "drive"},
                        arrays=alt_differs)
    assert choose_layout(load_run(keeping)) == "track"
    moved = write_run(tmp_path / "f", t, {"planner.lateral_offset": np.array([0, 1.0, 3.5])},
                      {"name": "drive"})
    assert choose_layout(load_run(moved)) == "manoeuvre"


def test_missing_signals_give_notes_not_errors(tmp_path):
    t = np.arange(0, 11) * 0.1
    run = write_run(tmp_path / "r", t, {"vehicle.x": t, "vehicle.y": 0 * t}, {"name": "open_loop"})
    fig, _ = build_figure([load_run(run)])
    notes = [txt.get_text() for ax in fig.axes for txt in ax.texts]
    assert "not recorded: yL" in notes and "not recorded: delta" in notes
    assert len(fig.axes) == 12


def test_compare_two_runs_overlays_and_tabulates(tmp_path):
    a = lane_change_run(tmp_path / "a" / "run")
    b = lane_change_run(tmp_path / "b" / "run", offset=0.2)
    (a / "metrics.json").write_text('{"planner_steps": 61, "note": "text is skipped"}')
    app, runner = _cli()
    result = runner.invoke(app, ["compare", str(a), str(b), "--out", str(tmp_path / "cmp")])
    assert result.exit_code == 0, result.output
    assert "| max_abs_yL | 0.1 | 0.3 |" in result.output  # the table is printed
    png, csv_path, md_path = (tmp_path / "cmp" / name for name in (
        "compare_manoeuvre.png", "compare_metrics.csv", "compare_metrics.md"))
    assert png.read_bytes()[:4] == b"\x89PNG"
    with open(csv_path) as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["metric", "a/run", "b/run"]
    table = {row[0]: row[1:] for row in rows[1:]}
    for col, run in enumerate((a, b)):
        for name, value in compute_metrics(run).items():
            assert float(table[name][col]) == value
    assert float(table["max_abs_yL"][1]) == pytest.approx(0.3)
    assert table["planner_steps"] == ["61", ""] and "note" not in table
    assert "| max_abs_yL | 0.1 | 0.3 |" in md_path.read_text()


def test_compare_figure_overlays_each_run_and_labels_are_unique(tmp_path):
    a = lane_change_run(tmp_path / "x" / "run")
    b = lane_change_run(tmp_path / "y" / "other", offset=0.2)
    assert run_labels([a, b]) == ["run", "other"]
    assert run_labels([a, tmp_path / "z" / "run"]) == ["x/run", "z/run"]
    runs = [load_run(a), load_run(b)]
    fig, _ = build_figure(runs, "track")
    lines = _axes_by_title(fig)["lateral error at CG"].get_lines()
    assert [line.get_label() for line in lines] == ["run: yc", "other: yc"]
    np.testing.assert_array_equal(lines[1].get_ydata(), runs[1].signal("controller.yc"))


def _cli():
    import typer
    from typer.testing import CliRunner

    from cosim.cli.analysis import register

    app = typer.Typer()
    register(app)
    return app, CliRunner()


def test_draw_figures_and_cli_plot_write_the_same_deterministic_png(tmp_path):
    run = lane_change_run(tmp_path / "r")
    (png,) = draw_figures(run)
    assert png == run / "figure_manoeuvre.png"
    first = png.read_bytes()
    assert first[:8] == b"\x89PNG\r\n\x1a\n"
    app, runner = _cli()
    result = runner.invoke(app, ["plot", str(run), "--layout", "manoeuvre"])  # the same bytes again
    assert result.exit_code == 0, result.output
    assert f"figure: {png}" in result.output
    assert png.read_bytes() == first


def test_cli_plot_error_is_one_line_without_traceback(tmp_path):
    app, runner = _cli()
    result = runner.invoke(app, ["plot", str(tmp_path / "missing")])
    assert result.exit_code == 2 and "no such run folder" in result.output
    assert "Traceback" not in result.output


def test_map_marks_the_cones_that_were_hit(tmp_path):
    t = np.arange(0, 301) * 0.01
    cols = {"vehicle.x": 10.0 * t, "vehicle.y": 0 * t, "vehicle.psi": 0 * t}
    cones = [[10.0, 0.8], [10.0, -1.0], [20.0, 0.5]]
    run = load_run(write_run(tmp_path / "r", t, cols, {"name": "iso3888_2",
                                                       "metrics": {"cones": cones}}))
    fig, _ = build_figure([run])
    road = _lines(_axes_by_title(fig)["road and planned trajectories"])
    hit = road["cone hit (2)"]
    assert list(zip(hit.get_xdata(), hit.get_ydata())) == [(10.0, 0.8), (20.0, 0.5)]
    assert list(road["cone"].get_ydata()) == [-1.0]


def _naive_envelope_indices(y, buckets):
    """Per bucket (cosim.figures.envelope.bucket_edges): first, last, argmin, argmax, by a plain loop."""
    edges = (np.arange(buckets + 1) * len(y)) // buckets
    keep = set()
    for a, b in zip(edges[:-1], edges[1:]):
        seg = y[a:b]
        keep |= {a, b - 1, a + int(np.argmin(seg)), a + int(np.argmax(seg))}
    return np.array(sorted(keep))


def test_envelope_keeps_each_bucket_first_last_min_max_as_a_plain_loop_does():
    rng = np.random.default_rng(7)
    y = np.cumsum(rng.standard_normal(30001)) + np.where(rng.random(30001) < 1e-3, 50.0, 0.0)
    t = 0.01 * np.arange(y.size)
    keep = envelope_indices(y, 1000)
    np.testing.assert_array_equal(keep, _naive_envelope_indices(y, 1000))
    xs, ys = envelope(t, y, 1000)
    np.testing.assert_array_equal(xs, t[keep])
    np.testing.assert_array_equal(ys, y[keep])
    assert ys.max() == y.max() and ys.min() == y.min() and len(ys) <= 4000
    short = np.arange(3999.0)                       # under 4 buckets' worth: drawn whole
    assert envelope(short, short, 1000)[1] is short
    gappy = y.copy()
    gappy[5] = np.nan                               # a gap must stay a gap: no decimation
    assert envelope(t, gappy, 1000)[1] is gappy
    with pytest.raises(ValueError, match="one length"):
        envelope(t[:-1], y)


def test_long_signals_are_plotted_as_their_envelope_with_every_bucket_peak(tmp_path):
    n = 20000
    t = 0.01 * np.arange(n)
    rng = np.random.default_rng(3)
    yc = 0.01 * np.sin(0.3 * t) + 1e-3 * rng.standard_normal(n)
    yc[12345] = 0.2                                  # one-tick spike: must be drawn
    cols = {"vehicle.x": 10 * t, "vehicle.y": 0 * t, "controller.yc": yc,
            "vehicle.vx": 10 + 0.1 * rng.standard_normal(n), "controller.vx_ref": 0 * t + 10}
    run = load_run(write_run(tmp_path / "r", t, cols, {"name": "satory_long"}))
    fig, _ = build_figure([run], "track")
    line = _lines(_axes_by_title(fig)["lateral error at CG"])["yc"]
    x, y = line.get_xdata(), line.get_ydata()
    assert len(y) <= 4 * BUCKETS < n
    where = np.searchsorted(t, x)                    # every plotted point is a recorded sample
    np.testing.assert_array_equal(t[where], x)
    np.testing.assert_array_equal(yc[where], y)
    edges = bucket_edges(n, BUCKETS)
    for a, b in zip(edges[:-1], edges[1:]):
        inside = (where >= a) & (where < b)
        assert y[inside].max() == yc[a:b].max() and y[inside].min() == yc[a:b].min()
    assert x[0] == t[0] and x[-1] == t[-1] and y.max() == 0.2
    speed = _lines(_axes_by_title(fig)["speed tracking"])
    np.testing.assert_array_equal(speed["vx"].get_ydata(), cols["vehicle.vx"][
        _naive_envelope_indices(cols["vehicle.vx"], BUCKETS)])


def test_save_png_gives_the_pixels_savefig_gives(tmp_path):
    def small_figure():
        fig = Figure(figsize=(4, 3), layout="constrained")
        ax = fig.subplots(1, 2)[1]
        ax.plot(np.sin(np.arange(500) * 0.05), label="sin")
        ax.set_title("a constrained layout")
        ax.legend(loc="best")
        FigureCanvasAgg(fig)
        return fig

    ours = save_png(small_figure(), tmp_path / "ours.png")
    small_figure().savefig(tmp_path / "theirs.png", dpi=DPI)
    np.testing.assert_array_equal(np.asarray(Image.open(ours)),
                                  np.asarray(Image.open(tmp_path / "theirs.png")))


def test_draw_figures_with_a_loaded_run_draws_the_same_png_without_the_csv(tmp_path):
    run_dir = lane_change_run(tmp_path / "r")
    (png,) = draw_figures(run_dir)
    first = png.read_bytes()
    run = load_run(run_dir)
    (run_dir / "signals.csv").unlink()
    png.unlink()
    assert draw_figures(run_dir, run=run) == [png]
    assert png.read_bytes() == first
    with pytest.raises(AnalysisError, match="loaded from another folder"):
        draw_figures(lane_change_run(tmp_path / "other"), run=run)


def test_run_command_analysis_parses_signals_once_with_the_same_outputs(tmp_path, monkeypatch):
    """cosim run's finish step: one load_run for metrics and figures, same files as two loads."""
    from types import SimpleNamespace

    from cosim.analysis import rundata as metrics_rundata
    from cosim.execution.finish import analyse_run_folder
    from cosim.analysis.metrics import write_metrics

    separate = lane_change_run(tmp_path / "separate" / "run")  # same name: same legend
    write_metrics(separate)
    draw_figures(separate)
    once = lane_change_run(tmp_path / "once" / "run")
    loads = []
    real_load = metrics_rundata.load_run
    monkeypatch.setattr(metrics_rundata, "load_run", lambda d: loads.append(d) or real_load(d))
    result = SimpleNamespace(out_dir=once, metrics={})
    notes = analyse_run_folder(result, figures=True)
    assert loads == [once]
    assert notes == [f"figure: {once / 'figure_manoeuvre.png'}"]
    for name in ("metrics.json", "figure_manoeuvre.png"):
        assert (once / name).read_bytes() == (separate / name).read_bytes()
    assert result.metrics == json.loads((once / "metrics.json").read_text())
    (once / "signals.csv").write_text("time,a\n0.0,x\n")
    message = f"{once / 'signals.csv'}:2: value 'x' is not a number"
    assert analyse_run_folder(result, figures=True) == [f"metrics not computed: {message}",
                                                        f"figures not drawn: {message}"]


def _offset_run(run_dir, peak_t, peak_yc):
    """Driving along x at 10 m/s, offset yc(t) left of a planned path on y = 0 (a bump at peak_t)."""
    t = np.arange(0, 401) * 0.01
    yc = peak_yc * np.exp(-((t - peak_t) / 0.3) ** 2)
    cols = {"vehicle.x": 10.0 * t, "vehicle.y": yc, "controller.yc": yc}
    tw = t[::10]
    px = 10.0 * tw[:, None] + 0.25 * np.arange(64)[None, :] - 2.0
    arrays = {"planner.ref_x": (tw, px), "planner.ref_y": (tw, np.zeros_like(px))}
    return write_run(run_dir, t, cols, {"name": "track_offset"}, arrays=arrays)


def test_zoom_is_sized_from_the_largest_yc_and_shows_the_gap(tmp_path):
    from cosim.figures.zoom import ZOOM_FACTOR

    run = load_run(_offset_run(tmp_path / "r", 2.5, 0.02))
    fig, _ = build_figure([run], "track")
    ax = _axes_by_title(fig)["zoom on tracking (largest |yc_cg|)"]
    half = ZOOM_FACTOR * 0.02
    np.testing.assert_allclose(ax.get_xlim(), (-half, half))
    np.testing.assert_allclose(ax.get_ylim(), (-half, half))
    lines = _lines(ax)
    planned = lines["planned path (window at t = 2.50 s)"]   # the window recorded at the worst tick
    np.testing.assert_allclose(planned.get_xdata(), 25.0 + 0.25 * np.arange(64) - 2.0 - 25.0)
    np.testing.assert_allclose(planned.get_ydata(), -0.02)   # the path lies |yc| to the right
    marker = lines["|yc_cg| = 2.00 cm at t = 2.50 s"]
    assert list(marker.get_xdata()) == [0.0] and list(marker.get_ydata()) == [0.0]
    vehicle = lines["vehicle"]
    inside = np.isfinite(vehicle.get_xdata())
    assert inside.sum() > 0 and np.all(np.abs(vehicle.get_xdata()[inside]) <= 2 * half)
    assert inside[0] and inside[-1] and len(inside) < 401     # only the stretch near the box
    assert ax.get_xlabel() == "x - 25.00 (m)" and ax.get_ylabel() == "y - 0.02 (m)"


def test_zoom_box_has_a_minimum_for_a_run_without_error(tmp_path):
    from cosim.figures.zoom import ZOOM_MIN_HALF_WIDTH, zoom_half_width

    assert zoom_half_width(0.0) == ZOOM_MIN_HALF_WIDTH == zoom_half_width(ZOOM_MIN_HALF_WIDTH / 5)
    run = load_run(_offset_run(tmp_path / "r", 2.5, 0.0))
    ax = _axes_by_title(build_figure([run], "track")[0])["zoom on tracking (largest |yc_cg|)"]
    np.testing.assert_allclose(ax.get_xlim(), (-ZOOM_MIN_HALF_WIDTH, ZOOM_MIN_HALF_WIDTH))


def test_compare_zoom_goes_to_the_worst_point_over_all_runs(tmp_path):
    from cosim.figures.zoom import worst_point

    small = load_run(_offset_run(tmp_path / "small", 1.0, 0.01))
    large = load_run(_offset_run(tmp_path / "large", 3.0, -0.03))
    assert worst_point([small, large]) == (1, 300, 0.03)
    assert worst_point([large, small]) == (0, 300, 0.03)
    fig, _ = build_figure([small, large], "track")
    ax = _axes_by_title(fig)["zoom on tracking (largest |yc_cg|)"]
    assert ax.get_xlabel() == "x - 30.00 (m)"             # large's worst tick, not small's
    labels = set(_lines(ax))
    assert {"small: vehicle", "large: vehicle", "|yc_cg| = 3.00 cm at t = 3.00 s (large)"} <= labels


def test_zoom_without_yc_says_so(tmp_path):
    t = np.arange(3.0)
    run = load_run(write_run(tmp_path / "r", t, {"vehicle.x": t, "vehicle.y": 0 * t}))
    ax = _axes_by_title(build_figure([run], "track")[0])["zoom on tracking (largest |yc_cg|)"]
    assert [txt.get_text() for txt in ax.texts] == ["not recorded: yc, vehicle.x, vehicle.y"]


def _road_run(run_dir, road, obstacles, name="obstacle_avoidance"):
    t = np.arange(0, 101) * 0.01
    cols = {"vehicle.x": 10.0 * t, "vehicle.y": 0 * t}
    planner = {"python": "controllers.planning:Planner",
               "parameters": {"road": road, "lane": 0, "speed": {"v_max": 10.0},
                              "manoeuvre": {"type": "obstacle_avoidance", "obstacles": obstacles}}}
    return load_run(write_run(run_dir, t, cols, {"name": name, "components": {"plan": planner}}))


def test_map_draws_lane_edges_dividers_and_obstacles_of_a_straight_road(tmp_path):
    obstacles = [{"s": 40.0, "lane": 0, "length": 4.0, "width": 2.0},
                 {"s": 60.0, "lane": 1, "length": 5.0, "width": 1.5, "offset": 0.2}]
    run = _road_run(tmp_path / "r", {"builder": "two_lane", "length": 100, "lane_width": 3.5}, obstacles)
    road_ax = _axes_by_title(build_figure([run])[0])["road and planned trajectories"]
    lines = road_ax.get_lines()
    grey = [line for line in lines if line.get_color() == "gray"]
    assert [np.unique(line.get_ydata()).tolist() for line in grey] == [[-1.75], [1.75], [5.25]]
    assert [line.get_linestyle() for line in grey] == ["-", "--", "-"]
    assert all(line.get_xdata()[0] == 0.0 and line.get_xdata()[-1] == 100.0 for line in grey)
    boxes = [patch.get_xy() for patch in road_ax.patches]
    assert len(boxes) == 2
    for box, (x0, x1, y0, y1) in zip(boxes, [(40.0, 44.0, -1.0, 1.0), (60.0, 65.0, 2.95, 4.45)]):
        np.testing.assert_allclose([box[:, 0].min(), box[:, 0].max()], [x0, x1], atol=1e-12)
        np.testing.assert_allclose([box[:, 1].min(), box[:, 1].max()], [y0, y1], atol=1e-12)
    labels = [text.get_text() for text in road_ax.get_legend().get_texts()]
    assert labels[:3] == ["lane edge", "lane divider", "obstacle"]


def test_obstacle_on_a_bend_follows_the_arc(tmp_path):
    """Arc of radius 50 m to the left from the origin heading east: centre (0, 50)."""
    road = {"reference": {"segments": [{"arc": {"radius": 50.0, "angle": 90.0}}]}, "lanes": 2,
            "lane_width": 3.5}
    run = _road_run(tmp_path / "r", road, [{"s": 30.0, "lane": 1, "length": 6.0, "width": 2.0}])
    road_ax = _axes_by_title(build_figure([run])[0])["road and planned trajectories"]
    (box,) = [patch.get_xy() for patch in road_ax.patches]
    radius = np.hypot(box[:, 0], box[:, 1] - 50.0)            # distance to the bend's centre
    assert radius.min() == pytest.approx(50.0 - 4.5) and radius.max() == pytest.approx(50.0 - 2.5)
    angle = np.arctan2(box[:, 0], 50.0 - box[:, 1])           # arc angle s / R of each corner
    np.testing.assert_allclose([angle.min(), angle.max()], [30.0 / 50.0, 36.0 / 50.0])
    edges = [line for line in road_ax.get_lines() if line.get_color() == "gray"]
    np.testing.assert_allclose(np.hypot(edges[0].get_xdata(), edges[0].get_ydata() - 50.0), 51.75)


def test_a_road_that_cannot_be_rebuilt_is_a_note_in_the_map(tmp_path):
    run = _road_run(tmp_path / "r", {"builder": "no_such_road"}, [])
    road_ax = _axes_by_title(build_figure([run])[0])["road and planned trajectories"]
    notes = [text.get_text() for text in road_ax.texts]
    assert notes == ["road not drawn: components.plan.parameters.road.builder: unknown road "
                     "'no_such_road' (known: satory_standin, two_lane)"]


def test_speed_layout_gives_each_run_its_own_speed_and_error_panels(tmp_path):
    runs = [load_run(lane_change_run(tmp_path / "a")), load_run(lane_change_run(tmp_path / "b"))]
    fig, layout = build_figure(runs, "speed")
    assert layout == "speed" and len(fig.axes) == 6
    errors = [ax for ax in fig.axes if ax.get_title() == "speed error"]
    assert len(errors) == 2
    for ax, run in zip(errors, runs):
        np.testing.assert_array_equal(_lines(ax)["ex"].get_ydata(), run.signal("controller.ex"))
    drag = _lines([ax for ax in fig.axes if ax.get_title() == "external forces"][0])["Fwx (aero drag)"]
    vx = runs[0].signal("vehicle.vx")
    np.testing.assert_allclose(drag.get_ydata(), -0.42 * vx * np.abs(vx))


def test_manoeuvre_map_is_equal_aspect_on_the_manoeuvre_with_a_steering_inset(tmp_path):
    t = np.arange(0, 601) * 0.01
    state = ((t >= 2.0) & (t < 4.0)).astype(float)
    path = lane_change_run(tmp_path / "r")
    run = load_run(path)
    cols = {name: run.columns[name] for name in run.columns if name != "time"}
    cols["planner.manoeuvre_state"] = state
    run = load_run(write_run(tmp_path / "s", t, cols, {"name": "lane_change"}))
    fig, _ = build_figure([run], "manoeuvre")
    road = _axes_by_title(fig)["road and planned trajectories"]
    assert road.get_aspect() == 1.0
    assert road.get_xlim() == pytest.approx((20.0 - 30.0, 40.0 + 30.0))
    steering = _axes_by_title(fig)["steering angle"]
    insets = [child for child in steering.get_children() if hasattr(child, "get_title")
              and child.get_title() == "manoeuvre start"]
    assert len(insets) == 1


def _following_run(path):
    """Follower and lead on the x axis, the lead pulling away from 20 m at 1 m/s."""
    t = np.arange(0, 301) * 0.01
    lead_x = 24.5 + 11.0 * t
    cols = {"vehicle.x": 10.0 * t, "vehicle.y": 0 * t, "vehicle.psi": 0 * t, "vehicle.vx": 10.0 + 0 * t,
            "vehicle.ax": 0 * t, "lead.x": lead_x, "lead.y": 0 * t, "lead.psi": 0 * t, "lead.vx": 11.0 + 0 * t,
            "planner.gap": lead_x - 10.0 * t - 4.5, "planner.gap_ref": 18.0 + 0 * t,
            "planner.a_follow": 0.1 + 0 * t, "controller.yc": 0.01 * t, "controller.yL": 0 * t,
            "controller.psiL": 0 * t, "controller.delta": 0 * t, "controller.vx_ref": 10.0 + 0 * t}
    links = ["lead.x -> planner.lead_x", "lead.y -> planner.lead_y", "lead.vx -> planner.lead_vx"]
    return write_run(path, t, cols, {"name": "lane_following"}, connections=links)


def test_a_run_with_a_lead_gets_the_following_layout(tmp_path):
    run = load_run(_following_run(tmp_path / "r"))
    assert choose_layout(run) == "following"      # before the name rule ("lane" means manoeuvre)
    fig, layout = build_figure([run])
    assert layout == "following" and len(fig.axes) == 9
    axes = _axes_by_title(fig)
    gap = _lines(axes["gap to the lead (bumper to bumper, along the road)"])
    np.testing.assert_array_equal(gap["gap"].get_ydata(), run.signal("planner.gap"))
    np.testing.assert_array_equal(gap["desired gap"].get_ydata(), run.signal("planner.gap_ref"))
    speeds = _lines(axes["speeds"])
    np.testing.assert_array_equal(speeds["lead vx"].get_ydata(), run.signal("lead.vx"))
    assert {"follower vx", "follower vx_ref"} <= set(speeds)
    lead = _lines(axes["road, follower and lead"])["lead"]
    np.testing.assert_array_equal(lead.get_xdata(), run.signal("lead.x"))
    # opening: no time to collision; the time gap is gap / vx
    headways = _lines(axes["time gap and TTC (capped at 20 s)"])
    np.testing.assert_allclose(headways["time gap"].get_ydata(), run.signal("planner.gap") / 10.0)
    assert np.all(np.isnan(headways["time to collision"].get_ydata()))
    for title in ("follower: lateral error at CG", "follower: lateral error at preview point",
                  "follower: heading error"):
        assert title in axes
    paths = draw_figures(run.run_dir)
    assert [p.name for p in paths] == ["figure_following.png"]
