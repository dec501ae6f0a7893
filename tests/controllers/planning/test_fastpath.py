"""The planner's per-step shortcuts give the plain computation's values bit for bit.

The lane keeping alternative (a lane change starting at the vehicle) is laid
out again at every planner step, so its code avoids np.clip, np.full, the
re-evaluation of sin/cos of the reference heading and a LateralPlan per step.
These tests recompute the same quantities with the plain expressions and
compare the raw bytes.
"""

import numpy as np
import pytest

from controllers.planning.manoeuvres import LateralPlan, Transition, offset_profile, transition_length
from controllers.planning.planner import ROUTE_DS, Planner
from controllers.road.builders import frenet_from_base, two_lane_road
from controllers.trajectory import WINDOW_POINTS


def plain_profile(d_start, transitions, s):
    """(d, dd, ddd) with the plain expressions (np.clip, np.full, temporaries)."""
    s = np.asarray(s, dtype=float)
    d = np.full(s.shape, float(d_start))
    d1, d2 = np.zeros(s.shape), np.zeros(s.shape)
    for tr in transitions:
        t = np.clip((s - tr.s0) * (1.0 / tr.length), 0.0, 1.0)
        big = tr.d1 - tr.d0
        d += big * (t * t) * t * (10.0 + t * (6.0 * t - 15.0))
        d1 += (30.0 * big / tr.length) * (t * t) * (1.0 - t) * (1.0 - t)
        d2 += (60.0 * big / tr.length ** 2) * t * (1.0 - t) * (1.0 - 2.0 * t)
    return d, d1, d2


def same_bits(a, b) -> bool:
    """True if two float arrays hold exactly the same bytes."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("d_start, transitions", [
    (0.0, (Transition(10.3, 37.7, 0.0, 3.5),)),
    (3.5, (Transition(0.0, 20.0, 3.5, 0.0),)),                 # to the right: big < 0, signed zeros
    (0.2, (Transition(5.0, 21.0, 0.2, 3.7), Transition(40.0, 25.5, 3.7, -0.4))),
])
def test_offset_profile_is_the_plain_quintic_bit_for_bit(d_start, transitions):
    s = np.linspace(-7.0, 90.0, 3881)
    fast = offset_profile(d_start, transitions, s)
    plain = plain_profile(d_start, transitions, s)
    assert all(same_bits(f, p) for f, p in zip(fast, plain))
    assert all(same_bits(f, p) for f, p in zip(LateralPlan(d_start, transitions).evaluate(s), fast))
    assert fast[0][-1] == pytest.approx(transitions[-1].d1, abs=1e-12)      # and it is the quintic


def test_frenet_with_known_heading_trig_is_bit_identical():
    road = two_lane_road(length=400.0, radius=150.0)
    s = np.arange(0.0, 400.0, ROUTE_DS)
    x, y, psi, k = road.reference.evaluate(s)
    base = (x, y, np.unwrap(psi), k, road.reference.dkappa(s))
    profile = offset_profile(0.0, (Transition(120.0, 60.0, 0.0, 3.5),), s)
    plain = frenet_from_base(base, *profile, s)
    fast = frenet_from_base(base, *profile, s, trig=(np.sin(base[2]), np.cos(base[2])))
    assert all(same_bits(f, p) for f, p in zip(fast, plain))
    assert np.ptp(plain[3]) > 1.0 / 200.0        # the bend and the lane change are in there


def plain_alt_window(planner: Planner, vx: float, psi_shift: float) -> dict:
    """The dynamic alternative window laid out the plain way on the window's grid slice."""
    idx = planner._indices(0.0)
    grid, ref = planner.grid, planner.ref_route
    d_now = float(np.interp(planner.progress, grid.s, ref.d))
    d_to = planner.road.lane_offset(planner.plan.alt_lane)
    length = transition_length(d_to - d_now, min(max(vx, 3.0), planner.limits.v_max), planner.plan.comfort)
    sl = slice(idx.start, idx.stop)
    s = grid.s[sl]
    lateral = LateralPlan(d_now, (Transition(planner.progress, length, d_now, d_to),))
    x, y, psi, kappa, g = frenet_from_base(tuple(b[sl] for b in grid.base), *plain_profile(
        lateral.d_start, lateral.transitions, s), s)
    sigma = np.concatenate([[0.0], np.cumsum(0.5 * ROUTE_DS * (g[1:] + g[:-1]))])
    sub = slice(None, None, idx.step)
    return {"alt_x": x[sub], "alt_y": y[sub], "alt_psi": psi[sub] + psi_shift, "alt_kappa": kappa[sub],
            "alt_s": sigma[sub], "alt_v": ref.v[idx], "alt_a": ref.a[idx]}


def test_lane_keeping_alternative_window_matches_the_plain_layout():
    planner = Planner(road={"builder": "two_lane", "length": 600, "radius": 150}, lane=0,
                      manoeuvre={"type": "lane_keeping"}, speed={"v_max": 12.0})
    ref = planner.road.reference
    x, y, psi, _ = (float(v[0]) for v in ref.evaluate(np.array([2.0])))
    planner.initialize(0.0, {"x": x, "y": y, "psi": psi, "vx": 10.0})
    checked = 0
    for k, (s, vx, d) in enumerate([(5.0, 10.0, 0.0), (170.3, 12.0, 0.4), (260.9, 2.0, -0.3), (333.3, 7.5, 0.1)]):
        x, y, psi, _ = (float(v[0]) for v in ref.evaluate(np.array([s])))
        pose = {"x": x - d * np.sin(psi), "y": y + d * np.cos(psi), "psi": psi, "vx": vx}
        out = planner.step(0.1 * (k + 1), pose)
        idx = planner._indices(0.0)
        shift = 2 * np.pi * round((psi - planner.ref_route.psi[idx.start]) / (2 * np.pi))
        for name, value in plain_alt_window(planner, vx, shift).items():
            assert value.shape == (WINDOW_POINTS,) and same_bits(out[name], value), (s, name)
            checked += 1
        assert out["lateral_offset"] == pytest.approx(d, abs=0.05)
    assert checked == 4 * 7
