"""Reference speed profile: every comfort bound, start/stop, consistency (controllers.planning.speed_profile)."""

import numpy as np
import pytest

from controllers.road.geometry import SpecError
from controllers.road.builders import satory_standin
from controllers.planning.speed_profile import SpeedLimits, plan_speed
from controllers.planning.speed_stop import segment_length, segment_phases, segment_samples

DS = 0.5


@pytest.fixture(scope="module")
def satory_curvature():
    path = satory_standin().reference
    return path.evaluate(np.arange(0.0, path.length, DS))[3]


def jerk(profile) -> np.ndarray:
    """Discrete jerk v da/ds at interior points whose stencil lies before the final stop segment
    (that segment is checked in time, where it is defined: see test_final_stop_segment_*)."""
    inner = profile.v[1:-1] * (profile.a[2:] - profile.a[:-2]) / (2 * DS)
    end = np.inf if profile.final_from is None else profile.final_from
    return inner[profile.s[2:] <= end]


@pytest.mark.parametrize("limits", [SpeedLimits(), SpeedLimits(v_max=13.5, a_lat_max=3.0, a_max=2.0,
                                                                d_max=2.5, j_max=0.7)])
def test_profile_respects_every_bound_and_starts_and_ends_at_rest(satory_curvature, limits):
    prof = plan_speed(satory_curvature, DS, limits)
    tiny = 1e-9
    assert prof.v[0] == 0.0 and prof.v[-1] == 0.0 and prof.a[-1] == 0.0
    assert prof.final_from is not None and prof.s[-1] - prof.final_from < 30.0
    assert prof.v.max() <= limits.v_max + tiny
    assert np.max(prof.v ** 2 * np.abs(satory_curvature)) <= limits.a_lat_max + tiny
    assert prof.a.max() <= limits.a_max + tiny and prof.a.min() >= -limits.d_max - tiny
    assert np.abs(jerk(prof)).max() <= limits.j_max + tiny


def test_profile_is_not_needlessly_slow(satory_curvature):
    limits = SpeedLimits()
    prof = plan_speed(satory_curvature, DS, limits)
    # the 380 m straights are long enough to reach v_max exactly
    assert prof.v.max() == pytest.approx(limits.v_max, abs=1e-12)
    # in the 50 m radius arc the speed reaches the lateral limit sqrt(a_lat R)
    in_tight = np.isclose(np.abs(satory_curvature), 1 / 50, rtol=1e-12)
    assert prof.v[in_tight].max() == pytest.approx(np.sqrt(limits.a_lat_max * 50), rel=1e-9)


def test_acceleration_is_v_dv_ds(satory_curvature):
    prof = plan_speed(satory_curvature, DS, SpeedLimits())
    u = 0.5 * prof.v ** 2
    numeric = (u[2:] - u[:-2]) / (2 * DS)  # v dv/ds = du/ds
    moving = prof.v[1:-1] > 2.0          # away from the sqrt singularity at rest
    moving &= prof.s[2:] <= prof.final_from   # the final segment is checked in time (below)
    np.testing.assert_allclose(prof.a[1:-1][moving], numeric[moving], atol=5e-4)  # O(ds^2) differences


def test_straight_line_profile_matches_the_analytic_smoothing():
    # On a straight from rest with no stop, u = v^2/2 rises as u = a s in the
    # envelope; the min filter then moving average of width W turn the corner
    # at s = 0 into a parabola: u = a (s + W/2)^2 / (2 W) for |s| <= W/2 (with
    # the grid's discrete offsets), then u = a s further on.
    limits = SpeedLimits(v_max=13.0, a_max=1.0, d_max=1.0, j_max=1.0)
    prof = plan_speed(np.zeros(2000), DS, limits, start_from_rest=True, stop_at_end=False)
    half = int(np.ceil(limits.v_max / limits.j_max / DS))
    width = 2 * half + 1
    i = np.arange(60, 2 * half)
    # eroded e[j] = a max(j - half, 0) ds; u[i] = mean of e[i-half .. i+half]
    m = np.arange(-half, half + 1)[None, :] + i[:, None]
    expected = (limits.a_max * DS * np.maximum(m - half, 0)).sum(axis=1) / width
    np.testing.assert_allclose(0.5 * prof.v[i] ** 2, expected, rtol=1e-12, atol=1e-12)
    assert prof.v[-1] == pytest.approx(13.0)


