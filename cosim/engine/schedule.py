"""The order in which the master steps components within one tick (Gauss-Seidel).

An edge `a -> b` forces `a` before `b` when `b` has direct feedthrough (a Python
component reads its inputs at t and answers at t) and the edge carries no
explicit delay. Edges into an FMU do not constrain the order: an FMU has no
direct feedthrough, it integrates from t_prev to t with the inputs held since
t_prev, so it steps first (that is the feedback edge with its implicit one-tick
delay). Among unconstrained components, components without feedthrough come
first, then declaration order: the order is deterministic.
"""

from __future__ import annotations

import heapq
from collections.abc import Iterable, Sequence
from typing import Any

from cosim.errors import Problem, WiringError


def ordering_edges(edges: Iterable[Any], feedthrough: dict[str, bool]) -> set[tuple[str, str]]:
    """The (src, dst) pairs that constrain the step order.

    Args:
        edges: resolved connections with attributes src, dst, delay.
        feedthrough: component name -> whether it has direct feedthrough.
    """
    pairs = set()
    for edge in edges:
        if edge.delay == 0 and feedthrough[edge.dst] and edge.src != edge.dst:
            pairs.add((edge.src, edge.dst))
    return pairs


def step_order(names: Sequence[str], feedthrough: dict[str, bool],
               edges: Iterable[Any]) -> list[str]:
    """Topological step order of the components.

    Args:
        names: component names in declaration order.
        feedthrough: component name -> direct feedthrough (False for FMUs).
        edges: resolved connections (src, dst, delay attributes).
    Raises:
        WiringError naming the loop when components with feedthrough form a
        cycle without a `delay: 1` edge.
    """
    edges = list(edges)
    for edge in edges:
        if edge.delay == 0 and edge.src == edge.dst and feedthrough[edge.dst]:
            raise wiring_error(f"algebraic loop: {edge.src} -> {edge.src} "
                              f"({edge.src_port} -> {edge.dst_port}) needs delay: 1")
    pairs = ordering_edges(edges, feedthrough)
    rank = {name: (1 if feedthrough[name] else 0, i) for i, name in enumerate(names)}
    indegree = {name: 0 for name in names}
    successors: dict[str, list[str]] = {name: [] for name in names}
    for src, dst in sorted(pairs):
        successors[src].append(dst)
        indegree[dst] += 1
    ready = [(rank[n], n) for n in names if indegree[n] == 0]
    heapq.heapify(ready)
    order: list[str] = []
    while ready:
        _, name = heapq.heappop(ready)
        order.append(name)
        for dst in successors[name]:
            indegree[dst] -= 1
            if indegree[dst] == 0:
                heapq.heappush(ready, (rank[dst], dst))
    if len(order) < len(names):
        loop = find_cycle([n for n in names if n not in order], pairs)
        raise wiring_error("algebraic loop between components with direct feedthrough: "
                          + " -> ".join(loop)
                          + "; mark one of these connections with delay: 1")
    return order


def find_cycle(nodes: Sequence[str], pairs: set[tuple[str, str]]) -> list[str]:
    """One cycle among `nodes` (closed: first name repeated at the end).

    Args:
        nodes: names left over by the topological sort (each lies on or
            downstream of a cycle).
        pairs: ordering edges (src, dst).
    """
    remaining = set(nodes)
    # Every leftover node has a leftover predecessor: walk predecessors until a
    # name repeats, then read the loop forwards.
    pred = {n: sorted(s for s, d in pairs if d == n and s in remaining) for n in nodes}
    path: list[str] = [nodes[0]]
    seen = {nodes[0]: 0}
    while True:
        back = pred[path[-1]][0]
        if back in seen:
            cycle = path[seen[back]:] + [back]
            cycle.reverse()
            return cycle
        seen[back] = len(path)
        path.append(back)


def wiring_error(message: str) -> WiringError:
    """A WiringError about the scenario's connections as a whole."""
    return WiringError(None, [Problem("connections", None, message)])
