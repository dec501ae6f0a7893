"""A Path's compiled foot-point search (numba, the `jit` extra) against the interpreted one, bit for bit.

Unit level: Path._point and Path._newton on random open paths of lines, arcs and
clothoids, spline paths and closed loops, and project() on both paths, float in
and numpy scalars in (these keep the interpreted path and its types). Planner
level: a planner stepped along a drifting vehicle gives the same outputs on both
paths. And the switch: COSIM_JIT=auto leaves it out of a short run; a
disagreeing kernel is compiled afresh once, then not used.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.component import constructing_for
from controllers.planning import Planner
from controllers.road import compiled_path
from controllers.road.geometry import Path
from tests.helpers.jit_gates import assert_refused_after_one_recompile

numba = pytest.importorskip("numba")


def same(a, b) -> bool:
    """Equal bit for bit and type for type (repr tells -0.0 from 0.0, None from a float)."""
    return repr(a) == repr(b)


def _random_paths(rng: np.random.Generator) -> list[Path]:
    paths = []
    for _ in range(6):
        pieces, kappa = [], 0.0
        for _ in range(int(rng.integers(2, 7))):
            end = float(rng.choice([0.0, kappa, rng.uniform(-0.05, 0.05)]))
            pieces.append((float(rng.uniform(5.0, 60.0)), kappa, end))
            kappa = end
        paths.append(Path.from_pieces(pieces, *rng.uniform(-50, 50, 2).tolist(), float(rng.uniform(-4, 4))))
    waypoints = np.cumsum(rng.normal(0.0, 8.0, (9, 2)) + [10.0, 0.0], axis=0)
    paths.append(Path.from_waypoints(waypoints))
    angles = np.linspace(0.0, 2.0 * np.pi, 12, endpoint=False)
    paths.append(Path.from_waypoints(np.c_[60.0 * np.cos(angles), 35.0 * np.sin(angles)], closed=True))
    paths.append(Path.from_pieces([(2.0 * math.pi * 25.0, 0.04, 0.04)], closed=True))
    return paths


def test_compiled_point_and_newton_equal_the_interpreted_ones_bit_for_bit(jit_mode):
    jit_mode("on")
    kernel = compiled_path.compiled_geometry()
    assert kernel is not None
    rng = np.random.default_rng(41)
    solved = unsolved = 0
    for path in _random_paths(rng):
        newton, point = path.with_compiled_search(kernel)._compiled
        length = path.length
        for s in [*rng.uniform(-20.0, length + 20.0, 300).tolist(), *path.s.tolist(), -0.0, 3.0 * length]:
            assert same(point(s), path._point(s)), s
        x, y, _, _ = path.evaluate(rng.uniform(0.0, length, 60))
        for px, py in zip(x.tolist(), y.tolist()):
            for offset in (rng.normal(0.0, 1.0, 2), rng.normal(0.0, 15.0, 2)):
                qx, qy = px + float(offset[0]), py + float(offset[1])
                guess = float(rng.uniform(-5.0, length + 5.0))
                expected = path._newton(qx, qy, guess)
                assert same(newton(qx, qy, guess), expected), (qx, qy, guess)
                solved += expected is not None
                unsolved += expected is None
    assert solved > 500 and unsolved > 10      # both outcomes compared


def test_project_takes_the_compiled_search_for_floats_and_keeps_numpy_scalars_interpreted(jit_mode):
    jit_mode("on")
    rng = np.random.default_rng(8)
    kernel = compiled_path.compiled_geometry()
    for interpreted in _random_paths(rng):
        path = interpreted.with_compiled_search(kernel)
        assert path._compiled is not None and interpreted._compiled is None     # a copy
        for _ in range(80):
            px, py = (float(v[0]) for v in interpreted.evaluate(rng.uniform(0, path.length))[:2])
            px, py = px + float(rng.normal(0, 3)), py + float(rng.normal(0, 3))
            guess = float(rng.uniform(0, path.length))
            for arguments in ((px, py), (px, py, 0.3, guess), (px, py, None, guess, 2.0)):
                assert same(path.project(*arguments), interpreted.project(*arguments)), arguments
            as_numpy = (np.float64(px), np.float64(py))
            assert same(path.project(*as_numpy, s_guess=guess), interpreted.project(*as_numpy, s_guess=guess))


def _planner_outputs(steps: int) -> tuple[list[str], bool]:
    """A lane-change planner stepped along a vehicle drifting off its lane: reprs of every output."""
    planner = Planner(road={"builder": "two_lane", "length": 400.0, "radius": 90.0},
                      manoeuvre={"type": "lane_change", "at": 40.0, "to_lane": 1, "a_lat": 1.5, "j_lat": 2.0})
    outputs = [repr(planner.initialize(0.0, {"x": 0.0, "y": 0.0, "psi": 0.0, "vx": 8.0}))]
    reference = planner.road.reference
    for k in range(1, steps + 1):
        x, y, psi, _ = (float(v[0]) for v in reference.evaluate(0.9 * k))
        lateral = 0.4 * math.sin(0.05 * k)
        state = {"x": x - lateral * math.sin(psi), "y": y + lateral * math.cos(psi), "psi": psi + 0.02,
                 "vx": 9.0}
        outputs.append(repr(planner.step(0.1 * k, state)))
    return outputs, reference._compiled is not None


def test_a_planner_gives_the_same_outputs_on_both_paths(jit_mode):
    jit_mode("off")
    interpreted, compiled = _planner_outputs(150)
    assert not compiled
    jit_mode("on")
    outputs, compiled = _planner_outputs(150)
    assert compiled and outputs == interpreted


def test_auto_leaves_the_compiled_search_out_of_a_short_run_only(jit_mode):
    jit_mode("auto")
    with constructing_for(compiled_path.SHORT_RUN_STEPS - 1):
        short = Planner()
    assert short.road.reference._compiled is None and compiled_path.compiled_geometry.cache_info().currsize == 0
    with constructing_for(compiled_path.SHORT_RUN_STEPS):
        long = Planner()
    assert long.road.reference._compiled is not None
    assert short.road.reference._compiled is None       # the builder's shared road is not changed


def test_a_search_that_disagrees_is_compiled_afresh_once_then_not_used(jit_mode, monkeypatch):
    jit_mode("off")
    from controllers.road import geometry_jit

    assert_refused_after_one_recompile(monkeypatch, compiled_path.compiled_geometry, geometry_jit, "point",
                                       r"the compiled road projection is not used: at s = -12.0 it gives")
    assert Planner().road.reference._compiled is None
