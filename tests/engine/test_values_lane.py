"""The master's values lane (`step_values`) and its array outputs written straight into the store.

A host that offers `step_values` with `value_names` matching its scalar ports
is stepped on plain floats; the store must be the same, bit for bit, as on
the mapping path (which `trace=True` forces), and a non-finite output must
fail as precisely as on that path.
"""

from __future__ import annotations

import math
import struct
from collections import namedtuple

import numpy as np
import pytest

from cosim.component import Port
from cosim.engine.master import Master
from cosim.errors import ComponentFailure, StopRequested

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


def _run(plant, trace, ticks=50):
    """The store after every tick (bits) of plant + feedback + reader."""
    rows = []

    class Watch:
        def begin(self, master):
            pass

        def after_tick(self, tick, t, values, arrays):
            rows.append(struct.pack(f"{len(values)}d", *values) + arrays.tobytes())

    reader = Reader()
    master = Master({"plant": plant, "ctrl": Feedback(), "reader": reader}, EDGES, 0.01, ticks,
                    observers=[Watch()], trace=trace)
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
