"""The real master loop over the Zenoh transport gives bit-identical signals to
the same closed loop hosted in-process (multi-rate, feedback with delays; a
component with `step_values`, scalar and array inputs, on the master's values
lane both ways; over Zenoh every component with scalar outputs is on the lane,
whatever its class: the wire carries values in declared order)."""

from __future__ import annotations

import os

import numpy as np
import pytest

from cosim.transport.inproc import InprocComponent
from cosim.engine.master import Master
from cosim.engine.wiring import Edge
from cosim.transport.zenoh import ZenohComponents
from tests.helpers.components import launch, run_processes

pytestmark = [pytest.mark.integration, pytest.mark.timeout(60)]

SPECS = [launch("m1", "Mixer", gain=0.7), launch("m2", "Mixer", 2, gain=-1.3),
         launch("echo", "Echo"), launch("track", "Tracker", k=1.3)]
EDGES = [Edge("m1", "z", "m2", "w"), Edge("m2", "z", "m1", "w", 1),
         Edge("m2", "y", "echo", "u"), Edge("echo", "y", "m1", "u", 1),
         Edge("m1", "y", "track", "x"), Edge("m1", "z", "track", "ref"),
         Edge("echo", "y", "track", "v"), Edge("m2", "z", "track", "w"),
         Edge("track", "u", "m2", "u", 1)]


class Tape:
    """Observer keeping an exact copy of the whole signal store after every tick."""

    def __init__(self) -> None:
        self.rows: list[tuple[int, float, bytes, bytes]] = []

    def begin(self, master: Master) -> None:
        pass

    def after_tick(self, tick: int, t: float, values: list[float], arrays: np.ndarray) -> None:
        self.rows.append((tick, t, np.array(values, dtype=np.float64).tobytes(), arrays.tobytes()))


def run(hosted, ticks: int) -> tuple[Tape, Master]:
    return run_with(hosted, EDGES, ticks)


def run_with(hosted, edges, ticks: int) -> tuple[Tape, Master]:
    tape = Tape()
    master = Master(hosted, edges, 0.01, ticks, 0.0, [tape])
    master.run()
    master.stop_all()
    return tape, master


def test_master_over_zenoh_matches_inproc_bit_for_bit():
    inproc, in_master = run({s.name: InprocComponent(s) for s in SPECS}, 200)
    run_id = f"t-master-{os.getpid()}"
    with ZenohComponents(SPECS, run_id) as hosted:
        zenoh, zenoh_master = run(hosted.components, 200)
    lanes = {master: {p.name for p in master._plans if p.step_values is not None}
             for master in (in_master, zenoh_master)}
    assert lanes[in_master] == {"track"} and lanes[zenoh_master] == {"track", "echo"}
    assert len(zenoh.rows) == 201
    assert zenoh.rows == inproc.rows
    assert run_processes(run_id) == []


def test_a_component_iterates_its_inputs_in_the_same_order_on_both_transports():
    spec = launch("probe", "InputOrder")
    edges = [Edge("m1", "y", "probe", "a"), Edge("m1", "z", "probe", "w"), Edge("m1", "y", "probe", "b")]
    specs = [launch("m1", "Mixer", gain=0.5), spec]
    inproc, in_master = run_with({s.name: InprocComponent(s) for s in specs}, edges, 5)
    with ZenohComponents(specs, f"t-order-{os.getpid()}") as hosted:
        zenoh, zenoh_master = run_with(hosted.components, edges, 5)
    assert in_master.value("probe", "order") == 132.0          # scalars a, b, then the array w
    assert zenoh_master.value("probe", "order") == 132.0
    assert zenoh.rows == inproc.rows
