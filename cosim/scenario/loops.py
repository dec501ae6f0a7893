"""An algebraic loop found by the engine, located at the scenario's connections.

The step order (`cosim.engine.schedule.step_order`) sees resolved edges, not
the file, so the `WiringError` it raises for a loop of components with direct
feedthrough names the components only ("<scenario>: connections: algebraic
loop ...: a -> b -> a; ..."). `locate_loop` turns it into one line at the
connection of the loop in the file (the one a `--set` changed, if any, with
its "(set by --set ...)" note), listing the loop's other connections and their
lines:

    loop.yaml:8: connections[0]: algebraic loop between components with direct
    feedthrough: a -> b -> a; mark one of these connections with delay: 1 (the
    loop: connections[0] at line 8, connections[1] at line 9)

It is reached through `Scenario.locate(error)`.
"""

from __future__ import annotations

import re
from typing import Any

from cosim.errors import Problem, WiringError
from cosim.scenario.yaml_lines import format_path

#: the two messages of cosim.engine.schedule: a loop through several components, a self-loop
_LOOP = re.compile(r"algebraic loop between components with direct feedthrough: "
                   r"(?P<names>\w+(?: -> \w+)+);")
_SELF_LOOP = re.compile(r"algebraic loop: (?P<name>\w+) -> (?P=name) "
                        r"\((?P<src_port>[^ ]+) -> (?P<dst_port>[^ )]+)\)")


def locate_loop(scenario: Any, error: BaseException) -> WiringError | None:
    """The loop error of the step order, located at the scenario's connections.

    Args:
        scenario: the validated `Scenario` the error is about.
        error: what deriving the step order raised.
    Returns:
        a WiringError of one problem at the loop's connection in the file; None
        when `error` is no algebraic loop without a place, or when no connection
        of the scenario makes the loop.
    """
    problems = getattr(error, "problems", None)
    if not isinstance(error, WiringError) or not problems or len(problems) != 1:
        return None
    problem = problems[0]
    if problem.path != "connections" or problem.line is not None:
        return None
    indices = _loop_connections(scenario.connections, problem.message)
    if not indices:
        return None
    overrides = {i: scenario.overrides_within(("connections", i)) for i in indices}
    chosen = next((i for i in indices if overrides[i]), indices[0])
    message = problem.message
    if len(indices) > 1:
        message += " (the loop: " + ", ".join(_shown(scenario, i) for i in indices) + ")"
    message += "".join(f" (set by --set {text})" for i in indices for text in overrides[i])
    path = ("connections", chosen)
    return WiringError(scenario.source_file,
                       [Problem(format_path(path), scenario.line_of(path), message)])


def _loop_connections(connections: list[Any], message: str) -> list[int]:
    """Indices of the undelayed connections that make the loop a message names, in file order."""
    self_loop = _SELF_LOOP.search(message)
    if self_loop is not None:
        name = self_loop["name"]
        return [i for i, c in enumerate(connections)
                if c.delay == 0 and c.src_component == name and c.dst_component == name
                and (c.is_short or (c.src_port, c.dst_port) == (self_loop["src_port"],
                                                                self_loop["dst_port"]))]
    loop = _LOOP.search(message)
    if loop is None:
        return []
    names = loop["names"].split(" -> ")
    pairs = set(zip(names, names[1:]))
    return [i for i, c in enumerate(connections)
            if c.delay == 0 and (c.src_component, c.dst_component) in pairs]


def _shown(scenario: Any, index: int) -> str:
    """"connections[1] at line 9", or "connections[1]" when a --set wrote it whole."""
    path = ("connections", index)
    line = scenario.line_of(path)
    return format_path(path) + (f" at line {line}" if line is not None else "")
