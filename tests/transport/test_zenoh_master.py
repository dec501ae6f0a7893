"""The real master loop over the Zenoh transport gives bit-identical signals to
the same closed loop hosted in-process (multi-rate, feedback with delays)."""

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
         launch("echo", "Echo")]
EDGES = [Edge("m1", "z", "m2", "w"), Edge("m2", "z", "m1", "w", 1),
         Edge("m2", "y", "echo", "u"), Edge("echo", "y", "m1", "u", 1)]


class Tape:
    """Observer keeping an exact copy of the whole signal store after every tick."""

    def __init__(self) -> None:
        self.rows: list[tuple[int, float, bytes, bytes]] = []

    def begin(self, master: Master) -> None:
        pass

    def after_tick(self, tick: int, t: float, values: list[float], arrays: np.ndarray) -> None:
        self.rows.append((tick, t, np.array(values, dtype=np.float64).tobytes(), arrays.tobytes()))


def run(hosted, ticks: int) -> Tape:
    tape = Tape()
    master = Master(hosted, EDGES, 0.01, ticks, 0.0, [tape])
    master.run()
    master.stop_all()
    return tape


def test_master_over_zenoh_matches_inproc_bit_for_bit():
    inproc = run({s.name: InprocComponent(s) for s in SPECS}, 200)
    run_id = f"t-master-{os.getpid()}"
    with ZenohComponents(SPECS, run_id) as hosted:
        zenoh = run(hosted.components, 200)
    assert len(zenoh.rows) == 201
    assert zenoh.rows == inproc.rows
    assert run_processes(run_id) == []
