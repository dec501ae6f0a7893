"""Connections of a scenario, resolved to edges between declared ports and checked.

`resolve_wiring` expands the short form `a -> b` (every output of a feeding
the input of b with the same name) and checks every connection against the
components' ports: the components and ports exist, the source is an output
and the destination an input, sizes and units agree, and no input is driven
twice, and the source's type converts exactly into the destination's
(`cosim.signal_types.exact_into`: an Int32 output may feed a Float64 input,
a Float64 output an Integer input only with `convert: float`). An explicit
`a.x -> b.y` connection takes precedence over a short form for the same input
(so `vehicle -> controller` plus one explicit exception works); two explicit
connections, or two short forms, to one input are an error. Every problem is reported at once, with the connection's YAML line.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from cosim.component import Port
from cosim.errors import Problem, WiringError, did_you_mean
from cosim.signal_types import FLOAT64, a_type, exact_into

PortTable = Mapping[str, tuple[tuple[Port, ...], tuple[Port, ...]]]


@dataclass(frozen=True)
class Edge:
    """One resolved signal edge: src.src_port feeds dst.dst_port, `delay` ticks late.

    `scale` and `offset`, when given, make the input read scale * x + offset (each
    only where given: x * scale, x + offset); None leaves the value untouched.
    `convert` ("float") accepts types whose conversion is not exact.
    """

    src: str
    src_port: str
    dst: str
    dst_port: str
    delay: int = 0
    scale: float | None = None
    offset: float | None = None
    convert: str | None = None


@dataclass(frozen=True)
class _Candidate:
    """An edge before the driven-twice check, with the connection it came from."""

    edge: Edge
    index: int
    explicit: bool


def resolve_wiring(scenario: Any, ports: PortTable,
                   unsupported: Mapping[str, Mapping[str, str]] | None = None) -> list[Edge]:
    """Resolve and check a scenario's connections.

    Args:
        scenario: a validated cosim.scenario.loader.Scenario (its `connections`, file, lines).
        ports: component name -> (inputs, outputs), for every component and source.
        unsupported: component name -> {variable: why} for FMU variables that
            exist but cannot be connected (FmuInterface.unsupported).
    Returns:
        the edges, in connection order (a short form expands in output order).
    Raises:
        WiringError: listing every bad connection with its YAML path and line.
    """
    problems: list[Problem] = []
    candidates: list[_Candidate] = []
    for index, connection in enumerate(scenario.connections):
        loc = ("connections", index)
        found, messages = _resolve_one(connection, ports, unsupported or {})
        problems += [scenario.problem(loc, m) for m in messages]
        candidates += [_Candidate(e, index, not connection.is_short) for e in found]
    kept, twice = _drop_overridden(candidates, scenario.line_of)
    problems += [scenario.problem(("connections", i), m) for i, m in twice]
    for cand in kept:  # short forms are checked after explicit connections took precedence
        mismatch = None if cand.explicit else _compatibility(cand.edge, ports, short=True)
        if mismatch:
            text = f"{scenario.connections[cand.index].src} -> {scenario.connections[cand.index].dst}"
            problems.append(scenario.problem(("connections", cand.index), f"{text}: {mismatch}"))
    if problems:
        problems.sort(key=lambda p: (p.line is None, p.line or 0))
        raise WiringError(scenario.source_file, problems)
    return [cand.edge for cand in kept]


def _resolve_one(connection: Any, ports: PortTable,
                 unsupported: Mapping[str, Mapping[str, str]]) -> tuple[list[Edge], list[str]]:
    """Edges of one connection and the problems with it."""
    text = f"{connection.src} -> {connection.dst}"
    missing = [_unknown_component(name, ports)
               for name in dict.fromkeys((connection.src_component, connection.dst_component))
               if name not in ports]
    if missing:
        return [], [f"{text}: {m}" for m in missing]
    if connection.is_short:
        return _expand_short(connection, ports, text)
    messages = [m for m in (
        _port_problem(connection.src_component, connection.src_port, "output", ports, unsupported),
        _port_problem(connection.dst_component, connection.dst_port, "input", ports, unsupported),
    ) if m]
    if messages:
        return [], [f"{text}: {m}" for m in messages]
    edge = Edge(connection.src_component, connection.src_port, connection.dst_component,
                connection.dst_port, connection.delay, connection.scale, connection.offset,
                getattr(connection, "convert", None))
    mismatch = _compatibility(edge, ports)
    return ([], [f"{text}: {mismatch}"]) if mismatch else ([edge], [])


def _expand_short(connection: Any, ports: PortTable, text: str) -> tuple[list[Edge], list[str]]:
    """Edges of `a -> b`: every output of a with the name of an input of b."""
    src, dst = connection.src_component, connection.dst_component
    inputs = {p.name for p in ports[dst][0]}
    edges = [Edge(src, p.name, dst, p.name, connection.delay,
                  convert=getattr(connection, "convert", None))
             for p in ports[src][1] if p.name in inputs]
    if not edges:
        outs = ", ".join(p.name for p in ports[src][1]) or "none"
        ins = ", ".join(p.name for p in ports[dst][0]) or "none"
        return [], [f"{text}: no output of {src!r} has the name of an input of {dst!r} "
                    f"(outputs of {src}: {outs}; inputs of {dst}: {ins})"]
    return edges, []


def _unknown_component(name: str, ports: PortTable) -> str:
    """Message for a connection naming a component that does not exist."""
    return f"no component or source named {name!r}{did_you_mean(name, ports)}; known: {', '.join(ports)}"


def _port_problem(component: str, port: str, side: str, ports: PortTable,
                  unsupported: Mapping[str, Mapping[str, str]]) -> str | None:
    """What is wrong with using component.port as an `side` ("output"/"input"), or None."""
    inputs, outputs = ports[component]
    wanted, other = (outputs, inputs) if side == "output" else (inputs, outputs)
    if any(p.name == port for p in wanted):
        return None
    role = "source" if side == "output" else "destination"
    if any(p.name == port for p in other):
        other_side = "input" if side == "output" else "output"
        return (f"wrong causality: {component}.{port} is an {other_side}, but a connection's "
                f"{role} must be an {side}")
    reason = unsupported.get(component, {}).get(port)
    if reason:
        return f"{component}.{port} cannot be connected: it is {reason}"
    names = [p.name for p in wanted]
    return (f"{component!r} has no {side} {port!r}{did_you_mean(port, names)}; its {side}s: "
            f"{', '.join(names) or 'none'}")


def _compatibility(edge: Edge, ports: PortTable, short: bool = False) -> str | None:
    """A size, type or unit mismatch between the two ends of an edge, or None.

    Args:
        edge: the edge; ports: the port table.
        short: the edge comes from a short form, so the message names its ports.
    """
    out = next(p for p in ports[edge.src][1] if p.name == edge.src_port)
    inp = next(p for p in ports[edge.dst][0] if p.name == edge.dst_port)
    ends = f" on {edge.src}.{edge.src_port} -> {edge.dst}.{edge.dst_port}" if short else ""
    if out.size != inp.size:
        return f"size mismatch{ends}: output has {out.size} values, input takes {inp.size}"
    transformed = edge.scale is not None or edge.offset is not None
    if transformed and out.size != 1:
        return f"scale/offset apply to scalar signals only; this one has {out.size} values"
    source_type = FLOAT64 if transformed else out.type  # scale * x + offset is a float
    if edge.convert is None and not exact_into(source_type, inp.type):
        return (f"type mismatch{ends}: {a_type(source_type)} output into {a_type(inp.type)} "
                "input is not an exact conversion (add convert: float to the connection to "
                "accept it)")
    if transformed:
        return None  # the transformation is the unit conversion: the user owns it
    if out.unit and inp.unit and out.unit != inp.unit:
        return f"unit mismatch{ends}: output in {out.unit!r}, input in {inp.unit!r}"
    return None


def _drop_overridden(candidates: list[_Candidate], line_of: Callable[[tuple], int | None]
                     ) -> tuple[list[_Candidate], list[tuple[int, str]]]:
    """Apply explicit-over-short precedence; report inputs still driven twice."""
    by_input: dict[tuple[str, str], list[_Candidate]] = {}
    for cand in candidates:
        by_input.setdefault((cand.edge.dst, cand.edge.dst_port), []).append(cand)
    kept: set[int] = set()
    twice: list[tuple[int, str]] = []
    for (dst, port), group in by_input.items():
        if any(c.explicit for c in group):
            group = [c for c in group if c.explicit]
        first = group[0]
        kept.add(id(first))
        line = line_of(("connections", first.index))
        where = f"connections[{first.index}]" + (f", line {line}" if line is not None else "")
        for cand in group[1:]:
            twice.append((cand.index, (
                f"input {dst}.{port} is driven twice: by {cand.edge.src}.{cand.edge.src_port} "
                f"here and by {first.edge.src}.{first.edge.src_port} "
                f"({where})")))
    return [c for c in candidates if id(c) in kept], twice


def unconnected_inputs(edges: Iterable[Edge], ports: PortTable) -> list[tuple[str, Port]]:
    """Inputs that no edge drives (they hold their default value): for warnings.

    Args:
        edges: the resolved edges.
        ports: component name -> (inputs, outputs).
    Returns:
        (component name, input port) pairs, in component and port order.
    """
    driven = {(e.dst, e.dst_port) for e in edges}
    return [(name, port) for name, (inputs, _) in ports.items()
            for port in inputs if (name, port.name) not in driven]


def outputs_read(edges: Iterable[Edge], ports: PortTable,
                 recorded: Callable[[str], bool]) -> dict[str, frozenset[str]]:
    """Each component's outputs that the run reads (what `Component.use_outputs` receives).

    Every scalar output counts (the live view shows them all), and each array output
    that an edge carries or that is recorded.

    Args:
        edges: the resolved edges.
        ports: component name -> (inputs, outputs).
        recorded: whether the recorder keeps "component.signal".
    """
    carried = {(e.src, e.src_port) for e in edges}
    return {name: frozenset(port.name for port in outputs
                            if port.size == 1 or (name, port.name) in carried
                            or recorded(f"{name}.{port.name}"))
            for name, (_, outputs) in ports.items()}