def test_not_from_rest_starts_at_the_given_speed():
    limits = SpeedLimits()
    prof = plan_speed(np.zeros(400), DS, limits, start_from_rest=False, stop_at_end=False, v_start=6.0)
    assert prof.v[0] == pytest.approx(6.0, abs=1e-9)
    # a(0) is the one-sided difference of u, whose second derivative is at most 2 A / W
    curv_bound = limits.j_max / limits.v_max
    assert 0.0 <= prof.a[0] <= curv_bound * DS
    assert prof.v[-1] == pytest.approx(12.0)


def test_profile_is_deterministic(satory_curvature):
    a = plan_speed(satory_curvature, DS, SpeedLimits())
    b = plan_speed(satory_curvature.copy(), DS, SpeedLimits())
    assert a.v.tobytes() == b.v.tobytes() and a.a.tobytes() == b.a.tobytes()


def test_lookup_interpolates_and_holds_beyond_the_ends():
    prof = plan_speed(np.zeros(400), DS, SpeedLimits(), s0=10.0)
    v, a = prof.at([5.0, 10.0 + 0.75, 10.0 + 399 * DS + 3])
    assert v[0] == 0.0 and a[0] == 0.0 and v[2] == 0.0 and a[2] == 0.0
    assert v[1] == pytest.approx(0.5 * (prof.v[1] + prof.v[2]))


@pytest.mark.parametrize("spec, message", [
    ({"v_max": 14.0}, "speed.v_max: must stay below 50 km/h"),
    ({"a_max": -1}, "speed.a_max: expected a positive finite number, got -1"),
    ({"a_lat": 2}, r"speed: unknown keys \['a_lat'\]"),
    ({"j_max": "soft"}, "speed.j_max: expected a number, got 'soft'"),
])
def test_bad_limits_name_the_field(spec, message):
    with pytest.raises(SpecError, match=message):
        SpeedLimits.from_spec(spec)


def test_bad_curvature_is_rejected():
    with pytest.raises(SpecError, match="finite"):
        plan_speed(np.array([0.0, np.nan, 0.0]), DS, SpeedLimits())


LIMIT_SETS = [SpeedLimits(), SpeedLimits(v_max=13.5, a_lat_max=3.0, a_max=2.0, d_max=2.5, j_max=0.7),
              SpeedLimits(d_max=1.0, j_max=2.0), SpeedLimits(v_max=5.0, d_max=0.5, j_max=5.0),
              SpeedLimits(d_max=3.0, j_max=0.3)]


@pytest.mark.parametrize("limits", LIMIT_SETS)
def test_final_stop_segment_reaches_rest_at_the_stop_point_within_the_bounds(limits):
    prof = plan_speed(np.zeros(800), DS, limits)          # 400 m straight, from rest, to a stop
    s_join, s_stop = prof.final_from, prof.s[-1]
    assert s_join is not None and s_join < s_stop
    before = prof.s <= s_join
    v1, a1 = prof.final_state
    assert prof.v[before][-1] >= v1 >= prof.v[~before][0]      # decreasing through the join
    assert np.all(np.diff(prof.v[prof.s >= s_join - 20.0]) <= 0.0)   # no wobble on the way to rest
    t, x, v, a = segment_samples(v1, a1, limits.j_max, limits.d_max)
    # the segment covers exactly the distance left and ends at rest, a and v zero together
    assert x[-1] == pytest.approx(s_stop - s_join, rel=1e-9)
    assert v[-1] == 0.0 and a[-1] == 0.0 and np.all(v >= 0.0) and np.all(np.diff(x) >= 0.0)
    # bounded deceleration and jerk, exactly, in time
    assert a.min() >= -limits.d_max - 1e-12 and a.max() <= 1e-12
    rate = np.diff(a) / np.diff(t)
    # a = dv/dt (mean over each sample interval; a phase change inside one costs up to j dt / 4)
    np.testing.assert_allclose(np.diff(v) / np.diff(t), 0.5 * (a[1:] + a[:-1]),
                               atol=limits.j_max * np.diff(t).max())
    assert np.all(np.abs(rate) <= limits.j_max * (1 + 1e-9))
    # finite time: dt = dx / v integrated along the segment equals its duration
    duration = float(sum(segment_phases(v1, a1, limits.j_max, limits.d_max)[0]))
    assert t[-1] == pytest.approx(duration, rel=1e-12) and duration < 2 * limits.d_max / limits.j_max + 5.0
    # the profile on the grid after the join is the segment, 0 from the stop point on
    after = ~before
    np.testing.assert_allclose(prof.v[after], np.interp(prof.s[after] - s_join, x * (s_stop - s_join) / x[-1], v),
                               atol=1e-12)
    assert prof.v[-1] == 0.0 and prof.at(s_stop + 5.0)[0] == 0.0
    # continuity at the join: the segment starts from the profile's speed and acceleration
    assert v[0] == v1 and a[0] == min(a1, 0.0) and a1 <= 0.0


