"""Paths, roads and track builders against analytic geometry (controllers.road.geometry, controllers.road.builders)."""

from math import factorial

import numpy as np
import pytest

from controllers.road.geometry import Path, SpecError
from controllers.road.builders import Road, frenet_to_world, road_from_spec, satory_standin, two_lane_road


def fresnel_reference(c: float, length: float) -> tuple[float, float]:
    """(int_0^L cos(c u^2/2) du, int_0^L sin(c u^2/2) du) by their power series."""
    cx = sum((-1) ** n * (c / 2) ** (2 * n) * length ** (4 * n + 1) / (factorial(2 * n) * (4 * n + 1))
             for n in range(30))
    sy = sum((-1) ** n * (c / 2) ** (2 * n + 1) * length ** (4 * n + 3) / (factorial(2 * n + 1) * (4 * n + 3))
             for n in range(30))
    return cx, sy


def test_line_is_exact():
    path = Path.from_spec({"segments": [{"line": 100}], "start": {"x": 1, "y": 2, "heading_deg": 30}})
    s = np.linspace(0, 100, 11)
    x, y, psi, kappa = path.evaluate(s)
    assert path.length == 100
    np.testing.assert_allclose(x, 1 + s * np.cos(np.pi / 6), atol=1e-12)
    np.testing.assert_allclose(y, 2 + s * np.sin(np.pi / 6), atol=1e-12)
    np.testing.assert_allclose(psi, np.pi / 6, atol=1e-15)
    assert np.all(kappa == 0)


@pytest.mark.parametrize("angle", [90.0, -135.0])
def test_circle_arc_length_heading_curvature(angle):
    radius = 50.0
    path = Path.from_spec({"segments": [{"arc": {"radius": radius, "angle": angle}}]})
    sign = np.sign(angle)
    assert path.length == pytest.approx(radius * np.radians(abs(angle)), rel=1e-14)
    s = np.linspace(0, path.length, 37)
    x, y, psi, kappa = path.evaluate(s)
    np.testing.assert_allclose(x, radius * np.sin(s / radius), atol=1e-10)
    np.testing.assert_allclose(y, sign * radius * (1 - np.cos(s / radius)), atol=1e-10)
    np.testing.assert_allclose(psi, sign * s / radius, atol=1e-12)
    np.testing.assert_allclose(kappa, sign / radius, rtol=1e-14)


def test_arc_length_form_with_signed_radius_turns_right():
    path = Path.from_spec({"segments": [{"arc": {"length": 20.0, "radius": -40.0}}]})
    x, y, psi, kappa = path.evaluate([20.0])
    assert psi[0] == pytest.approx(-0.5) and kappa[0] == pytest.approx(-1 / 40)
    assert y[0] == pytest.approx(-40 * (1 - np.cos(0.5)), abs=1e-10)


def test_clothoid_curvature_linear_and_endpoint_matches_fresnel_series():
    length, k1 = 120.0, 1 / 60.0
    path = Path.from_spec({"segments": [{"clothoid": {"length": length, "kappa_start": 0, "kappa_end": k1}}]})
    s = np.linspace(0, length, 25)
    _, _, psi, kappa = path.evaluate(s)
    np.testing.assert_allclose(kappa, k1 * s / length, atol=1e-15)
    np.testing.assert_allclose(psi, k1 * s ** 2 / (2 * length), atol=1e-13)
    x, y, _, _ = path.evaluate([length])
    cx, sy = fresnel_reference(k1 / length, length)
    assert abs(x[0] - cx) < 1e-9 and abs(y[0] - sy) < 1e-9


def test_vectorised_and_scalar_evaluation_agree():
    path = satory_standin().reference
    s = np.random.default_rng(3).uniform(-50, path.length + 50, 200)
    x, y, psi, kappa = path.evaluate(s)
    wrapped = np.mod(psi + np.pi, 2 * np.pi)
    for i, si in enumerate(s):
        px, py, ppsi, pk = path._point(float(si))
        assert (px, py, pk) == pytest.approx((x[i], y[i], kappa[i]), abs=1e-9)
        assert np.mod(ppsi + np.pi, 2 * np.pi) == pytest.approx(wrapped[i], abs=1e-12)


def test_projection_on_circle_distance_is_radius_gap():
    radius = 80.0
    path = Path.from_spec({"segments": [{"arc": {"radius": radius, "angle": 360}}], "closed": True})
    rng = np.random.default_rng(7)
    for _ in range(60):
        theta = rng.uniform(0, 2 * np.pi)
        r = radius + rng.uniform(-30, 30)
        px, py = r * np.sin(theta), radius - r * np.cos(theta)   # centre (0, R)
        proj = path.project(px, py, heading=theta + 0.1)
        assert proj.distance == pytest.approx(abs(r - radius), abs=1e-8)
        assert proj.lateral == pytest.approx(radius - r, abs=1e-8)       # inside = left
        assert proj.s == pytest.approx(radius * theta, abs=1e-7)
        assert proj.heading_error == pytest.approx(0.1, abs=1e-9)
        assert proj.kappa == pytest.approx(1 / radius)


