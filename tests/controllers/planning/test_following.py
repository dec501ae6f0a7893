"""The vehicle-following manoeuvre: the time-gap policy, its bounds and the planner's lead inputs
(controllers.planning.following, the vehicle_following manoeuvre of controllers.planning.planner)."""

import math

import numpy as np
import pytest

from cosim.component import ComponentError
from controllers.planning.following import TimeGapPolicy, TimeGapSpeed, window_speed
from controllers.planning.planner import Planner
from controllers.spec import SpecError

DT = 0.1
FREE_ROAD = 100.0      # m/s: a road speed that never binds


def follow_point_mass(policy: TimeGapPolicy, lead_v, gap0: float, v0: float, seconds: float):
    """Close the policy's loop on a follower that tracks v_ref exactly (a point mass), lead at lead_v(t).

    Returns per planner step (t, gap, v, a) as arrays.
    """
    speed = TimeGapSpeed(policy, v0)
    gap, v, s_lead_rate = gap0, v0, lead_v(0.0)
    rows = [(0.0, gap, v, 0.0)]
    for k in range(1, int(round(seconds / DT)) + 1):
        t = k * DT
        v_prev = v
        v, a = speed.advance(policy.demand(gap, v, s_lead_rate), FREE_ROAD, 0.0, DT)
        v_lead_next = lead_v(t)
        gap += 0.5 * (s_lead_rate + v_lead_next) * DT - 0.5 * (v_prev + v) * DT
        s_lead_rate = v_lead_next
        rows.append((t, gap, v, a))
    return tuple(np.array(c) for c in zip(*rows))


@pytest.mark.parametrize("v_lead, time_gap, standstill", [(10.0, 1.5, 3.0), (4.0, 2.0, 5.0), (13.0, 1.0, 2.0)])
def test_constant_lead_speed_settles_at_the_analytic_gap(v_lead, time_gap, standstill):
    """Constant lead speed V: the only equilibrium is v = V, gap = standstill + time_gap * V."""
    policy = TimeGapPolicy(time_gap=time_gap, standstill=standstill)
    t, gap, v, a = follow_point_mass(policy, lambda t: v_lead, gap0=40.0, v0=0.6 * v_lead, seconds=120.0)
    expected = standstill + time_gap * v_lead
    assert gap[-1] == pytest.approx(expected, abs=1e-6)
    assert v[-1] == pytest.approx(v_lead, abs=1e-7)
    assert abs(a[-1]) < 1e-7
    assert policy.desired_gap(v_lead) == expected


def test_equilibrium_is_a_fixed_point_of_the_policy():
    policy = TimeGapPolicy()
    speed = TimeGapSpeed(policy, 12.0)
    for _ in range(50):
        v, a = speed.advance(policy.demand(policy.desired_gap(12.0), 12.0, 12.0), FREE_ROAD, 0.0, DT)
        assert (v, a) == (12.0, 0.0)


def _hard_stop(t: float) -> float:
    """Lead: 13 m/s, then -8 m/s2 (beyond d_max) to a stop at t = 11.625 s."""
    return max(0.0, 13.0 - 8.0 * max(t - 10.0, 0.0))


@pytest.mark.parametrize("a_max, d_max, j_max", [(1.5, 5.0, 5.0), (1.0, 3.0, 2.0), (2.0, 6.0, 10.0)])
def test_acceleration_and_jerk_bounds_hold_through_a_hard_stop_and_a_launch(a_max, d_max, j_max):
    policy = TimeGapPolicy(a_max=a_max, d_max=d_max, j_max=j_max)
    # start far behind a fast lead (full acceleration), then the lead brakes harder than d_max
    t, gap, v, a = follow_point_mass(policy, _hard_stop, gap0=60.0, v0=5.0, seconds=40.0)
    assert a.max() == pytest.approx(a_max) and a.min() == pytest.approx(-d_max)  # both bounds reached
    assert np.all(a <= a_max) and np.all(a >= -d_max)
    jerk = np.diff(a) / DT
    assert np.max(np.abs(jerk)) <= j_max * (1 + 1e-12)
    assert np.all(v >= 0.0)
    assert v[-1] < 0.05 and abs(a[-1]) < 0.05      # at rest behind the stopped lead ...
    assert np.all(gap > 0.0)                        # ... without touching it


@pytest.mark.parametrize("v0, a0", [(1.8, -4.0), (2.0, -4.0), (0.5, -2.0), (3.0, -1.0), (6.0, 0.0)])
def test_soft_landing_ends_braking_exactly_as_the_speed_reaches_zero(v0, a0):
    """The lead far too close: the policy wants d_max throughout, yet braking fades out at j_max
    and a reaches 0 at the step v_ref reaches 0, never earlier or later (from states with
    a^2 <= 2 j_max v, which are all the states the policy reaches from its start at a = 0)."""
    policy = TimeGapPolicy(j_max=5.0)
    speed = TimeGapSpeed(policy, v0)
    speed.a = a0
    rows = [(v0, a0)] + [speed.advance(-policy.d_max, FREE_ROAD, 0.0, DT) for _ in range(40)]
    v, a = np.array(rows).T
    stopped = int(np.argmax(v == 0.0))
    assert stopped > 0 and np.all(v[stopped:] == 0.0) and np.all(v[:stopped] > 0.0)
    assert abs(a[stopped]) < 1e-12 and np.all(a[stopped:] == pytest.approx(0.0, abs=1e-12))
    assert np.all(np.abs(np.diff(a)) <= policy.j_max * DT * (1 + 1e-12))
    assert np.all(a >= -policy.d_max)


