"""The master's values lane (`step_values`) and its array outputs written straight into the store.

A host that offers `step_values` with `value_names` matching its ports is
stepped on plain sequences (an FMU-like host here; a Python component with
`Component.step_values`, scalar and array inputs, through `InprocComponent`
below); the store must be the same, bit for bit, as on the mapping path (which
`trace=True` or a twin without `step_values` gives), and a bad output must
fail as precisely as on that path.
"""

from __future__ import annotations

import math
import struct
from collections import namedtuple

import numpy as np
import pytest

from cosim.component import Component, Port
from cosim.engine.master import Master
from cosim.engine.wiring import Edge as WiredEdge
from cosim.errors import ComponentFailure, StopRequested
from cosim.transport.inproc import InprocComponent, PythonComponentLaunch
from tests.helpers.components import Tracker

Edge = namedtuple("Edge", "src src_port dst dst_port delay")


class Lagged:
    """A host with both lanes: y = 0.9 * y + 0.1 * u, z = sin(y) (or `bad` from tick `bad_at` on)."""

    direct_feedthrough = False

    def __init__(self, name="plant", bad=None, bad_at=None, stop_at=None):
        self.name, self.period_ticks = name, 1
        self.inputs, self.outputs = (Port("u"),), (Port("y"), Port("z"))
        self.value_names = (("u",), ("y", "z"))
        self.y, self.bad, self.bad_at, self.stop_at = 0.25, bad, bad_at, stop_at
        self.lanes: list[str] = []

    def start(self, t0, inputs):
        return {"y": self.y, "z": math.sin(self.y)}

    def step_values(self, tick, t, inputs):
        self.lanes.append("values")
        return self._advance(tick, t, inputs[0])

    def step(self, tick, t, inputs):
        self.lanes.append("mapping")
        return dict(zip(("y", "z"), self._advance(tick, t, inputs["u"])))

    def _advance(self, tick, t, u):
        self.y = 0.9 * self.y + 0.1 * u
        out = [self.y, math.sin(self.y) if self.bad_at is None or tick < self.bad_at else self.bad]
        if tick == self.stop_at:
            raise StopRequested(self.name, tick, t, dict(zip(("y", "z"), out)), "asked to stop")
        return out

    def stop(self):
        return {}


class Feedback:
    """u = 1 - y, and an array output w = [y, 2y, 3y] (mapping lane only)."""

    def __init__(self):
        self.name, self.period_ticks = "ctrl", 1
        self.inputs, self.outputs = (Port("y"),), (Port("u"), Port("w", size=3))

    def start(self, t0, inputs):
        return self.step(0, t0, inputs)

    def step(self, tick, t, inputs):
        y = inputs["y"]
        return {"u": 1.0 - y, "w": np.array([y, 2 * y, 3 * y])}

    def stop(self):
        return {}


class Reader:
    """r = sum of the array input w (a reader of the lazily frozen copy)."""

    def __init__(self):
        self.name, self.period_ticks = "reader", 1
        self.inputs, self.outputs = (Port("w", size=3),), (Port("r"),)
        self.seen = []

    def start(self, t0, inputs):
        return self.step(0, t0, inputs)

    def step(self, tick, t, inputs):
        self.seen.append(inputs["w"])
        return {"r": float(inputs["w"].sum())}

    def stop(self):
        return {}


EDGES = [Edge("plant", "y", "ctrl", "y", 0), Edge("ctrl", "u", "plant", "u", 0),
         Edge("ctrl", "w", "reader", "w", 0)]


class StoreBits:
    """Observer appending the store's bits (scalars, then arrays) after every tick to `rows`."""

    def __init__(self, rows: list) -> None:
        self.rows = rows

    def begin(self, master) -> None:
        pass

    def after_tick(self, tick, t, values, arrays) -> None:
        self.rows.append(struct.pack(f"{len(values)}d", *values) + arrays.tobytes())


def _run(plant, trace, ticks=50):
    """The store after every tick (bits) of plant + feedback + reader."""
    rows = []
    watch = StoreBits(rows)

    reader = Reader()
    master = Master({"plant": plant, "ctrl": Feedback(), "reader": reader}, EDGES, 0.01, ticks,
                    observers=[watch], trace=trace)
    master.run()
    return master, rows, reader


def test_values_lane_gives_the_mapping_lanes_bits():
    on_values, on_mapping = Lagged(), Lagged()
    _, fast, reader = _run(on_values, trace=False)
    _, slow, _ = _run(on_mapping, trace=True)
    assert set(on_values.lanes) == {"values"} and set(on_mapping.lanes) == {"mapping"}
    assert fast == slow and len(fast) == 51
    assert all(not w.flags.writeable for w in reader.seen)  # readers get read-only copies
    y = reader.seen[-1][0]
    assert list(reader.seen[-1]) == [y, 2 * y, 3 * y]


