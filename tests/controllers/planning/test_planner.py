"""Manoeuvres and the planner component: shapes, clearances, stops, windows (controllers.planning.manoeuvres, .planner)."""

import numpy as np
import pytest

from cosim.component import ComponentError
from controllers.planning.manoeuvres import (QUINTIC_PEAK_CURV, Comfort, LateralPlan, Obstacle, Transition,
                                    plan_obstacles, transition_length)
from controllers.planning.planner import ROUTE_DS, Planner
from controllers.road.builders import frenet_to_world, two_lane_road
from controllers.planning.speed_stop import segment_phases
from controllers.trajectory import FIELDS, WINDOW_POINTS

OBSTACLE = {"s": 200.0, "lane": 0, "length": 4.0, "width": 2.0}


def start(planner: Planner, x=0.0, y=0.0, psi=0.0, vx=0.0) -> dict:
    """Initialize a planner at a vehicle pose."""
    return planner.initialize(0.0, {"x": x, "y": y, "psi": psi, "vx": vx})


def pose_on_ref(planner: Planner, s: float) -> dict:
    """Inputs for a vehicle sitting exactly on the recommended trajectory at reference s."""
    lateral = planner.plan.ref.lateral
    x, y, psi, _, _ = frenet_to_world(planner.road.reference, [s], *lateral.evaluate([s]))
    return {"x": float(x[0]), "y": float(y[0]), "psi": float(psi[0]),
            "vx": float(np.interp(s, planner.grid.s, planner.ref_route.v))}


def drive(planner: Planner, stations) -> list[dict]:
    """Step the planner with a vehicle placed on its own recommended trajectory."""
    return [planner.step(0.1 * (k + 1), pose_on_ref(planner, s)) for k, s in enumerate(stations)]


# ---- manoeuvres -----------------------------------------------------------
def test_transition_is_the_quintic_with_flat_ends():
    plan = LateralPlan(0.5, (Transition(100.0, 50.0, 0.5, 4.0),))
    s = np.linspace(90, 160, 701)
    d, d1, d2 = plan.evaluate(s)
    tau = np.clip((s - 100) / 50, 0, 1)
    np.testing.assert_allclose(d, 0.5 + 3.5 * (10 * tau ** 3 - 15 * tau ** 4 + 6 * tau ** 5), atol=1e-14)
    ends = np.isin(s, [90.0, 100.0, 150.0, 160.0])
    assert np.all(np.abs(d1[ends]) < 1e-15) and np.all(np.abs(d2[ends]) < 1e-15)
    np.testing.assert_allclose(d1[1:-1], np.gradient(d, s)[1:-1], atol=2e-4)
    assert plan.evaluate([125.0])[1][0] == pytest.approx(3.5 * 1.875 / 50)
    assert plan.active(100.0) and not plan.active(150.0)


@pytest.mark.parametrize("delta, v", [(3.5, 12.0), (3.5, 5.0), (1.0, 13.0)])
def test_transition_length_keeps_lateral_acceleration_and_jerk_in_comfort(delta, v):
    comfort = Comfort()
    length = transition_length(delta, v, comfort)
    plan = LateralPlan(0.0, (Transition(0.0, length, 0.0, delta),))
    s = np.linspace(0, length, 20001)
    _, _, d2 = plan.evaluate(s)
    d3 = np.gradient(d2, s)
    acc, jerk = v ** 2 * np.abs(d2).max(), v ** 3 * np.abs(d3).max()
    assert acc <= comfort.a_lat * (1 + 1e-6) and jerk <= comfort.j_lat * (1 + 1e-3)
    # the binding limit is reached (not needlessly long) unless the minimum length rules
    assert length == comfort.min_length or max(acc / comfort.a_lat, jerk / comfort.j_lat) > 0.999
    assert np.abs(d2).max() == pytest.approx(QUINTIC_PEAK_CURV * delta / length ** 2, rel=1e-6)


def vehicle_outline(x, y, psi, comfort: Comfort, n=12) -> np.ndarray:
    """Points on the vehicle rectangle's outline (CG at its centre)."""
    hl, hw = comfort.vehicle_length / 2, comfort.vehicle_width / 2
    corners = np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw], [hl, hw]])
    local = np.concatenate([np.linspace(a, b, n, endpoint=False) for a, b in zip(corners[:-1], corners[1:])])
    rot = np.array([[np.cos(psi), -np.sin(psi)], [np.sin(psi), np.cos(psi)]])
    return local @ rot.T + [x, y]


