"""Window projection against analytic cases: a line, a circle, a clothoid-like ramp, the ends."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.trajectory import TrajectoryWindow
from controllers.road.projection import (WindowError, point_at, project, validate_window,
                                           wrap_angle)
from tests.helpers.closed_loop import CirclePath, LinePath, make_window


def test_line_projection_is_exact():
    window = make_window(LinePath(), sigma0=10.0, v=7.0, a=0.5)
    proj = project(window, 30.25, -1.5)
    assert proj.s == pytest.approx(20.25, abs=1e-12)
    assert proj.offset == pytest.approx(-1.5, abs=1e-12)
    assert (proj.x, proj.y) == pytest.approx((30.25, 0.0), abs=1e-12)
    assert proj.psi_path == 0.0 and proj.kappa == 0.0 and proj.dkappa_ds == 0.0
    assert (proj.v, proj.a, proj.extrapolated) == (7.0, 0.5, 0)


@pytest.mark.parametrize("radius, inside", [(50.0, 1.0), (50.0, -2.0), (20.0, 0.3), (200.0, -0.7)])
def test_circle_projection_matches_geometry(radius, inside):
    path = CirclePath(radius)
    window = make_window(path, sigma0=3.0)
    for sigma in (7.3, 21.0, 40.6):
        angle = sigma / radius
        # a point `inside` metres towards the centre from the path point at arc length sigma
        px = (radius - inside) * math.sin(angle)
        py = radius - (radius - inside) * math.cos(angle)
        proj = project(window, px, py)
        assert proj.offset == pytest.approx(inside, abs=2e-6)
        assert proj.s == pytest.approx(sigma - 3.0, abs=2e-5)
        assert proj.psi_path == pytest.approx(angle, abs=2e-6)
        assert proj.kappa == pytest.approx(1.0 / radius, abs=1e-12)


def test_curvature_gradient_and_interpolation():
    # a clothoid-like window: kappa = 0.001 s, fields interpolated linearly in s
    s = np.arange(10, dtype=float)
    kappa = 0.001 * s
    psi = 0.0005 * s**2
    x = np.concatenate([[0.0], np.cumsum(np.cos(0.5 * (psi[1:] + psi[:-1])))])
    y = np.concatenate([[0.0], np.cumsum(np.sin(0.5 * (psi[1:] + psi[:-1])))])
    window = TrajectoryWindow(x=x, y=y, psi=psi, kappa=kappa, s=s, v=2.0 * s, a=np.ones(10))
    proj = project(window, x[4] + 0.5 * (x[5] - x[4]), y[4] + 0.5 * (y[5] - y[4]))
    assert proj.dkappa_ds == pytest.approx(0.001, rel=1e-12)
    assert proj.s == pytest.approx(4.5, abs=1e-3)
    assert proj.kappa == pytest.approx(0.001 * proj.s, rel=1e-9)
    assert proj.v == pytest.approx(2.0 * proj.s, rel=1e-9)


def test_before_and_after_window_extrapolate_along_end_tangents():
    path = CirclePath(50.0)
    window = make_window(path, sigma0=0.0, points=11)
    before = project(window, -4.0, 0.5)        # behind the start, which heads east at the origin
    assert before.extrapolated == -1
    assert (before.s, before.offset, before.psi_path) == pytest.approx((-4.0, 0.5, 0.0), abs=1e-12)
    end_heading = 10.0 / 50.0
    ex, ey = window.x[-1], window.y[-1]
    tx, ty = math.cos(end_heading), math.sin(end_heading)
    after = project(window, ex + 3.0 * tx - 0.25 * ty, ey + 3.0 * ty + 0.25 * tx)
    assert after.extrapolated == 1
    assert after.s == pytest.approx(13.0, abs=1e-12)
    assert after.offset == pytest.approx(0.25, abs=1e-12)
    assert after.psi_path == pytest.approx(end_heading, abs=1e-15)
    assert after.kappa == 1.0 / 50.0 and after.dkappa_ds == 0.0
    assert point_at(window, 13.0) == pytest.approx((ex + 3.0 * tx, ey + 3.0 * ty), abs=1e-12)


def test_point_at_on_circle():
    path = CirclePath(30.0)
    window = make_window(path, sigma0=2.0)
    for s in (0.0, 5.5, 17.25, 63.0):
        expected_x, expected_y, _, _ = path.point(np.array([2.0 + s]))
        assert point_at(window, s) == pytest.approx((expected_x[0], expected_y[0]), abs=2e-5)


def test_validation_names_field_index_and_value():
    window = make_window(LinePath(), sigma0=0.0, points=5)
    bad_s = TrajectoryWindow(**{**window.__dict__, "s": np.array([0.0, 1.0, 1.0, 3.0, 4.0])})
    with pytest.raises(WindowError, match=r"ref_s must increase strictly: ref_s\[1\] = 1.0, ref_s\[2\] = 1.0"):
        validate_window(bad_s, "ref")
    bad_kappa = TrajectoryWindow(**{**window.__dict__, "kappa": np.array([0.0, np.nan, 0.0, 0.0, 0.0])})
    with pytest.raises(WindowError, match=r"alt_kappa\[1\] is not finite"):
        validate_window(bad_kappa, "alt")


def test_wrap_angle():
    assert wrap_angle(3.0 * math.pi / 2.0) == pytest.approx(-math.pi / 2.0)
    assert wrap_angle(-0.1) == pytest.approx(-0.1)
    assert wrap_angle(2.0 * math.pi + 0.2) == pytest.approx(0.2)
