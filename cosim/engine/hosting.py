"""How the master drives a component, wherever it runs.

The master never calls a Component directly: it drives a `HostedComponent`,
which may wrap a Python component in this process (inproc), proxy one running
in another OS process over Zenoh, or wrap an FMU through fmpy. Every transport
implements this protocol, so the master loop is the same for all of them and
results are bit-identical across transports.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol

from cosim.component import Port, Value


class HostedComponent(Protocol):
    """A component as the master sees it.

    Attributes:
        name: the component's name in the scenario ("vehicle", "controller", ...).
        inputs / outputs: the declared ports (known before `start`).
        period_ticks: how many master ticks between two steps (>= 1).

    Optional, the values lane: a host may also offer `step_values(tick, t,
    inputs) -> outputs`, the same step as `step` with both sides plain
    sequences, in the orders its `value_names` = (input names, output names)
    gives: in, the float or read-only array the mapping would hold for each
    input; out, one float per output. The master uses it (no mapping built or
    read per step) for a component whose outputs are all scalars when
    `value_names` names every input and every output in declared order (None:
    no lane); `trace=True` keeps the mapping. The FMU host offers it for
    Float64 scalar ports, the in-process host for a Python component that
    defines `step_values` (`cosim.component`). The master tests the result's
    length and type (one sum), unless the host sets `values_exact` = True:
    it always returns a list of as many Python floats as outputs (the FMU host).

    Optional too: `use_outputs(names)`, which passes on to a Python component
    the outputs the run reads (`cosim.component.Component.use_outputs`); the
    master calls it once on every host that has it, before starting any.
    """

    name: str
    inputs: tuple[Port, ...]
    outputs: tuple[Port, ...]
    period_ticks: int

    def start(self, t0: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Initialize at t0 and return the initial outputs."""
        ...

    def step(self, tick: int, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Advance to time t (= t0 + tick * master tick) and return every output."""
        ...

    def stop(self) -> dict[str, float]:
        """End the component (process, FMU instance); return its final metrics."""
        ...