def test_a_host_whose_value_names_do_not_match_its_ports_keeps_the_mapping_lane():
    plant = Lagged()
    plant.value_names = (("u",), ("z", "y"))
    _run(plant, trace=False, ticks=3)
    assert set(plant.lanes) == {"mapping"}


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_non_finite_value_fails_naming_output_tick_and_value(bad):
    with pytest.raises(ComponentFailure) as caught:
        _run(Lagged(bad=bad, bad_at=7), trace=False)
    message = str(caught.value)
    assert "'plant'" in message and "tick 7" in message and f"output 'z' is non-finite: {bad!r}" in message
    assert caught.value.details == {"kind": "bad_output", "output": "z",
                                    "problem": f"is non-finite: {bad!r}"}  # the manifest's cause


def test_finite_values_whose_sum_overflows_pass():
    master, rows, _ = _run(Lagged(bad=1.7e308, bad_at=3), trace=False, ticks=5)
    assert len(rows) == 6 and master.value("plant", "z") == 1.7e308


def test_a_stop_request_on_the_values_lane_records_its_outputs():
    master, rows, _ = _run(Lagged(stop_at=4), trace=False)
    assert master.stop_request is not None and master.ticks_done == 4 and len(rows) == 5
    reference, _, _ = _run(Lagged(), trace=False, ticks=4)
    assert master.value("plant", "y") == reference.value("plant", "y")


def test_a_non_finite_array_output_fails_naming_its_index():
    class BadArray(Feedback):
        def step(self, tick, t, inputs):
            out = super().step(tick, t, inputs)
            if tick == 5:
                out["w"][1] = math.nan
            return out

    master = Master({"plant": Lagged(), "ctrl": BadArray(), "reader": Reader()}, EDGES, 0.01, 10)
    with pytest.raises(ComponentFailure) as caught:
        master.run()
    assert "tick 5" in str(caught.value) and "output 'w' is non-finite at [1]: nan" in str(caught.value)


def test_an_array_output_of_the_wrong_shape_fails():
    class Short(Feedback):
        def step(self, tick, t, inputs):
            return {"u": 0.0, "w": np.zeros(2)}

    master = Master({"plant": Lagged(), "ctrl": Short(), "reader": Reader()}, EDGES, 0.01, 10)
    with pytest.raises(ComponentFailure, match=r"output 'w' has shape \(2,\), expected \(3,\)"):
        master.run()


# -- Python components in-process: `Component.step_values` through InprocComponent --------------

class Feeder(Component):
    """x, v and the arrays ref and w (3 each) moving with the tracker's u (fed back one tick late)."""

    inputs = (Port("u"),)
    outputs = (Port("x"), Port("ref", size=3), Port("v"), Port("w", size=3))

    def __init__(self):
        self.phase = 0.1

    def step(self, t, inputs):
        self.phase += 0.05 + 0.01 * inputs["u"]
        ramp = np.arange(3) * 0.3 + math.sin(self.phase)
        return {"x": math.cos(self.phase), "ref": ramp, "v": 2.0 + t, "w": np.cos(ramp * 1.7)}


class NumpyScalars(Tracker):
    """The tracker returning numpy scalars (the master converts them as `float()` would)."""

    def step_values(self, t, inputs):
        return [np.float64(value) for value in super().step_values(t, inputs)]


class RaisesAtTick(Tracker):
    """The tracker raising from t >= 0.03 on (in `step_values`, so in `step` too)."""

    def step_values(self, t, inputs):
        if t >= 0.03:
            raise ZeroDivisionError(f"at {t}")
        return super().step_values(t, inputs)


class ShortResult(Tracker):
    """The tracker returning one value too few from `step_values` after t0."""

    def step_values(self, t, inputs):
        values = super().step_values(t, inputs)
        return values[:2] if t > 0.0 else values


class WithArrayOutput(Tracker):
    """A `step_values` on a component with an array output: not offered on the lane."""

    outputs = Tracker.outputs + (Port("spare", size=2),)

    def step(self, t, inputs):
        return super().step(t, inputs) | {"spare": np.zeros(2)}


LANE_EDGES = [WiredEdge("feed", "x", "track", "x"), WiredEdge("feed", "ref", "track", "ref"),
              WiredEdge("feed", "v", "track", "v", scale=0.5, offset=-1.0),
              WiredEdge("feed", "w", "track", "w", delay=1), WiredEdge("track", "u", "feed", "u", delay=1)]


def _hosted(class_name, module="tests.helpers.components", **parameters):
    return InprocComponent(PythonComponentLaunch("track", f"{module}:{class_name}", parameters, 1))


