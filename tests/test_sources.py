"""Tests of the signal sources: exact analytic values, cross-checks, schema agreement."""

from __future__ import annotations

import importlib
import inspect
import math
from pathlib import Path

import numpy as np
import pytest

from cosim.component import ComponentError, Port
from cosim.scenario.loader import load_scenario
from cosim.scenario.sources import SOURCE_CLASSES, SOURCE_MODELS
from cosim.sources import Constant, Gust, Ramp, Step, Table


def value(component, t: float, **inputs: float) -> float:
    return component.step(t, inputs)["value"]


def test_constant_and_its_unit() -> None:
    source = Constant(value=-2.5, unit="N")
    assert source.outputs == (Port("value", unit="N", description=Constant.__doc__),)
    assert source.inputs == ()
    assert source.initialize(0.0, {}) == {"value": -2.5}
    assert value(source, 123.0) == -2.5


def test_default_unit_is_empty_so_it_matches_any_unit() -> None:
    assert Step(initial=0, final=1, at=1).outputs[0].unit == ""


def test_step_switches_exactly_at_its_time() -> None:
    source = Step(initial=1.0, final=0.3, at=2.0)
    assert [value(source, t) for t in (0.0, 1.99, 2.0, 5.0)] == [1.0, 1.0, 0.3, 0.3]


def test_ramp_values() -> None:
    source = Ramp(start=1.0, end=3.0, t_start=2.0, t_end=4.0)
    got = [value(source, t) for t in (0.0, 2.0, 2.5, 3.0, 4.0, 9.0)]
    assert got == [1.0, 1.0, 1.5, 2.0, 3.0, 3.0]


def test_gust_exact_points() -> None:
    gust = Gust(amplitude=400.0, start=1.0, duration=2.0, base=10.0, unit="N")
    assert value(gust, 0.5) == 10.0        # before
    assert value(gust, 1.0) == 10.0        # onset: 1 - cos(0) = 0
    assert value(gust, 2.0) == 410.0       # middle: cos(pi) = -1 exactly, the peak
    assert value(gust, 3.0) == 10.0        # end: cos(2 pi) = 1
    assert value(gust, 3.5) == 10.0        # after
    assert value(gust, 1.5) == pytest.approx(210.0, rel=1e-15)  # quarter: cos(pi/2) ~ 0


def test_gust_matches_vectorised_formula_and_is_symmetric() -> None:
    gust = Gust(amplitude=-300.0, start=0.7, duration=1.3)
    times = 0.7 + np.linspace(0.0, 1.3, 131)
    expected = -150.0 * (1.0 - np.cos(2.0 * np.pi * (times - 0.7) / 1.3))
    got = np.array([value(gust, float(t)) for t in times])
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(got, got[::-1], rtol=1e-9, atol=1e-9)
    assert got.min() == pytest.approx(-300.0)


def test_time_table_linear_and_previous() -> None:
    points = [[0.0, 1.0], [10.0, 0.5], [20.0, 0.5], [30.0, 0.9]]
    linear = Table(points=points)
    previous = Table(points=points, interpolation="previous")
    assert linear.inputs == ()
    assert [value(linear, t) for t in (-1.0, 0.0, 5.0, 10.0, 15.0, 25.0, 30.0, 40.0)] == [
        1.0, 1.0, 0.75, 0.5, 0.5, 0.7, 0.9, 0.9]
    assert [value(previous, t) for t in (-1.0, 0.0, 9.99, 10.0, 29.9, 30.0, 99.0)] == [
        1.0, 1.0, 1.0, 0.5, 0.5, 0.9, 0.9]


def test_time_table_cross_checks_numpy_interp() -> None:
    xs = np.array([0.0, 0.3, 1.7, 2.0, 5.5])
    vs = np.array([0.2, -1.0, 4.0, 4.0, 0.1])
    table = Table(points=np.column_stack([xs, vs]).tolist())
    grid = np.linspace(-1.0, 7.0, 801)
    got = np.array([table.lookup(float(t)) for t in grid])
    np.testing.assert_allclose(got, np.interp(grid, xs, vs), rtol=1e-13, atol=1e-13)


def test_single_point_table_is_constant() -> None:
    table = Table(points=[[3.0, 0.8]])
    assert [table.lookup(s) for s in (-5.0, 3.0, 100.0)] == [0.8, 0.8, 0.8]