def test_segment_length_matches_the_sampled_integral_and_the_closed_forms():
    j, d = 1.0, 1.5
    # two phases only (peak below d): v1 = 0.8, a1 = -0.3
    (t1, t2, t3), _ = segment_phases(0.8, -0.3, j, d)
    assert t2 == 0.0 and t3 == pytest.approx(np.sqrt(0.5 * 0.09 + 0.8))
    t, x, v, a = segment_samples(0.8, -0.3, j, d)
    np.testing.assert_allclose(x[-1], np.trapezoid(v, t), rtol=1e-6)
    assert x[-1] == pytest.approx(float(segment_length(0.8, -0.3, j, d)), rel=1e-12)
    # from the constant-deceleration line: a pure release phase of d/j at the end
    (t1, t2, t3), _ = segment_phases(6.0, -d, j, d)
    assert t1 == 0.0 and t3 == pytest.approx(d / j)
    last = t >= t[-1] - t3
    t, x, v, a = segment_samples(6.0, -d, j, d)
    release = t >= t[-1] - t3
    tau = t[-1] - t[release]
    np.testing.assert_allclose(v[release], 0.5 * j * tau ** 2, atol=1e-9)          # v = j tau^2 / 2
    np.testing.assert_allclose(x[-1] - x[release], j * tau ** 3 / 6.0, atol=1e-9)   # x = j tau^3 / 6
    assert last.any()


def test_a_follower_of_the_profile_reaches_the_stop_point_in_finite_time():
    limits = SpeedLimits()
    prof = plan_speed(np.zeros(800), DS, limits)
    # a point that moves at exactly v(s), from the join: integrate in time with a fine step
    s, t, dt = prof.final_from, 0.0, 1e-4
    while s < prof.s[-1] - 1e-6 and t < 20.0:
        s += dt * float(prof.at(s)[0])
        t += dt
    assert prof.s[-1] - s < 1e-3 and t < 10.0        # the old tail (v ~ distance) never got there


@pytest.mark.parametrize("radius, length", [(10.0, 30.0), (3.0, 15.0), (1.5, 10.0)])
def test_stop_in_a_tight_curve_keeps_the_curve_limit_and_still_ends_at_rest(radius, length):
    limits = SpeedLimits()
    kappa = np.zeros(800)
    kappa[-int(length / DS):] = 1.0 / radius             # the stop point lies in the curve
    prof = plan_speed(kappa, DS, limits)
    v_curve = np.sqrt(limits.a_lat_max * radius)
    assert prof.final_from is not None and prof.v[-1] == 0.0 and prof.a[-1] == 0.0
    assert np.all(prof.v[kappa != 0.0] <= v_curve + 1e-9) and prof.v.max() <= limits.v_max + 1e-9
    assert prof.a.min() >= -limits.d_max - 1e-9
    assert np.abs(jerk(prof)).max() <= limits.j_max + 1e-9
