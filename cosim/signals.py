"""The master's flat signal buffer and the precomputed gather/scatter indices.

Every output port of every component owns a slot range in one float64 array.
Inputs are read from that array through indices computed once: a connected
input reads its source's slots, an unconnected input reads extra slots that hold
its default, and an input on a `delay: 1` edge reads slots that the master
refreshes from the source at the start of every tick (the value as of the end
of the previous tick).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cosim.component import Port
from cosim.schedule import wiring_error


@dataclass
class ComponentSlots:
    """Where one component's inputs come from and its outputs go, in the buffer.

    Scalar ports use single indices, array ports (offset, size) ranges.
    """

    in_scalar_names: list[str] = field(default_factory=list)
    in_scalar_index: list[int] = field(default_factory=list)
    in_arrays: list[tuple[str, int, int]] = field(default_factory=list)
    out_scalar_names: list[str] = field(default_factory=list)
    out_scalar_index: list[int] = field(default_factory=list)
    out_arrays: list[tuple[str, int, int]] = field(default_factory=list)


@dataclass
class SignalLayout:
    """The whole buffer: output slots, default slots, delay slots.

    Attributes:
        outputs: (component, port) -> (offset, size) of every output port.
        ports: (component, port) -> the output Port declaration.
        initial: the buffer's initial content (defaults in place).
        slots: component name -> its ComponentSlots.
        delay_src / delay_dst: index arrays; at each tick start the master
            copies buffer[delay_src] into buffer[delay_dst].
    """

    outputs: dict[tuple[str, str], tuple[int, int]]
    ports: dict[tuple[str, str], Port]
    initial: np.ndarray
    slots: dict[str, ComponentSlots]
    delay_src: np.ndarray
    delay_dst: np.ndarray

    def scalar_columns(self) -> list[tuple[str, int]]:
        """("component.signal", index) of every scalar output, in buffer order."""
        return [(f"{c}.{p}", off) for (c, p), (off, size) in self.outputs.items() if size == 1]

    def array_signals(self) -> list[tuple[str, str, int, int]]:
        """(component, signal, offset, size) of every array output."""
        return [(c, p, off, size) for (c, p), (off, size) in self.outputs.items() if size > 1]


class _Allocator:
    """Hands out consecutive slot ranges and records their initial values."""

    def __init__(self) -> None:
        self.values: list[float] = []

    def take(self, size: int, value: float) -> int:
        offset = len(self.values)
        self.values.extend([float(value)] * size)
        return offset


def build_layout(components: Mapping[str, Any], edges: Iterable[Any]) -> SignalLayout:
    """Allocate the buffer for hosted components and resolved edges.

    Args:
        components: name -> object with `inputs` and `outputs` (tuples of Port),
            in declaration order.
        edges: resolved connections (src, src_port, dst, dst_port, delay).
    Raises:
        WiringError for an edge naming an unknown port, an input fed twice or a
        size mismatch between the two ends.
    """
    alloc = _Allocator()
    outputs: dict[tuple[str, str], tuple[int, int]] = {}
    ports: dict[tuple[str, str], Port] = {}
    for name, comp in components.items():
        for port in comp.outputs:
            outputs[(name, port.name)] = (alloc.take(port.size, port.default), port.size)
            ports[(name, port.name)] = port
    feeds = _index_edges(components, edges, outputs)
    delay_src: list[int] = []
    delay_dst: list[int] = []
    slots: dict[str, ComponentSlots] = {}
    for name, comp in components.items():
        slot = ComponentSlots()
        for port in comp.inputs:
            edge = feeds.get((name, port.name))
            if edge is None:
                offset = alloc.take(port.size, port.default)
            elif edge.delay:
                src_off = outputs[(edge.src, edge.src_port)][0]
                offset = alloc.take(port.size, port.default)
                delay_src.extend(range(src_off, src_off + port.size))
                delay_dst.extend(range(offset, offset + port.size))
            else:
                offset = outputs[(edge.src, edge.src_port)][0]
            _add_input(slot, port, offset)
        for port in comp.outputs:
            _add_output(slot, port, outputs[(name, port.name)][0])
        slots[name] = slot
    return SignalLayout(outputs, ports, np.array(alloc.values, dtype=np.float64), slots,
                        np.array(delay_src, dtype=np.intp), np.array(delay_dst, dtype=np.intp))


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
        slot.out_scalar_index.append(offset)
    else:
        slot.out_arrays.append((port.name, offset, port.size))
