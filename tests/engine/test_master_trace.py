"""Exact scheduler traces: which component stepped at which tick with which inputs."""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
import pytest

from cosim.component import Component, Port
from cosim.errors import ComponentFailure, WiringError
from cosim.transport.inproc import InprocComponent, PythonComponentLaunch
from cosim.engine.master import Master

try:  # the scenario layer's Edge when it exists; the master only reads the fields
    from cosim.engine.wiring import Edge
except ImportError:  # pragma: no cover - colleague's module not landed yet
    Edge = namedtuple("Edge", "src src_port dst dst_port delay")


class Clock(Component):
    """Outputs a = t."""

    outputs = (Port("a"),)

    def step(self, t, inputs):
        return {"a": t}


class Offset(Component):
    """Outputs b = a + 100."""

    inputs = (Port("a"),)
    outputs = (Port("b"),)

    def step(self, t, inputs):
        return {"b": inputs["a"] + 100.0}


class Sum(Component):
    """Outputs c = a + b."""

    inputs = (Port("a"), Port("b"))
    outputs = (Port("c"),)

    def step(self, t, inputs):
        return {"c": inputs["a"] + inputs["b"]}


class PlusOne(Component):
    """u = y + 1 (y has a default of 0.5 when nothing has arrived yet)."""

    inputs = (Port("y", default=0.5),)
    outputs = (Port("u"),)

    def step(self, t, inputs):
        return {"u": inputs["y"] + 1.0}


class Double(Component):
    """y = 2 u."""

    inputs = (Port("u"),)
    outputs = (Port("y"),)

    def step(self, t, inputs):
        return {"y": 2.0 * inputs["u"]}


class Misbehaving(Component):
    """Returns what its `mode` parameter asks for at tick `at` (t = at * 0.5)."""

    outputs = (Port("y"), Port("w", size=3), Port("v", size=2))   # w and v: one block in the store

    def __init__(self, mode: str, at: int):
        self.mode, self.at = mode, at

    def step(self, t, inputs):
        out = {"y": 1.0, "w": np.zeros(3), "v": [1, 2]}
        if t != self.at * 0.5:
            return out
        if self.mode == "nan":
            out["y"] = math.nan
        elif self.mode == "inf_array":
            out["w"] = np.array([0.0, math.inf, 0.0])
        elif self.mode == "missing":
            del out["y"]
        elif self.mode == "short":
            out["w"] = np.zeros(2)
        elif self.mode == "swapped":      # the block's total size, ports' sizes swapped
            out["w"], out["v"] = np.zeros(2), np.zeros(3)
        elif self.mode == "text":
            out["v"] = "ab"
        elif self.mode == "raise":
            raise ValueError("boom")
        return out


class HeldPlant:
    """An FMU-like hosted component (no direct feedthrough): x += h * u held.

    Implements HostedComponent directly, as cosim.fmu.host does.
    """

    direct_feedthrough = False
    inputs = (Port("u"),)
    outputs = (Port("x"),)

    def __init__(self, name, period_ticks, h):
        self.name, self.period_ticks, self.h = name, period_ticks, h
        self.x = 0.0

    def start(self, t0, inputs):
        return {"x": self.x}

    def step(self, tick, t, inputs):
        self.x += self.period_ticks * self.h * inputs["u"]
        return {"x": self.x}

    def stop(self):
        return {"final_x": self.x}


def inproc(name, cls, period=1, **parameters):
    """Host a test component of this module in-process."""
    return InprocComponent(PythonComponentLaunch(name, f"{__name__}:{cls.__name__}",
                                                 parameters, period))