def test_distance_table_integrates_travelled_distance() -> None:
    table = Table(points=[[0.0, 0.0], [10.0, 1.0]], over="distance", unit="1")
    assert table.inputs == (Port("x", unit="m", description="world x of the tracked point"),
                            Port("y", unit="m", description="world y of the tracked point"))
    path = [(100.0, 50.0), (103.0, 54.0), (103.0, 54.0), (106.0, 58.0), (100.0, 50.0)]
    got = [table.initialize(0.0, {"x": path[0][0], "y": path[0][1]})["value"]]
    got += [value(table, 0.1 * k, x=x, y=y) for k, (x, y) in enumerate(path[1:], 1)]
    # 3-4-5 triangles: 0, 5, 5, 10, then 10 more going back (distance, not displacement)
    assert got == [0.0, 0.5, 0.5, 1.0, 1.0]
    assert table.distance == 20.0
    assert table.initialize(0.0, {"x": 0.0, "y": 0.0}) == {"value": 0.0}  # restart resets


@pytest.mark.parametrize("make, message", [
    (lambda: Ramp(start=0, end=1, t_start=2, t_end=2), r"t_end \(2\) must be after t_start \(2\)"),
    (lambda: Gust(amplitude=1, start=0, duration=0), r"duration must be > 0 \(got 0\)"),
    (lambda: Constant(value=float("nan")), r"parameter 'value' must be finite \(got nan\)"),
    (lambda: Step(initial="x", final=1, at=0), r"parameter 'initial' must be a number \(got 'x'\)"),
    (lambda: Table(points=[[0, 1], [0, 2]]),
     r"points\[1\] abscissa 0.0 is not greater than the previous one 0.0"),
    (lambda: Table(points=[[0, 1, 2]]), r"points\[0\] must be \[abscissa, value\]"),
    (lambda: Table(points=[]), "points must be a non-empty list"),
    (lambda: Table(points=[[0, 1]], over="space"), "over must be 'time' or 'distance'"),
    (lambda: Table(points=[[0, 1]], interpolation="cubic"), "interpolation must be 'linear' or"),
])
def test_bad_parameters_are_named(make, message: str) -> None:
    with pytest.raises(ComponentError, match=message):
        make()


@pytest.mark.parametrize("kind", sorted(SOURCE_MODELS))
def test_schema_fields_are_the_class_keyword_arguments(kind: str) -> None:
    module, _, name = SOURCE_CLASSES[kind].partition(":")
    cls = getattr(importlib.import_module(module), name)
    fields = set(SOURCE_MODELS[kind].model_fields) - {"kind", "period", "host"}
    assert set(inspect.signature(cls).parameters) == fields


def test_sources_built_from_a_scenario_give_their_values(tmp_path: Path) -> None:
    (tmp_path / "s.yaml").write_text("""
name: sources
duration: 4
tick: 0.5
components:
  controller: {python: "a.b:C"}
sources:
  wind: {kind: gust, amplitude: 200, start: 1, duration: 2, unit: N, period: 1.0}
  mu: {kind: table, over: distance, points: [[0, 1.0], [10, 0.4]], interpolation: previous}
  brake: {kind: step, initial: 0, final: -100, at: 2}
""")
    scenario = load_scenario(tmp_path / "s.yaml")
    specs = scenario.python_components()
    built = {}
    for name in ("wind", "mu", "brake"):
        module, _, cls = specs[name].python.partition(":")
        built[name] = getattr(importlib.import_module(module), cls)(**specs[name].parameters)
    assert scenario.period_ticks("wind") == 2 and scenario.period_ticks("mu") == 1
    assert built["wind"].outputs[0].unit == "N"
    assert value(built["wind"], 2.0) == 200.0
    assert built["mu"].initialize(0.0, {"x": 0.0, "y": 0.0}) == {"value": 1.0}
    assert value(built["mu"], 0.5, x=6.0, y=8.0) == 0.4
    assert [value(built["brake"], t) for t in (1.5, 2.0)] == [0.0, -100.0]


def test_same_parameters_give_identical_sequences() -> None:
    def run() -> list[float]:
        table = Table(points=[[0, 0.0], [3, 1.0], [7, -2.0]], over="distance")
        out = [table.initialize(0.0, {"x": 0.0, "y": 0.0})["value"]]
        for k in range(1, 200):
            t = 0.01 * k
            out.append(value(table, t, x=3.0 * math.sin(t), y=t * t))
        return out

    assert run() == run()
