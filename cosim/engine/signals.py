"""The master's signal store and the gather/scatter indices computed once.

Scalar signals live in one Python list of floats (`values`): indexing a list
is several times cheaper than indexing a numpy array element by element, and
the master moves scalars one by one. Array signals live in one float64 numpy
array (`arrays`). Every output port owns slots there, and a component's scalar
outputs are contiguous so they are written with one slice assignment.

Inputs read through indices computed once: a connected input reads its
source's slots; an unconnected input reads extra slots holding its default;
an input on a `delay: 1` edge reads extra slots that the master refreshes from
the source at the start of every tick (the value at the end of the previous
tick). An input on an edge with a linear transformation (`scale`, `offset`) also
reads extra slots: the master writes scale * x + offset there just before the
component gathers its inputs (or at the start of the tick, for a delayed edge).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np

from cosim.component import Port
from cosim.engine.schedule import wiring_error


#: (source slot, destination slot, scale or None, offset or None) in `values`.
Transform = tuple[int, int, Optional[float], Optional[float]]


@dataclass
class ComponentSlots:
    """Where one component's inputs come from and its outputs go.

    Attributes:
        in_scalar_names / in_scalar_index: scalar inputs and their `values` slots.
        in_arrays: (name, offset, size) of array inputs in `arrays`.
        out_scalar_names: scalar outputs, in slot order from out_scalar_start.
        out_arrays: (name, offset, size) of array outputs in `arrays`.
        transforms: (src slot, own slot, scale, offset) of the scalar inputs on
            transformed edges without delay, written just before each gather.
    """

    in_scalar_names: list[str] = field(default_factory=list)
    in_scalar_index: list[int] = field(default_factory=list)
    in_arrays: list[tuple[str, int, int]] = field(default_factory=list)
    out_scalar_names: list[str] = field(default_factory=list)
    out_scalar_start: int = 0
    out_arrays: list[tuple[str, int, int]] = field(default_factory=list)
    transforms: list[Transform] = field(default_factory=list)


def transformed(x: float, scale: float | None, offset: float | None) -> float:
    """x through a linear transformation: scale * x + offset, each part only where given."""
    if scale is not None:
        x = scale * x
    if offset is not None:
        x = x + offset
    return x


@dataclass
class SignalLayout:
    """The whole store: output slots, default slots, delay slots.

    Attributes:
        outputs: (component, port) -> (offset, size); offset indexes `values`
            when size == 1, `arrays` otherwise.
        ports: (component, port) -> the output Port declaration.
        initial_values / initial_arrays: initial content (defaults in place).
        slots: component name -> its ComponentSlots.
        scalar_delays / array_delays: (src, dst) slot pairs (arrays: ranges as
            (src_offset, dst_offset, size)) the master copies at each tick start.
        delayed_transforms: transformed delayed scalar edges (see Transform),
            written at each tick start from the value at the end of the last tick.
    """

    outputs: dict[tuple[str, str], tuple[int, int]]
    ports: dict[tuple[str, str], Port]
    initial_values: list[float]
    initial_arrays: np.ndarray
    slots: dict[str, ComponentSlots]
    scalar_delays: list[tuple[int, int]]
    array_delays: list[tuple[int, int, int]]
    delayed_transforms: list[Transform] = field(default_factory=list)

    def scalar_columns(self) -> list[tuple[str, int]]:
        """("component.signal", index in values) of every scalar output."""
        return [(f"{c}.{p}", off) for (c, p), (off, size) in self.outputs.items() if size == 1]

    def array_signals(self) -> list[tuple[str, str, int, int]]:
        """(component, signal, offset in arrays, size) of every array output."""
        return [(c, p, off, size) for (c, p), (off, size) in self.outputs.items() if size > 1]


class _Store:
    """Hands out scalar and array slots and records their initial values."""

    def __init__(self) -> None:
        self.values: list[float] = []
        self.arrays: list[float] = []

    def take(self, port: Port) -> int:
        if port.size == 1:
            self.values.append(float(port.default))
            return len(self.values) - 1
        offset = len(self.arrays)
        self.arrays.extend([float(port.default)] * port.size)
        return offset


def build_layout(components: Mapping[str, Any], edges: Iterable[Any]) -> SignalLayout:
    """Allocate the store for hosted components and resolved edges.

    Args:
        components: name -> object with `inputs` and `outputs` (tuples of Port),
            in declaration order.
        edges: resolved connections (src, src_port, dst, dst_port, delay).
    Raises:
        WiringError for an edge naming an unknown port, an input fed twice,
        a size mismatch between the two ends or a delay other than 0 and 1.
    """
    store = _Store()
    outputs: dict[tuple[str, str], tuple[int, int]] = {}
    ports: dict[tuple[str, str], Port] = {}
    slots = {name: ComponentSlots() for name in components}
    for name, comp in components.items():
        slots[name].out_scalar_start = len(store.values)
        for port in (p for p in comp.outputs if p.size == 1):  # contiguous scalars
            outputs[(name, port.name)] = (store.take(port), 1)
        for port in comp.outputs:
            if port.size > 1:
                outputs[(name, port.name)] = (store.take(port), port.size)
            ports[(name, port.name)] = port
            _add_output(slots[name], port, outputs[(name, port.name)][0])
    feeds = _index_edges(components, edges, outputs)
    scalar_delays: list[tuple[int, int]] = []
    array_delays: list[tuple[int, int, int]] = []
    delayed_transforms: list[Transform] = []
    for name, comp in components.items():
        for port in comp.inputs:
            edge = feeds.get((name, port.name))
            if edge is None:
                offset = store.take(port)
            elif _transform_of(edge) is not None:
                offset = store.take(port)
                scale, shift = _transform_of(edge)
                src = outputs[(edge.src, edge.src_port)][0]
                (delayed_transforms if edge.delay else slots[name].transforms).append(
                    (src, offset, scale, shift))
            elif edge.delay:
                src = outputs[(edge.src, edge.src_port)][0]
                offset = store.take(port)
                if port.size == 1:
                    scalar_delays.append((src, offset))
                else:
                    array_delays.append((src, offset, port.size))
            else:
                offset = outputs[(edge.src, edge.src_port)][0]
            _add_input(slots[name], port, offset)
    return SignalLayout(outputs, ports, store.values, np.array(store.arrays, dtype=np.float64),
                        slots, scalar_delays, array_delays, delayed_transforms)


def _transform_of(edge: Any) -> tuple[float | None, float | None] | None:
    """(scale, offset) of an edge with a linear transformation, else None."""
    scale, offset = getattr(edge, "scale", None), getattr(edge, "offset", None)
    return None if scale is None and offset is None else (scale, offset)


def _index_edges(components: Mapping[str, Any], edges: Iterable[Any],
                 outputs: dict[tuple[str, str], tuple[int, int]]) -> dict[tuple[str, str], Any]:
    """Map (dst, dst_port) -> edge, checking both ends exist and sizes agree."""
    feeds: dict[tuple[str, str], Any] = {}
    for edge in edges:
        where = f"connection {edge.src}.{edge.src_port} -> {edge.dst}.{edge.dst_port}"
        if (edge.src, edge.src_port) not in outputs:
            raise wiring_error(f"{where}: {edge.src!r} has no output {edge.src_port!r}")
        if edge.dst not in components:
            raise wiring_error(f"{where}: no component {edge.dst!r}")
        dst_ports = {p.name: p for p in components[edge.dst].inputs}
        if edge.dst_port not in dst_ports:
            raise wiring_error(f"{where}: {edge.dst!r} has no input {edge.dst_port!r}")
        if (edge.dst, edge.dst_port) in feeds:
            raise wiring_error(f"{where}: input {edge.dst}.{edge.dst_port} is fed twice")
        src_size = outputs[(edge.src, edge.src_port)][1]
        if src_size != dst_ports[edge.dst_port].size:
            raise wiring_error(f"{where}: size {src_size} does not match size "
                               f"{dst_ports[edge.dst_port].size}")
        if edge.delay not in (0, 1):
            raise wiring_error(f"{where}: delay must be 0 or 1, got {edge.delay!r}")
        if _transform_of(edge) is not None and src_size != 1:
            raise wiring_error(f"{where}: scale/offset apply to scalar signals only")
        feeds[(edge.dst, edge.dst_port)] = edge
    return feeds


def _add_input(slot: ComponentSlots, port: Port, offset: int) -> None:
    if port.size == 1:
        slot.in_scalar_names.append(port.name)
        slot.in_scalar_index.append(offset)
    else:
        slot.in_arrays.append((port.name, offset, port.size))


def _add_output(slot: ComponentSlots, port: Port, offset: int) -> None:
    if port.size == 1:
        slot.out_scalar_names.append(port.name)
    else:
        slot.out_arrays.append((port.name, offset, port.size))