def test_multirate_trace_is_exact():
    # Declared in reverse so the order must come from the graph, not the file.
    comps = {"sum": inproc("sum", Sum, 5), "offset": inproc("offset", Offset, 2),
             "clock": inproc("clock", Clock, 1)}
    edges = [Edge("clock", "a", "offset", "a", 0), Edge("clock", "a", "sum", "a", 0),
             Edge("offset", "b", "sum", "b", 0)]
    master = Master(comps, edges, tick=0.5, total_ticks=6, trace=True)
    master.run()
    assert master.order == ["clock", "offset", "sum"]
    assert master.trace == [
        (0, "clock", {}), (0, "offset", {"a": 0.0}), (0, "sum", {"a": 0.0, "b": 100.0}),
        (1, "clock", {}),
        (2, "clock", {}), (2, "offset", {"a": 1.0}),
        (3, "clock", {}),
        (4, "clock", {}), (4, "offset", {"a": 2.0}),
        # sum sees clock's new a and offset's b held since tick 4 (zero-order hold)
        (5, "clock", {}), (5, "sum", {"a": 2.5, "b": 102.0}),
        (6, "clock", {}), (6, "offset", {"a": 3.0}),
    ]
    assert master.value("sum", "c") == 2.5 + 102.0
    assert master.value("offset", "b") == 103.0


def test_feedback_with_explicit_delay_trace():
    comps = {"double": inproc("double", Double), "plus": inproc("plus", PlusOne)}
    edges = [Edge("plus", "u", "double", "u", 0), Edge("double", "y", "plus", "y", 1)]
    master = Master(comps, edges, tick=0.1, total_ticks=3, trace=True)
    master.run()
    assert master.order == ["plus", "double"]
    # tick 0: the delayed input holds its default 0.5; afterwards y of the previous tick
    assert master.trace == [
        (0, "plus", {"y": 0.5}), (0, "double", {"u": 1.5}),
        (1, "plus", {"y": 3.0}), (1, "double", {"u": 4.0}),
        (2, "plus", {"y": 8.0}), (2, "double", {"u": 9.0}),
        (3, "plus", {"y": 18.0}), (3, "double", {"u": 19.0}),
    ]


def test_loop_without_delay_is_a_wiring_error_naming_the_loop():
    comps = {"double": inproc("double", Double), "plus": inproc("plus", PlusOne)}
    edges = [Edge("plus", "u", "double", "u", 0), Edge("double", "y", "plus", "y", 0)]
    with pytest.raises(WiringError) as err:
        Master(comps, edges, tick=0.1, total_ticks=3)
    message = str(err.value)
    assert "double -> plus -> double" in message or "plus -> double -> plus" in message
    assert "delay: 1" in message


def test_fmu_like_plant_steps_first_with_held_inputs():
    comps = {"ctrl": inproc("ctrl", PlusOne), "plant": HeldPlant("plant", 2, 0.25)}
    edges = [Edge("plant", "x", "ctrl", "y", 0), Edge("ctrl", "u", "plant", "u", 0)]
    master = Master(comps, edges, tick=0.25, total_ticks=4, trace=True)
    master.run()
    assert master.order == ["plant", "ctrl"]
    # plant (period 2, h = 0.5 per step) integrates u held from the previous step:
    # x(2) = 0 + 0.5 * 1 = 0.5; ctrl then gives u = 1.5; x(4) = 0.5 + 0.75 = 1.25
    assert master.trace == [
        (0, "plant", {"u": 0.0}), (0, "ctrl", {"y": 0.0}),
        (1, "ctrl", {"y": 0.0}),
        (2, "plant", {"u": 1.0}), (2, "ctrl", {"y": 0.5}),
        (3, "ctrl", {"y": 0.5}),
        (4, "plant", {"u": 1.5}), (4, "ctrl", {"y": 1.25}),
    ]
    metrics, errors = master.stop_all()
    assert metrics["plant"] == {"final_x": 1.25} and errors == []


def test_time_is_computed_from_integer_ticks():
    comps = {"clock": inproc("clock", Clock)}
    master = Master(comps, [], tick=0.1, total_ticks=1000, trace=False)
    master.run()
    # 1000 additions of 0.1 give 99.9999999999986; t0 + k h gives exactly 100.0
    assert master.value("clock", "a") == 100.0


@pytest.mark.parametrize("mode, cause", [
    ("nan", "output 'y' is non-finite: nan"),
    ("inf_array", "output 'w' is non-finite at [1]: inf"),
    ("missing", "output 'y' missing"),
    ("short", "output 'w' has shape (2,), expected (3,)"),
    ("swapped", "output 'w' has shape (2,), expected (3,)"),
    ("text", "output 'v' is not a number: 'ab'"),
    ("raise", "ValueError: boom"),
])
def test_bad_outputs_name_component_tick_signal_value(mode, cause):
    comps = {"bad": inproc("bad", Misbehaving, mode=mode, at=3)}
    master = Master(comps, [], tick=0.5, total_ticks=5)
    assert master._plans[0].write_arrays is not None      # w and v: the block writer, then its fallback
    with pytest.raises(ComponentFailure) as err:
        master.run()
    assert str(err.value) == f"component 'bad' failed at tick 3 (t=1.5 s): {cause}"
    assert master.ticks_done == 2