def box_distance(points, x0, x1, y0, y1) -> np.ndarray:
    """Distance from points to the axis-aligned box [x0, x1] x [y0, y1] (0 inside)."""
    dx = np.maximum.reduce([x0 - points[:, 0], np.zeros(len(points)), points[:, 0] - x1])
    dy = np.maximum.reduce([y0 - points[:, 1], np.zeros(len(points)), points[:, 1] - y1])
    return np.hypot(dx, dy)


def test_obstacle_with_free_lane_is_passed_with_the_margin():
    planner = Planner(road="two_lane", manoeuvre={"type": "obstacle_avoidance", "obstacles": [OBSTACLE]})
    start(planner)
    comfort = planner.plan.comfort
    assert planner.ref_route.stops is True and planner.plan.ref.stop_s is None   # stops only at the road end
    route, grid = planner.ref_route, planner.grid
    near = (grid.s > OBSTACLE["s"] - 40) & (grid.s < OBSTACLE["s"] + 45)
    assert np.all(route.v[near] > 5.0)                  # goes around at speed, does not brake
    worst = np.inf
    for x, y, psi in zip(route.x[near], route.y[near], route.psi[near]):
        pts = vehicle_outline(x, y, psi, comfort)
        # straight road along x: the obstacle box in world coordinates
        worst = min(worst, box_distance(pts, 200.0, 204.0, -1.0, 1.0).min())
    # it goes to the next lane's centre, which clears the obstacle by more than the margin
    assert worst >= comfort.margin
    assert worst == pytest.approx(3.5 - OBSTACLE["width"] / 2 - comfort.vehicle_width / 2, abs=1e-6)
    # the alternative is to stop before it
    assert planner.alt_route.stops and planner.plan.alt.stop_s < OBSTACLE["s"]


def test_obstacle_with_blocked_lane_stops_before_it():
    blocker = {"s": 180.0, "lane": 1, "length": 40.0, "width": 2.0}
    planner = Planner(road="two_lane",
                      manoeuvre={"type": "obstacle_avoidance", "obstacles": [OBSTACLE, blocker]})
    start(planner)
    comfort = planner.plan.comfort
    stop = planner.plan.ref.stop_s
    assert stop + comfort.vehicle_length / 2 + comfort.gap == pytest.approx(OBSTACLE["s"])
    grid, route = planner.grid, planner.ref_route
    assert np.all(route.v[grid.s >= stop] == 0.0)
    # a vehicle that follows the reference speed exactly comes to the stop point, never past it,
    # in the final segment's duration (the old exponential tail was 0.3 m short after 90 s);
    # the last 0.25 m route cell is linear in s, so the very end is exponential with time
    # constant 0.25 m / v(0.25 m before), about 0.3 s: 1 s more gets within 1 cm
    s, t, dt, entered = 0.0, 0.0, 1e-3, None
    while stop - s > 0.01 and t < 90.0:
        s += dt * float(np.interp(s, grid.s, route.v))
        t += dt
        if entered is None and s >= route.final_from:
            entered = t
    limits = planner.limits
    duration = float(sum(segment_phases(*route.profile.final_state, limits.j_max, limits.d_max)[0]))
    assert stop - 0.01 <= s <= stop and entered is not None and t - entered < duration + 1.0
    # the alternative goes around through the blocked lane (recorded, not followed)
    assert planner.alt_route.stops and len(planner.plan.alt.lateral.transitions) == 2


def test_manoeuvre_state_and_obstacle_distance_while_braking():
    blocker = {"s": 150.0, "lane": 1, "length": 100.0, "width": 2.0}
    planner = Planner(road="two_lane",
                      manoeuvre={"type": "obstacle_avoidance", "obstacles": [OBSTACLE, blocker]})
    start(planner)
    stations = np.arange(5.0, planner.plan.ref.stop_s, 1.0)
    outs = drive(planner, stations)
    states = np.array([o["manoeuvre_state"] for o in outs])
    braking = stations >= planner.ref_route.brake_from
    assert np.all(states[braking] == 2.0) and np.all(states[~braking] == 0.0) and braking.any()
    np.testing.assert_allclose([o["obstacle_distance"] for o in outs], OBSTACLE["s"] - stations, atol=1e-6)