def _run_tracker(track, trace=False, ticks=60):
    """(master, the store's bits after every tick) of feeder + tracker."""
    rows = []
    watch = StoreBits(rows)

    feed = InprocComponent(PythonComponentLaunch("feed", f"{__name__}:Feeder", {}, 1))
    master = Master({"feed": feed, "track": track}, LANE_EDGES, 0.01, ticks, observers=[watch],
                    trace=trace)
    master.run()
    master.stop_all()
    return master, rows


def _lane_of(master, name="track"):
    return next(plan.step_values for plan in master._plans if plan.name == name)


def test_a_python_component_on_the_values_lane_gives_the_mapping_paths_store_tick_by_tick():
    lane_host = _hosted("Tracker")
    on_lane, lane_rows = _run_tracker(lane_host)
    on_twin, twin_rows = _run_tracker(_hosted("TrackerWithoutLane"))
    traced, traced_rows = _run_tracker(_hosted("Tracker"), trace=True)
    assert _lane_of(on_lane) is not None and _lane_of(on_twin) is None
    assert len(lane_rows) == 61 and lane_rows == twin_rows == traced_rows
    assert all(type(value) is float for value in on_lane.values)
    received = lane_host.component.received
    assert len(received) == 61 and all(not a.flags.writeable for pair in received for a in pair)
    assert on_lane.stop_all()[0]["track"] == {"steps": 61.0}


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_non_finite_output_on_the_lane_fails_as_on_the_mapping_path(bad):
    failures = []
    for class_name in ("Tracker", "TrackerWithoutLane"):
        with pytest.raises(ComponentFailure) as caught:
            _run_tracker(_hosted(class_name, bad=bad, bad_at=0.07))
        failures.append(str(caught.value))
    assert failures[0] == failures[1]
    assert failures[0] == f"component 'track' failed at tick 7 (t=0.07 s): output 'energy' is non-finite: {bad!r}"


def test_an_exception_in_step_values_fails_as_in_step():
    failures = []
    for trace in (False, True):
        with pytest.raises(ComponentFailure) as caught:
            _run_tracker(_hosted("RaisesAtTick", module=__name__), trace=trace)
        failures.append(str(caught.value))
    assert failures[0] == failures[1]
    assert failures[0] == "component 'track' failed at tick 3 (t=0.03 s): ZeroDivisionError: at 0.03"


def test_numpy_scalars_from_step_values_are_stored_as_floats_with_the_same_bits():
    master, rows = _run_tracker(_hosted("NumpyScalars", module=__name__))
    _, reference = _run_tracker(_hosted("Tracker"))
    assert _lane_of(master) is not None and rows == reference
    assert all(type(value) is float for value in master.values)


def test_a_wrong_number_of_values_fails_the_run():
    with pytest.raises(ComponentFailure, match=r"at tick 1 .*step_values returned 2 values for 3 outputs"):
        _run_tracker(_hosted("ShortResult", module=__name__))


@pytest.mark.parametrize("value_names", [
    (("ref", "x", "v", "w"), ("u", "integral", "energy")),  # inputs in another order
    (("x", "ref", "v"), ("u", "integral", "energy")),  # an input missing
    (("x", "ref", "v", "w"), ("integral", "u", "energy")),  # outputs in another order
    None])
def test_value_names_that_do_not_match_the_ports_fall_back_to_the_mapping_path(value_names):
    host = _hosted("Tracker")
    host.value_names = value_names
    master, rows = _run_tracker(host, ticks=10)
    _, reference = _run_tracker(_hosted("TrackerWithoutLane"), ticks=10)
    assert _lane_of(master) is None and rows == reference


def test_a_component_with_an_array_output_is_not_offered_the_lane():
    host = _hosted("WithArrayOutput", module=__name__)
    assert host.value_names is None


def test_a_host_that_vouches_for_its_results_is_only_tested_for_finiteness():
    class Vouching(Lagged):
        values_exact = True

        def step_values(self, tick, t, inputs):
            return [np.float64(v) for v in super().step_values(tick, t, inputs)]

    master, _, _ = _run(Vouching(), trace=False, ticks=3)
    assert type(master.values[0]) is np.float64  # taken as given: the host's promise
    master, _, _ = _run(type("Plain", (Vouching,), {"values_exact": False})(), trace=False, ticks=3)
    assert type(master.values[0]) is float
    with pytest.raises(ComponentFailure, match="output 'z' is non-finite: nan"):
        _run(Vouching(bad=math.nan, bad_at=2), trace=False, ticks=3)


def test_the_backstepping_controller_is_offered_the_lane_for_all_its_ports():
    host = InprocComponent(PythonComponentLaunch(
        "controller", "controllers.backstepping:BacksteppingController", {}, 1))
    assert host.value_names == (tuple(p.name for p in host.inputs), tuple(p.name for p in host.outputs))
    assert len(host.value_names[0]) == 13 and len(host.value_names[1]) == 17