def test_failure_during_initialization_is_named():
    comps = {"bad": inproc("bad", Misbehaving, mode="nan", at=0)}
    with pytest.raises(ComponentFailure, match="failed during initialization .*'y' is non-finite"):
        Master(comps, [], tick=0.5, total_ticks=5).run()


class Relay(Component):
    """o = i + 1."""

    inputs = (Port("i"),)
    outputs = (Port("o"),)

    def step(self, t, inputs):
        return {"o": inputs["i"] + 1.0}


def test_three_component_loop_is_named_in_order_and_a_delay_breaks_it():
    comps = {n: inproc(n, Relay) for n in ("a", "b", "c")}
    loop = [Edge("a", "o", "b", "i", 0), Edge("b", "o", "c", "i", 0), Edge("c", "o", "a", "i", 0)]
    with pytest.raises(WiringError, match=r"algebraic loop .*: a -> b -> c -> a;"):
        Master(comps, loop, tick=1.0, total_ticks=1)
    broken = loop[:2] + [Edge("c", "o", "a", "i", 1)]
    master = Master(comps, broken, tick=1.0, total_ticks=2, trace=True)
    master.run()
    assert master.order == ["a", "b", "c"]
    assert [(k, n, i["i"]) for k, n, i in master.trace] == [
        (0, "a", 0.0), (0, "b", 1.0), (0, "c", 2.0),
        (1, "a", 3.0), (1, "b", 4.0), (1, "c", 5.0),
        (2, "a", 6.0), (2, "b", 7.0), (2, "c", 8.0)]


def test_wiring_size_mismatch_and_double_feed_are_refused():
    comps = {"clock": inproc("clock", Clock), "bad": inproc("bad", Misbehaving, mode="", at=0),
             "sum": inproc("sum", Sum)}
    with pytest.raises(WiringError, match="size 3 does not match size 1"):
        Master(comps, [Edge("bad", "w", "sum", "a", 0)], tick=1.0, total_ticks=1)
    with pytest.raises(WiringError, match="input sum.a is fed twice"):
        Master(comps, [Edge("clock", "a", "sum", "a", 0), Edge("bad", "y", "sum", "a", 0)],
               tick=1.0, total_ticks=1)


class Pair(Component):
    """w = [t, -t] (an array output)."""

    outputs = (Port("w", size=2),)

    def step(self, t, inputs):
        return {"w": np.array([t, -t])}


class PairReader(Component):
    """Reads the array w (default 7.0 before anything arrives); s = w[0]."""

    inputs = (Port("w", size=2, default=7.0),)
    outputs = (Port("s"),)

    def step(self, t, inputs):
        assert not inputs["w"].flags.writeable
        return {"s": float(inputs["w"][0])}


@pytest.mark.parametrize("delay", [0, 1])
def test_array_edges_with_and_without_delay(delay):
    comps = {"reader": inproc("reader", PairReader), "pair": inproc("pair", Pair)}
    master = Master(comps, [Edge("pair", "w", "reader", "w", delay)], tick=0.5,
                    total_ticks=3, trace=True)
    master.run()
    seen = [(k, i["w"].tolist()) for k, n, i in master.trace if n == "reader"]
    if delay:
        # delay edges do not order: declaration order, the reader sees the previous tick
        assert master.order == ["reader", "pair"]
        assert seen == [(0, [7.0, 7.0]), (1, [0.0, -0.0]), (2, [0.5, -0.5]), (3, [1.0, -1.0])]
    else:
        assert master.order == ["pair", "reader"]
        assert seen == [(0, [0.0, -0.0]), (1, [0.5, -0.5]), (2, [1.0, -1.0]), (3, [1.5, -1.5])]
    assert master.value("pair", "w").tolist() == [1.5, -1.5]