def test_hold_at_the_stop_point_latches_with_a_zero_reference():
    blocker = {"s": 150.0, "lane": 1, "length": 100.0, "width": 2.0}
    planner = Planner(road="two_lane",
                      manoeuvre={"type": "obstacle_avoidance", "obstacles": [OBSTACLE, blocker]})
    start(planner)
    route, stop = planner.ref_route, planner.plan.ref.stop_s
    assert route.brake_from < route.final_from < stop
    inside = 0.5 * (route.final_from + stop)
    moving = planner.step(0.1, {**pose_on_ref(planner, inside), "vx": 0.5})
    assert moving["manoeuvre_state"] == 2.0 and moving["v_ref"] > 0.0
    early = planner.step(0.2, {**pose_on_ref(planner, route.final_from - 1.0), "vx": 0.005})
    assert early["manoeuvre_state"] == 2.0          # slow but before the final segment: no hold
    held = planner.step(0.3, {**pose_on_ref(planner, stop - 0.03), "vx": 0.005})
    assert held["manoeuvre_state"] == 3.0 and held["v_ref"] == 0.0
    assert np.all(held["ref_v"] == 0.0) and np.all(held["ref_a"] == 0.0)
    assert np.interp(stop - 0.03, planner.grid.s, route.v) > 0.0   # the plan itself still creeps there
    later = planner.step(0.4, {**pose_on_ref(planner, stop - 0.03), "vx": 0.02})
    assert later["manoeuvre_state"] == 3.0 and np.all(later["ref_v"] == 0.0)   # latched
    start(planner)                                   # a new run starts unheld
    assert planner.step(0.1, {**pose_on_ref(planner, 5.0), "vx": 0.0})["manoeuvre_state"] == 0.0


def test_plan_obstacles_ignores_obstacles_outside_the_lane():
    road = two_lane_road()
    ref, alt = plan_obstacles(road, 0, [Obstacle(s=100, lane=1, length=5, width=2)], 12.0, Comfort())
    assert ref.lateral.transitions == () and ref.stop_s is None and alt == ref


# ---- planner windows ------------------------------------------------------
@pytest.mark.parametrize("lane", [0, 1])
def test_windows_have_the_contract_shape_and_cover_the_preview(lane):
    planner = Planner(road="satory_standin", lane=lane)
    out = start(planner, *pose_on_ref_xy(lane))
    outs = [out] + drive(planner, [300.0, 1900.0, 2500.0])
    reach = 5.0 + 2 * 0.1 * planner.limits.v_max
    for o in outs:
        for prefix in ("ref", "alt"):
            for name, _, _ in FIELDS:
                arr = o[f"{prefix}_{name}"]
                assert arr.shape == (WINDOW_POINTS,) and arr.dtype == np.float64 and np.all(np.isfinite(arr))
            s = o[f"{prefix}_s"]
            assert s[0] == 0.0 and np.all(np.diff(s) > 0)
            # the vehicle's projection on the window lies after the first point and
            # at least `reach` before the last one
            win_idx = planner._indices(0.0)
            s_vehicle_on_window = float(np.interp(planner.progress, planner.grid.s[win_idx], s))
            assert 2.5 <= s_vehicle_on_window and s[-1] - s_vehicle_on_window >= reach


def pose_on_ref_xy(lane):
    """Start pose on the Satory stand-in's lane (lane 1 is 3.5 m left of the start)."""
    return 0.0, 3.5 * lane, 0.0


def test_ref_window_lies_on_the_lane_with_its_heading_and_curvature():
    planner = Planner(road="satory_standin", lane=1)
    start(planner, 0.0, 3.5)
    lane = planner.road.lane_centre(1)
    for o in drive(planner, [120.0, 700.0, 1500.0]):
        for x, y, psi, kappa in zip(o["ref_x"], o["ref_y"], o["ref_psi"], o["ref_kappa"]):
            proj = lane.project(x, y)
            assert proj.distance < 1e-6
            assert np.cos(proj.psi - psi) == pytest.approx(1.0, abs=1e-12)
            assert kappa == pytest.approx(proj.kappa, abs=1e-6)
        chords = np.hypot(np.diff(o["ref_x"]), np.diff(o["ref_y"]))
        assert np.all(np.diff(o["ref_s"]) >= chords - 1e-9)
        np.testing.assert_allclose(np.diff(o["ref_s"]), chords, rtol=2e-5)