def test_no_lead_in_range_follows_the_road_speed():
    policy = TimeGapPolicy()
    speed = TimeGapSpeed(policy, 5.0)
    for _ in range(400):
        v, a = speed.advance(None, 8.0, 0.0, DT)
    assert v == pytest.approx(8.0, abs=1e-9) and abs(a) < 1e-9


def test_policy_fields_and_errors():
    policy = TimeGapPolicy.from_spec({"time_gap": 2, "standstill": 4.0}, "manoeuvre")
    assert (policy.time_gap, policy.standstill, policy.d_max) == (2.0, 4.0, 5.0)
    with pytest.raises(SpecError, match="manoeuvre.time_gap: expected a positive"):
        TimeGapPolicy.from_spec({"time_gap": -1.0}, "manoeuvre")


def test_window_speed_carries_the_acceleration_and_respects_the_road():
    ahead = np.array([-3.0, 0.0, 5.0, 10.0, 40.0])
    v, a = window_speed(ahead, 10.0, -2.0, np.full(5, 20.0), np.zeros(5))
    np.testing.assert_allclose(v, [10.0, 10.0, math.sqrt(80.0), math.sqrt(60.0), 0.0])
    np.testing.assert_array_equal(a, [-2.0, -2.0, -2.0, -2.0, 0.0])
    road_v, road_a = np.array([20.0, 20.0, 9.0, 20.0, 20.0]), np.array([0.0, 0.0, -1.0, 0.0, 0.0])
    v, a = window_speed(ahead, 10.0, 0.0, road_v, road_a)
    np.testing.assert_array_equal(v, [10.0, 10.0, 9.0, 10.0, 10.0])
    np.testing.assert_array_equal(a, [0.0, 0.0, -1.0, 0.0, 0.0])


# ---- the planner with a lead ----------------------------------------------------
FOLLOW = {"type": "vehicle_following", "time_gap": 1.5, "standstill": 3.0}
SPEED = {"v_max": 13.0, "a_lat_max": 2.0, "a_max": 1.0, "d_max": 1.5, "j_max": 1.0}


def _planner(**overrides) -> Planner:
    params = dict(road={"builder": "two_lane", "length": 600, "radius": 150}, manoeuvre=FOLLOW, speed=SPEED)
    params.update(overrides)
    return Planner(**params)


def test_following_planner_declares_the_lead_ports_and_the_others_do_not():
    names = {p.name for p in _planner().inputs}
    assert {"lead_x", "lead_y", "lead_vx"} <= names
    assert {"gap", "gap_ref", "a_follow"} <= {p.name for p in _planner().outputs}
    keeping = _planner(manoeuvre={"type": "lane_keeping"})
    assert keeping.inputs == Planner.inputs and keeping.outputs == Planner.outputs


def test_planner_gap_is_along_the_road_bumper_to_bumper_and_sets_the_window_speed():
    planner = _planner()
    out = planner.initialize(0.0, {"x": 0.0, "y": 0.0, "psi": 0.0, "vx": 10.0,
                                   "lead_x": 30.0, "lead_y": 0.0, "lead_vx": 10.0})
    assert out["gap"] == pytest.approx(30.0 - 4.5, abs=1e-9)
    assert out["gap_ref"] == pytest.approx(3.0 + 1.5 * 10.0)
    assert out["v_ref"] == pytest.approx(10.0)
    # a lead in the bend: the gap is its arc length minus the follower's, not the chord
    road = planner.road.reference
    s_lead = 300.0
    x, y, _, _ = road.evaluate(np.array([s_lead]))
    out = planner.step(0.1, {"x": 0.0, "y": 0.0, "psi": 0.0, "vx": 10.0,
                             "lead_x": float(x[0]), "lead_y": float(y[0]), "lead_vx": 10.0})
    assert out["gap"] == pytest.approx(s_lead - 4.5, abs=1e-6)
    chord = math.hypot(float(x[0]), float(y[0])) - 4.5
    assert out["gap"] - chord > 1.0
    # too close: the policy brakes, and the window carries the braking ahead of the vehicle
    out = planner.step(0.2, {"x": 0.0, "y": 0.0, "psi": 0.0, "vx": 10.0,
                             "lead_x": 10.0, "lead_y": 0.0, "lead_vx": 5.0})
    assert out["a_follow"] < 0.0 and out["v_ref"] < 10.0
    assert np.all(np.diff(out["ref_v"]) <= 0.0) and out["ref_a"][-1] <= 0.0


@pytest.mark.parametrize("name, value", [("lead_vx", float("nan")), ("lead_x", None)])
def test_bad_lead_input_is_a_clear_error(name, value):
    planner = _planner()
    inputs = {"x": 0.0, "y": 0.0, "psi": 0.0, "vx": 10.0, "lead_x": 30.0, "lead_y": 0.0, "lead_vx": 10.0}
    if value is None:
        del inputs[name]
        match = f"input '{name}' missing at t = 0.0"
    else:
        inputs[name] = value
        match = f"input '{name}' is nan at t = 0.0"
    with pytest.raises(ComponentError, match=match):
        planner.initialize(0.0, inputs)


def test_lead_off_the_road_is_a_clear_error():
    planner = _planner()
    with pytest.raises(ComponentError, match="lead vehicle at .* has left the road"):
        planner.initialize(0.0, {"x": 0.0, "y": 0.0, "psi": 0.0, "vx": 10.0,
                                 "lead_x": 30.0, "lead_y": 500.0, "lead_vx": 10.0})


def test_unknown_following_field_is_refused():
    with pytest.raises(ComponentError, match=r"unknown keys \['headway'\] for vehicle_following"):
        _planner(manoeuvre={"type": "vehicle_following", "headway": 1.0})
