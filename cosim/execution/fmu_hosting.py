"""How a run hosts its local FMUs, and the settings it takes from them.

Each local FMU component is hosted in the master's process (`FmuComponent`,
or `ModelExchangeComponent` for a Model Exchange FMU) or, with `isolate: true`,
in a local process of its own (`IsolatedFmu`, either kind); a second instance
of an FMU that declares canBeInstantiatedOnlyOncePerProcess is isolated
automatically. `log: true` (or `--fmu-log` for all) sends an
FMU's messages to run.log. The start time is the scenario's, else the FMUs'
DefaultExperiment startTime, else 0; every component's call deadline is its
`deadline:`, else the run's `--deadline`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from cosim.errors import UserError

RUN_LOG = "run.log"


def start_time(scenario: Any, plans: list[Any]) -> float:
    """The run's start time: the scenario's, else the FMUs' DefaultExperiment, else 0.

    Args:
        scenario: the validated scenario.
        plans: the FMU plans (`cosim.execution.prepare.FmuPlan`) of every FMU component.
    Raises:
        UserError when the scenario sets none and two FMUs disagree.
    """
    if scenario.start_time is not None:
        return float(scenario.start_time)
    found: dict[str, float] = {}
    for plan in plans:
        experiment = getattr(plan.interface.model_description, "defaultExperiment", None)
        if experiment is not None and experiment.startTime is not None:
            found[plan.name] = float(experiment.startTime)
    if len(set(found.values())) > 1:
        listed = ", ".join(f"{n}: {t:g} s" for n, t in found.items())
        raise UserError(f"{scenario.where(('start_time',))}: the FMUs' DefaultExperiment "
                        f"start times differ ({listed}); set start_time in the scenario")
    return next(iter(found.values()), 0.0)


def deadlines(scenario: Any, names: list[str], default_s: float) -> dict[str, float]:
    """Component -> call deadline in seconds (`deadline:` in the YAML, else `default_s`)."""
    specs = {**scenario.components, **scenario.sources}
    return {n: float(getattr(specs.get(n), "deadline", None) or default_s) for n in names}


def host_fmus(scenario: Any, plans: list[Any], out: Path, deadline_of: dict[str, float],
              fmu_log: bool) -> dict[str, Any]:
    """Host the local FMU components; name -> HostedComponent (isolated ones start now).

    Args:
        scenario: the validated scenario.
        plans: the local FMU plans.
        out: the run folder (for run.log).
        deadline_of: component -> call deadline (see `deadlines`).
        fmu_log: `--fmu-log`: every FMU logs to run.log.
    """
    from cosim.fmu import stepper
    from cosim.fmu.in_process import in_process_host

    if plans:
        stepper.library()  # a first use compiles the stepping shim now, not inside a start's deadline
    hosted: dict[str, Any] = {}
    loaded: set[str] = set()  # model identifiers hosted in this process
    for plan in plans:
        spec = scenario.components[plan.name]
        log_file = out / RUN_LOG if (spec.log or fmu_log) else None
        solver = getattr(plan, "solver", None)  # a Model Exchange FMU: we integrate it
        if spec.isolate or _only_once(plan) and _identifier(plan) in loaded:
            from cosim.fmu.isolated import IsolatedFmu

            hosted[plan.name] = IsolatedFmu(plan.name, plan.path, plan.interface,
                                            dict(spec.variables), plan.parameters,
                                            plan.period_ticks, deadline_of[plan.name], log_file,
                                            solver, getattr(spec, "interface", None))
            continue
        loaded.add(_identifier(plan))
        hosted[plan.name] = in_process_host(plan.name, plan.path, plan.interface,
                                            plan.parameters, plan.period_ticks, log_file, solver)
    return hosted


def wait_ready(hosted: dict[str, Any]) -> None:
    """Wait for the isolated FMUs' processes to be ready, outside any call deadline
    (their start-up, under load, can take longer than an FMI call may)."""
    from cosim.fmu.isolated import IsolatedFmu

    isolated = [c for c in hosted.values() if isinstance(c, IsolatedFmu)]
    try:
        for component in isolated:
            component.wait_ready()
    except BaseException:
        for component in isolated:
            component.stop()
        raise


def _identifier(plan: Any) -> str:
    return str(getattr(plan.interface, "model_identifier", None) or plan.path.stem)


def _only_once(plan: Any) -> bool:
    """Whether the FMU declares canBeInstantiatedOnlyOncePerProcess (for the interface used)."""
    md = plan.interface.model_description
    me = getattr(plan, "solver", None) is not None
    description = getattr(md, "modelExchange" if me else "coSimulation", None)
    return bool(getattr(description, "canBeInstantiatedOnlyOncePerProcess", False))


def is_local_call(hosted: Any) -> bool:
    """Whether a hosted component's calls run in the master's process (the supervisor's watch)."""
    from cosim.fmu.instance import FmuInstance
    from cosim.transport.inproc import InprocComponent

    return isinstance(hosted, (FmuInstance, InprocComponent))