def test_closed_loop_progress_unwraps_over_laps_and_headings_stay_continuous():
    planner = Planner(road="satory_standin", laps=2)
    start(planner)
    length = planner.road.length
    stations = np.concatenate([np.arange(0.0, length - 30.0, 20.0), np.arange(length - 30.0, length + 30.0, 1.3)])
    outs = drive(planner, stations)
    np.testing.assert_allclose([o["s_vehicle"] for o in outs], stations, atol=1e-6)
    for o, s in zip(outs, stations):
        psi_vehicle = pose_on_ref(planner, s)["psi"]
        assert abs(o["ref_psi"][0] - psi_vehicle) < 0.2
        assert np.max(np.abs(np.diff(o["ref_psi"]))) < 0.05
        assert o["lateral_offset"] == pytest.approx(0.0, abs=1e-6)


def test_lane_change_states_and_final_lane():
    planner = Planner(road={"builder": "two_lane", "length": 600, "radius": -150},
                      manoeuvre={"type": "lane_change", "at": 150.0, "to_lane": 1})
    start(planner)
    tr = planner.plan.ref.lateral.transitions[0]
    stations = np.arange(100.0, 300.0, 2.0)
    outs = drive(planner, stations)
    states = np.array([o["manoeuvre_state"] for o in outs])
    inside = (stations >= tr.s0) & (stations < tr.s1)
    assert np.all(states[inside] == 1.0) and np.all(states[~inside] == 0.0)
    assert all(abs(o["lateral_offset"]) < 1e-6 for o in outs)
    last = outs[-1]
    proj = planner.road.lane_centre(1).project(last["ref_x"][0], last["ref_y"][0])
    assert proj.distance < 1e-6
    # the alternative stays in the starting lane
    proj = planner.road.reference.project(last["alt_x"][-1], last["alt_y"][-1])
    assert proj.distance < 1e-6


def test_lane_keeping_alternative_changes_lane_from_the_vehicle():
    planner = Planner(road="two_lane")
    start(planner)
    out = drive(planner, [80.0])[0]
    offsets = np.array([planner.road.reference.project(x, y).lateral for x, y in zip(out["alt_x"], out["alt_y"])])
    behind = planner.grid.s[planner._indices(0.0)] <= 80.0
    np.testing.assert_allclose(offsets[behind], 0.0, atol=1e-9)
    assert np.all(np.diff(offsets) >= -1e-12) and offsets[-1] > 0.5
    np.testing.assert_allclose(out["alt_v"], out["ref_v"])


def test_launch_from_rest_has_a_positive_reference():
    planner = Planner(road="two_lane")
    out = start(planner)
    assert 0.0 < out["v_ref"] < 1.0
    assert out["ref_v"][0] == 0.0 and out["ref_a"].max() <= planner.limits.a_max + 1e-9


def test_planner_is_deterministic():
    def run():
        planner = Planner(road="satory_standin", manoeuvre={"type": "lane_change", "at": 60.0, "to_lane": 1})
        outs = [start(planner)] + drive(planner, np.arange(1.0, 120.0, 3.7))
        return b"".join(np.asarray(v, dtype=float).tobytes() for o in outs for v in o.values())
    assert run() == run()


@pytest.mark.parametrize("params, message", [
    ({"road": "nurburgring"}, "road.builder: unknown road 'nurburgring'"),
    ({"lane": 3}, "lane: expected a lane index 0..1, got 3"),
    ({"speed": {"v_max": 20}}, "speed.v_max: must stay below 50 km/h"),
    ({"manoeuvre": {"type": "drift"}}, "manoeuvre.type: unknown manoeuvre 'drift'"),
    ({"manoeuvre": {"type": "obstacle_avoidance", "obstacles": [{"s": 5, "lane": 0, "length": 2}]}},
     r"manoeuvre.obstacles\[0\]: expected keys s, lane, length, width"),
    ({"manoeuvre": {"type": "lane_change", "at": 10, "to_lane": 7}}, "manoeuvre.to_lane"),
    ({"laps": 0}, "laps: expected an integer >= 1"),
    ({"cones": [[1, 2]]}, r"cones: unknown parameters \['cones'\] \(known: road, lane, manoeuvre,"),
    ({"stop_at_end": "yes"}, "stop_at_end / start_from_rest: expected true or false"),
])
def test_bad_parameters_give_one_clear_message(params, message):
    with pytest.raises(ComponentError, match=message):
        Planner(**params)


