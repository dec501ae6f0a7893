"""`cosim validate`: check a scenario as far as possible without running it.

Everything `cosim run` checks before tick 0, with the Python components
constructed in this process to read their ports: FMUs, parameters, wiring,
array layouts and the step order.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from cosim.errors import UserError
from cosim.execution.abort import locate_parameter_problem
from cosim.execution.limits import RunLimits, check_formats, check_recorded_size, check_ticks


def validate_scenario(scenario: Any, limits: RunLimits | None = None,
                      strict: bool = False) -> dict[str, Any]:
    """Check a scenario as far as possible without running it.

    Resolves and describes the FMUs (their archives too), checks parameters,
    constructs the Python components in this process to read their ports,
    resolves the wiring, derives the step order (an algebraic loop is an
    error) and lists the interface gaps (`cosim.execution.completeness`).

    Args:
        scenario: a validated `cosim.scenario.loader.Scenario`.
        limits: how large the run may be (default: the defaults of `cosim run`).
        strict: interface gaps are errors.
    Returns:
        {"components": name -> (inputs, outputs), "edges": [...], "order": [...],
        "warnings": [...]}.
    Raises:
        UserError describing the first class of problems found.
    """
    from cosim.transport.inproc import construct_component
    from cosim.execution.completeness import interface_gaps, report_gaps, unrecorded_outputs
    from cosim.execution.prepare import prepare_run

    limits = limits or RunLimits()
    check_ticks(scenario, limits)
    check_formats(scenario)
    try:
        prepared = prepare_run(scenario)
        prepared.limits = limits
        checked = _validate_prepared(scenario, prepared, construct_component)
        checked["warnings"] = interface_gaps(scenario, checked["components"], checked["edges"])
        report_gaps(checked["warnings"], strict, None)
        checked["warnings"] += unrecorded_outputs(scenario, prepared.fmus)
        return checked
    except UserError as exc:
        located = locate_parameter_problem(scenario, exc)
        if located is not None:
            raise located from None
        raise


def _validate_prepared(scenario: Any, prepared: Any,
                       construct_component: Callable[[Any], Any]) -> dict[str, Any]:
    """validate_scenario's checks after prepare_run (see there)."""
    from cosim.engine.schedule import step_order
    from cosim.engine.signals import build_layout
    from cosim.engine.wiring import resolve_wiring

    ports: dict[str, tuple[Any, Any]] = {}
    feedthrough: dict[str, bool] = {}
    for plan in prepared.fmus:
        ports[plan.name] = (plan.interface.inputs, plan.interface.outputs)
        feedthrough[plan.name] = False
    for launch in prepared.launches:  # built for their ports, never stepped
        comp = construct_component(dataclasses.replace(launch, steps=0))
        ports[launch.name] = (tuple(comp.inputs), tuple(comp.outputs))
        feedthrough[launch.name] = True
    ports = {name: ports[name] for name in prepared.names}
    edges = resolve_wiring(scenario, ports,
                           {plan.name: plan.interface.unsupported for plan in prepared.fmus})
    layout = build_layout({n: _Ports(*p) for n, p in ports.items()}, edges)
    periods = {plan.name: plan.period_ticks for plan in [*prepared.fmus, *prepared.launches]}
    check_recorded_size(scenario, layout, periods, prepared.limits)
    order = step_order(prepared.names, feedthrough, edges)
    return {"components": ports, "edges": edges, "order": order}


@dataclass
class _Ports:
    inputs: Any
    outputs: Any
