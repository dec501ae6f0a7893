"""`cosim export-ssp`: the FMU part of a scenario as an SSP package.

The scenario is checked as `cosim validate` checks it; then its FMU
components (built-in ones from the FMU cache), the connections between them
(short forms expanded, scale/offset kept) and their parameter values
(uncertainty applied) are written by `cosim.scenario.ssp_write`, under the FMUs'
own variable names. Python components, sources, connections to them and the
recording settings stay out: SSP describes FMU systems.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cosim.errors import UserError
from cosim.execution import fmu_hosting


@dataclass
class ExportReport:
    """What was written: FMU components, connections, and what was left out."""

    components: int
    connections: int
    left_out: list[str]


def export_ssp(scenario: Any, out: Path, version: str = "1.0") -> ExportReport:
    """Write the FMU part of a validated scenario to `out` as an SSP `version` package.

    Raises:
        UserError: the scenario does not validate, has no FMU component, or an
            FMU-to-FMU connection has a delay (SSP has no delay on connections); `out`
            cannot be written (a folder of that name, a file in its folder's place, no
            permission). Its folder is created if missing.
    """
    from cosim.analysis.outputs import output_file, write_failure
    from cosim.execution.prepare import plan_fmus
    from cosim.execution.validate import validate_scenario
    from cosim.scenario.ssp_write import ExportComponent, ExportSystem, write_ssp

    if version not in ("1.0", "2.0"):
        raise UserError(f"--ssp-version {version!r}: SSP versions are 1.0 and 2.0")
    checked = validate_scenario(scenario)
    plans = {plan.name: plan for plan in plan_fmus(scenario)}
    if not plans:
        raise UserError(f"{scenario.where(('components',))}: the scenario has no FMU component "
                        "to export")
    edges, left_out = _fmu_edges(checked["edges"], plans)
    components = []
    for name, plan in plans.items():
        names = plan.interface.fmu_names
        components.append(ExportComponent(
            name, Path(plan.path),
            inputs=[(names.get(p.name, p.name), p.unit) for p in plan.interface.inputs],
            outputs=[(names.get(p.name, p.name), p.unit) for p in plan.interface.outputs],
            parameters={names.get(k, k): (v, plan.interface.parameters[k].unit)
                        for k, v in plan.parameters.items()},
            period=scenario.components[name].period))
    start = fmu_hosting.start_time(scenario, list(plans.values()))
    system = ExportSystem(scenario.name, version, start, scenario.duration,
                          scenario.tick, components, edges)
    try:
        write_ssp(system, output_file(out))
    except OSError as exc:
        raise write_failure(out, exc) from None
    left_out += [f"component {n}" for n in checked["components"] if n not in plans]
    return ExportReport(len(components), len(edges), left_out)


def _fmu_edges(edges: list[Any], plans: dict[str, Any]) -> tuple[list[tuple], list[str]]:
    """The FMU-to-FMU edges under FMU variable names, and the connections left out."""
    kept, left_out = [], []
    for edge in edges:
        text = f"{edge.src}.{edge.src_port} -> {edge.dst}.{edge.dst_port}"
        if edge.src not in plans or edge.dst not in plans:
            left_out.append(f"connection {text}")
            continue
        if edge.delay:
            raise UserError(f"connection {text} has delay: {edge.delay}, which SSP cannot "
                            "express; remove the delay to export it")
        src_names = plans[edge.src].interface.fmu_names
        dst_names = plans[edge.dst].interface.fmu_names
        kept.append((edge.src, src_names.get(edge.src_port, edge.src_port), edge.dst,
                     dst_names.get(edge.dst_port, edge.dst_port), edge.scale, edge.offset))
    return kept, left_out