def test_bad_inputs_and_lost_vehicle_are_reported():
    planner = Planner(road="two_lane")
    start(planner)
    with pytest.raises(ComponentError, match=r"input 'y' is nan at t = 0.3"):
        planner.step(0.3, {"x": 1.0, "y": float("nan"), "psi": 0.0, "vx": 1.0})
    with pytest.raises(ComponentError, match=r"at t = 0.4: vehicle at \(700.00, 0.00\) is 100.00 m from the road"):
        planner.step(0.4, {"x": 700.0, "y": 0.0, "psi": 0.0, "vx": 1.0})


def test_window_spacing_grows_for_a_short_window_budget():
    planner = Planner(road="two_lane", window_spacing=0.25, preview=20.0, planner_period=0.5)
    start(planner)
    out = drive(planner, [50.0])[0]
    reach = 20.0 + 2 * 0.5 * planner.limits.v_max
    assert out["ref_s"][-1] >= reach + planner.back
    assert planner.step_pts * ROUTE_DS > 0.25


def test_double_lane_change_with_offsets_and_lengths():
    spec = {"type": "lane_change", "changes": [{"at": 100.0, "to_offset": 2.0, "length": 30.0},
                                               {"at": 150.0, "to_offset": 0.0, "length": 25.0}]}
    planner = Planner(road="two_lane", manoeuvre=spec)
    start(planner)
    d, _, _ = planner.plan.ref.lateral.evaluate([99.0, 130.0, 140.0, 175.0, 300.0])
    np.testing.assert_allclose(d, [0.0, 2.0, 2.0, 0.0, 0.0], atol=1e-15)
    with pytest.raises(ComponentError, match=r"manoeuvre.changes\[1\]: expected at, one of to_lane"):
        Planner(road="two_lane", manoeuvre={"type": "lane_change", "changes": [{"at": 1, "to_lane": 1},
                                                                              {"at": 90}]})
    with pytest.raises(ComponentError, match="transitions overlap"):
        Planner(road="two_lane", manoeuvre={"type": "lane_change", "changes": [
            {"at": 100, "to_lane": 1}, {"at": 110, "to_lane": 0}]})


def test_routes_are_laid_out_once_per_parameters_and_first_state(monkeypatch):
    """A planner with the parameters and first vehicle state of an earlier one (a sweep's
    next sample on the same worker) reuses its routes and steps as if it had laid them out."""
    import controllers.planning.planner as planner_module

    monkeypatch.setattr(planner_module, "_routes", {})
    params = {"road": {"builder": "two_lane", "length": 600, "radius": 200},
              "manoeuvre": {"type": "obstacle_avoidance", "margin": 0.5, "obstacles": [OBSTACLE]},
              "speed": {"v_max": 10.0}}
    first, again = Planner(**params), Planner(**params)
    outputs = [start(first, vx=0.0)]
    assert start(again, vx=0.0).keys() == outputs[0].keys()
    assert again.ref_route is first.ref_route and again.grid is first.grid
    assert again.alt_route is first.alt_route
    monkeypatch.setattr(planner_module, "_routes", {})  # a planner that lays out its own
    alone = Planner(**params)
    reference = start(alone, vx=0.0)
    assert alone.ref_route is not first.ref_route
    stations = np.linspace(5.0, 400.0, 40)
    for shared, own in zip(drive(again, stations), drive(alone, stations)):
        assert shared.keys() == own.keys()
        for name, value in own.items():
            np.testing.assert_array_equal(shared[name], value, err_msg=name)
    for name, value in reference.items():
        np.testing.assert_array_equal(outputs[0][name], value, err_msg=name)
    # another speed limit, another first state: laid out afresh
    slower = Planner(**{**params, "speed": {"v_max": 8.0}})
    start(slower, vx=0.0)
    assert slower.ref_route is not alone.ref_route
    moved = Planner(**params)
    start(moved, vx=0.5)
    assert moved.ref_route is not alone.ref_route


def test_routes_of_a_road_read_from_a_file_are_not_kept():
    from controllers.planning.planner import _parameters_key

    assert _parameters_key({"road": {"opendrive": "/x/track.xodr", "road": "1"}}) is None
    assert _parameters_key({"road": "satory_standin", "speed": {"v_max": 1}}) != \
        _parameters_key({"road": "satory_standin", "speed": {"v_max": 1.0}})
    assert _parameters_key({"road": "satory_standin", "lane": object()}) is None
