"""Interface completeness before t = 0: what a scenario leaves out, as warnings or (--strict) errors.

Two kinds of gap are reported, one line each, naming the YAML file and component:

- a plant FMU (one with a `variables:` map, or with the contract's `delta`
  input) that does not provide every output of the plant contract
  (docs/plant-contract.md);
- the inputs no connection drives: they hold their start value for the whole
  run (an input that a plant-contract output would feed says so). A plant's
  disturbance inputs held at their neutral value (no wind, mu = 1) are not
  gaps: every scenario without wind or a friction change has them.

`cosim validate` and `cosim run` both call `report_gaps`; with `--strict` the
gaps are one UserError instead of warnings. The FMU outputs that are not
recorded (String, Binary: `unrecorded_outputs`) are a warning line each in
both, `--strict` or not: they are no gap in the interface a run needs.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from cosim.errors import UserError

CONTRACT_OUTPUTS = ("x", "y", "psi", "vx", "vy", "r", "ax", "ay", "phi",
                    "omega_fl", "omega_fr", "omega_rl", "omega_rr")
NEUTRAL_INPUTS = {"wind_fx": 0.0, "wind_fy": 0.0, "mu": 1.0}  # the contract's disturbances


class IncompleteInterface(UserError):
    """`--strict`: a plant-contract output missing or an input left unconnected."""


def interface_gaps(scenario: Any, ports: Mapping[str, tuple[Sequence[Any], Sequence[Any]]],
                   edges: Sequence[Any]) -> list[str]:
    """The completeness gaps of a wired scenario, one message each, in component order.

    Args:
        scenario: the validated Scenario (its FMU specs, file and lines).
        ports: component name -> (inputs, outputs), every component and source.
        edges: the resolved `cosim.engine.wiring.Edge`s.
    """
    from cosim.engine.wiring import unconnected_inputs

    plants = _plants(scenario, ports)
    missing = {}
    for plant in plants:
        have = {port.name for port in ports[plant][1]}
        absent = [name for name in CONTRACT_OUTPUTS if name not in have]
        if absent:
            missing[plant] = absent
    gaps = [f"{_where(scenario, plant)}: plant {plant!r} does not provide the plant-contract "
            f"output{'s' if len(names) > 1 else ''} {', '.join(names)} (docs/plant-contract.md)"
            for plant, names in missing.items()]
    lacking = {name for names in missing.values() for name in names}
    held: dict[str, list[str]] = {}
    for component, port in unconnected_inputs(edges, ports):
        if component in plants and NEUTRAL_INPUTS.get(port.name) == port.default:
            continue
        note = " (no plant provides it)" if port.name in lacking else ""
        held.setdefault(component, []).append(f"{port.name} = {port.default:g}{note}")
    for component, entries in held.items():
        several = len(entries) > 1
        gaps.append(f"{_where(scenario, component)}: input{'s' if several else ''} not "
                    f"connected, held at {'their' if several else 'its'} start "
                    f"value{'s' if several else ''}: {', '.join(entries)}")
    return gaps


def report_gaps(gaps: Sequence[str], strict: bool,
                on_warning: Callable[[str], None] | None) -> None:
    """Raise the gaps as one error (strict), else hand each to `on_warning`.

    Args:
        gaps: from `interface_gaps`.
        strict: `--strict`.
        on_warning: prints one warning line (None: the gaps are dropped).
    Raises:
        IncompleteInterface: strict and there is a gap.
    """
    if strict and gaps:
        raise IncompleteInterface("\n".join(f"{gap} (--strict)" for gap in gaps))
    for gap in gaps if on_warning is not None else ():
        on_warning(gap)


def unrecorded_outputs(scenario: Any, plans: Sequence[Any]) -> list[str]:
    """One warning per FMU component with String or Binary outputs: they are not recorded.

    Args:
        scenario: the validated Scenario (its file and lines).
        plans: the FMU plans (`name`, `interface.not_recorded`).
    """
    lines = []
    for plan in plans:
        skipped = getattr(plan.interface, "not_recorded", None) or {}
        if skipped:
            listed = ", ".join(f"{name} ({kind})" for name, kind in skipped.items())
            lines.append(f"{_where(scenario, plan.name)}: output{'s' if len(skipped) > 1 else ''} "
                         f"not recorded (only numeric signals are): {listed}")
    return lines


def _plants(scenario: Any, ports: Mapping[str, tuple[Sequence[Any], Sequence[Any]]]) -> list[str]:
    """The vehicle plants: FMU components with a name map or the contract's `delta` input."""
    return [name for name, spec in scenario.fmu_components().items() if name in ports
            and (spec.variables or any(p.name == "delta" for p in ports[name][0]))]


def _where(scenario: Any, component: str) -> str:
    """FILE:LINE: components.NAME (or sources.NAME)."""
    section = "sources" if component in scenario.sources else "components"
    return scenario.where((section, component))