def test_warm_start_keeps_the_branch_on_a_hairpin():
    # Two parallel legs 12 m apart joined by a half circle.
    path = Path.from_spec({"segments": [{"line": 100}, {"arc": {"radius": 6, "angle": 180}}, {"line": 100}]})
    s_back = 100 + 6 * np.pi + 50.0          # on the return leg, x = 50, y = 12
    cold = path.project(50.0, 5.0)            # nearer the outbound leg
    warm = path.project(50.0, 5.0, s_guess=s_back - 1.0, search=20.0)
    assert cold.s == pytest.approx(50.0, abs=1e-9) and cold.lateral == pytest.approx(5.0)
    assert warm.s == pytest.approx(s_back, abs=1e-9) and warm.lateral == pytest.approx(7.0)  # heading west: south is left


def test_closed_loop_wraps_in_evaluation_and_projection():
    path = satory_standin().reference
    s = np.array([0.0, 10.0, 1234.5])
    a = np.array(path.evaluate(s)[:2])
    b = np.array(path.evaluate(s + path.length)[:2])
    c = np.array(path.evaluate(s - 2 * path.length)[:2])
    np.testing.assert_allclose(a, b, atol=1e-9)
    np.testing.assert_allclose(a, c, atol=1e-9)
    x, y, psi, _ = path.evaluate([path.length - 0.3])
    proj = path.project(x[0], y[0], s_guess=0.2)
    assert proj.s == pytest.approx(path.length - 0.3, abs=1e-8)
    proj = path.project(0.4, 0.0, s_guess=path.length - 0.2)
    assert proj.s == pytest.approx(0.4, abs=1e-9)


def test_wrap_of_a_float_is_np_mod_bit_for_bit():
    # Path.wrap takes Python's % for a float (the planner's per-step progress) and np.mod otherwise
    path = satory_standin().reference
    rng = np.random.default_rng(7)
    values = np.concatenate([rng.uniform(-3.0, 3.0, 5000) * path.length,
                             [0.0, -0.0, path.length, -path.length, 2.0 * path.length, 1e-320, -1e-320]])
    wrapped = np.array([path.wrap(float(v)) for v in values])
    assert all(type(path.wrap(float(v))) is float for v in values[:10])
    assert wrapped.tobytes() == np.mod(values, path.length).tobytes()
    assert path.wrap(values).tobytes() == wrapped.tobytes()


def test_open_path_extends_along_end_tangents():
    path = Path.from_spec({"segments": [{"arc": {"radius": 20, "angle": 90}}]})
    x, y, psi, kappa = path.evaluate([path.length + 5.0, -3.0])
    assert (x[0], y[0], psi[0], kappa[0]) == pytest.approx((20.0, 25.0, np.pi / 2, 0.0), abs=1e-10)
    assert (x[1], y[1], psi[1], kappa[1]) == pytest.approx((-3.0, 0.0, 0.0, 0.0), abs=1e-12)


def test_offset_of_a_circle_is_a_concentric_circle():
    radius, d = 50.0, 3.5
    base = Path.from_spec({"segments": [{"arc": {"radius": radius, "angle": 360}}], "closed": True})
    lane = base.offset(d)
    assert lane.closed and lane.length == pytest.approx(2 * np.pi * (radius - d), rel=1e-12)
    x, y, psi, kappa = lane.evaluate(np.linspace(0, lane.length, 50))
    np.testing.assert_allclose(np.hypot(x, y - radius), radius - d, atol=1e-9)
    np.testing.assert_allclose(kappa, 1 / (radius - d), rtol=1e-12)
    with pytest.raises(SpecError, match="centre of curvature"):
        base.offset(60.0)


def test_curvature_profile_path_matches_segments():
    a = Path.from_curvature([0, 30, 80, 110], [0, 0.02, 0.02, 0.0])
    b = Path.from_spec({"segments": [{"clothoid": {"length": 30, "kappa_start": 0, "kappa_end": 0.02}},
                                     {"arc": {"length": 50, "radius": 50}},
                                     {"clothoid": {"length": 30, "kappa_start": 0.02, "kappa_end": 0}}]})
    s = np.linspace(0, 110, 23)
    for u, v in zip(a.evaluate(s), b.evaluate(s)):
        np.testing.assert_allclose(u, v, atol=1e-10)


