"""Connections with scale/offset: the input reads scale * x + offset, exactly, only where given."""

from __future__ import annotations

import pytest

from cosim.engine.master import Master
from cosim.engine.wiring import Edge
from cosim.errors import WiringError
from tests.engine.test_master_trace import Clock, Double, HeldPlant, PlusOne, inproc


@pytest.mark.parametrize("scale, offset", [(1.3, 50.0), (1.3, None), (None, 50.0), (-0.1, 0.0)])
def test_transformed_input_trace(scale, offset):
    comps = {"clock": inproc("clock", Clock), "double": inproc("double", Double)}
    edges = [Edge("clock", "a", "double", "u", 0, scale, offset)]
    master = Master(comps, edges, tick=0.1, total_ticks=3, trace=True)
    master.run()
    seen = [inputs["u"] for _, name, inputs in master.trace if name == "double"]
    expected = []
    for k in range(4):
        x = 0.0 + k * 0.1  # t as the master computes it
        x = x * scale if scale is not None else x
        expected.append(x + offset if offset is not None else x)
    assert seen == expected  # exact floats: the same operations in the same order
    assert master.value("double", "y") == 2.0 * expected[-1]


def test_scale_only_adds_no_hidden_zero_offset():
    # scale alone is x * scale: no hidden "+ 0.0", which would turn -0.0 into 0.0
    comps = {"clock": inproc("clock", Clock), "double": inproc("double", Double)}
    master = Master(comps, [Edge("clock", "a", "double", "u", 0, -1.0, None)], tick=0.1,
                    total_ticks=0, trace=True)
    master.run()
    (_, _, inputs), = [t for t in master.trace if t[1] == "double"]
    assert str(inputs["u"]) == "-0.0"


def test_transformed_delayed_edge_reads_the_previous_tick():
    comps = {"double": inproc("double", Double), "plus": inproc("plus", PlusOne)}
    edges = [Edge("plus", "u", "double", "u", 0), Edge("double", "y", "plus", "y", 1, 0.5, 1.0)]
    master = Master(comps, edges, tick=0.1, total_ticks=2, trace=True)
    master.run()
    # tick 0: the delayed input holds its default 0.5 untransformed; then 0.5 * y + 1
    assert master.trace == [
        (0, "plus", {"y": 0.5}), (0, "double", {"u": 1.5}),
        (1, "plus", {"y": 0.5 * 3.0 + 1.0}), (1, "double", {"u": 3.5}),
        (2, "plus", {"y": 0.5 * 7.0 + 1.0}), (2, "double", {"u": 5.5}),
    ]


def test_fmu_like_plant_reads_the_transformed_value_held_since_the_last_tick():
    plant = HeldPlant("plant", 1, 0.1)
    comps = {"plant": plant, "clock": inproc("clock", Clock)}
    master = Master(comps, [Edge("clock", "a", "plant", "u", 0, 2.0, 1.0)], tick=0.1,
                    total_ticks=2, trace=True)
    master.run()
    plant_inputs = [inputs["u"] for _, name, inputs in master.trace if name == "plant"]
    # the plant steps first: at tick k it reads 2 * t_{k-1} + 1 (tick 0: clock not started yet)
    assert plant_inputs == [2.0 * 0.0 + 1.0, 2.0 * 0.0 + 1.0, 2.0 * 0.1 + 1.0]


def test_untransformed_edges_keep_reading_the_source_slot():
    comps = {"clock": inproc("clock", Clock), "double": inproc("double", Double)}
    master = Master(comps, [Edge("clock", "a", "double", "u", 0)], tick=0.1, total_ticks=1)
    slots = master.layout.slots["double"]
    assert slots.transforms == [] and master.layout.delayed_transforms == []
    assert slots.in_scalar_index == [master.layout.outputs[("clock", "a")][0]]


def test_transformation_on_an_array_edge_is_refused():
    from tests.engine.test_master_trace import Misbehaving  # has a 3-vector output w
    from cosim.component import Component, Port

    class TakesW(Component):
        inputs = (Port("w", size=3),)
        outputs = (Port("z"),)

    comps = {"m": inproc("m", Misbehaving, mode="none", at=99),
             "t": type("Host", (), {"inputs": TakesW.inputs, "outputs": TakesW.outputs,
                                    "period_ticks": 1})()}
    with pytest.raises(WiringError, match="scalar signals only"):
        Master(comps, [Edge("m", "w", "t", "w", 0, 2.0, None)], tick=0.1, total_ticks=1)