def test_waypoint_spline_passes_through_points_and_fits_a_circle():
    pts = np.array([[0, 0], [20, 5], [40, -3], [60, 0], [80, 10]], dtype=float)
    path = Path.from_waypoints(pts)
    for p in pts:
        assert path.project(*p).distance < 1e-9
    radius = 40.0
    ang = np.linspace(0, 2 * np.pi, 41)[:-1]
    ring = Path.from_spec({"waypoints": np.c_[radius * np.cos(ang), radius * np.sin(ang)].tolist(),
                           "closed": True})
    x, y, _, kappa = ring.evaluate(np.linspace(0, ring.length, 200))
    assert ring.closed and ring.length == pytest.approx(2 * np.pi * radius, rel=1e-5)
    np.testing.assert_allclose(np.hypot(x, y), radius, atol=2e-4)
    np.testing.assert_allclose(kappa, 1 / radius, rtol=5e-3)


@pytest.mark.parametrize("spec, message", [
    ({"segments": [{"spiral": 3}]}, r"path.segments\[0\]: unknown segment kind 'spiral'"),
    ({"segments": [{"line": 5}, {"arc": {"radius": -5, "angle": 30}}]}, r"segments\[1\].arc.radius"),
    ({"segments": [{"line": 5}, {"arc": {"radius": 5}}]}, r"segments\[1\].arc: expected keys"),
    ({"segments": [{"line": "far"}]}, r"segments\[0\].line: expected a number, got 'far'"),
    ({"segments": [{"line": 100}], "closed": True}, "does not close: end misses start by 100"),
    ({"waypoints": [[0, 0], [0, 0], [1, 1]]}, "coincide"),
    ({"segments": [], "waypoints": []}, "exactly one of"),
])
def test_bad_specs_name_the_field(spec, message):
    with pytest.raises(SpecError, match=message):
        Path.from_spec(spec)


def test_satory_standin_closes_and_matches_its_description():
    road = satory_standin()
    path = road.reference
    pieces = list(zip(np.diff(path.s), path.k0, path.k1))
    open_loop = Path.from_pieces(pieces)          # integrate without the closing snap
    assert np.hypot(open_loop.x[-1], open_loop.y[-1]) < 1e-3
    assert abs(open_loop.psi[-1] - 2 * np.pi) < 1e-6
    assert 3400 < path.length < 3600
    arcs = np.abs(path.k0[(path.k0 == path.k1) & (path.k0 != 0)])
    assert 1 / arcs.max() == pytest.approx(50.0) and 1 / arcs.min() == pytest.approx(500.0)
    # clothoid transitions: curvature continuous from one interval to the next
    assert np.max(np.abs(path.k0[1:] - path.k1[:-1])) < 1e-12
    assert np.max(np.abs(np.concatenate([path.k0, path.k1]))) == pytest.approx(1 / 50)


def test_road_lanes_and_spec_forms():
    road = road_from_spec({"builder": "two_lane", "length": 400, "radius": -120})
    assert road.lanes == 2 and road.length == pytest.approx(400)
    assert road.lane_offset(1) == 3.5 and road.edges() == (-1.75, 5.25)
    lane = road.lane_centre(1)
    x, y, _, _ = lane.evaluate([0.0])
    assert (x[0], y[0]) == pytest.approx((0.0, 3.5))
    spec = {"reference": {"segments": [{"line": 50}]}, "lanes": 3, "lane_width": 3.0}
    assert road_from_spec(spec).lane_offset(2) == 6.0
    with pytest.raises(SpecError, match="road.builder: unknown road 'nurburgring'"):
        road_from_spec("nurburgring")
    with pytest.raises(SpecError, match="lane: expected a lane index 0..1, got 2"):
        two_lane_road().lane_offset(2)
    assert isinstance(satory_standin(lanes=1), Road)


def test_frenet_constant_offset_equals_offset_path_and_curvature_is_dpsi_dsigma():
    road = two_lane_road(length=600, radius=80)
    s = np.linspace(0, 600, 2401)
    x, y, psi, kappa, g = frenet_to_world(road.reference, s, np.full_like(s, 3.5), 0 * s, 0 * s)
    lane = road.reference.offset(3.5)
    sigma = np.concatenate([[0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(s))])
    lx, ly, lpsi, lk = lane.evaluate(sigma)
    np.testing.assert_allclose(np.c_[x, y, psi], np.c_[lx, ly, lpsi], atol=1e-6)
    # the offset path stores exact curvature at its knots and interpolates it linearly
    # in its own arc length in between, which is off by O(kappa d) relative in clothoids
    np.testing.assert_allclose(kappa, lk, atol=1e-6)
    # a varying offset: curvature against the numerical derivative of the heading
    d = 2.0 * np.sin(s / 40)
    x, y, psi, kappa, g = frenet_to_world(road.reference, s, d, np.cos(s / 40) / 20, -np.sin(s / 40) / 800)
    inner = slice(1, -1)
    numeric = np.gradient(psi, s)[inner] / g[inner]
    ok = np.abs(np.diff(road.reference.dkappa(s)))[:-1] == 0      # away from curvature kinks
    np.testing.assert_allclose(kappa[inner][ok], numeric[ok], atol=2e-5)
