"""Everything checked before any component of a run starts.

`prepare_run` resolves and checks the scenario's components without starting
anything: FMUs built (the built-in ones) and described, their parameters
checked, Python classes imported, periods in ticks, placement resolved.
`cosim.execution.run` starts and executes what this prepares, and
`cosim.execution.validate` stops after it.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim.errors import UserError
from cosim.scenario.imports import add_import_roots, import_roots
from cosim.execution.limits import RunLimits
from cosim.transport.launch import PythonComponentLaunch


@dataclass
class FmuPlan:
    """One FMU component, resolved and checked."""

    name: str
    path: Path
    interface: Any
    parameters: dict[str, float]
    period_ticks: int
    solver: dict[str, Any] | None = None  # Model Exchange: the resolved `solver:` settings


@dataclass
class PreparedRun:
    """Everything checked before any component starts.

    Attributes:
        fmus: the FMU components in file order.
        launches: the Python components (sources included) in file order.
        names: every component name in declaration order (components, then sources).
        limits: how large the run may be (ticks, CSV size).
    """

    scenario: Any
    fmus: list[FmuPlan]
    launches: list[PythonComponentLaunch]
    names: list[str]
    placement: dict[str, str] = field(default_factory=dict)
    deploy: Any = None
    limits: RunLimits = field(default_factory=RunLimits)


def prepare_run(scenario: Any) -> PreparedRun:
    """Resolve FMUs and Python classes and check them, without starting anything.

    Args:
        scenario: a validated `cosim.scenario.loader.Scenario`.
    Raises:
        UserError (FmuInterfaceError, ScenarioError, ...) naming the component.
    """
    _check_hosts(scenario)
    fmus = plan_fmus(scenario)
    return PreparedRun(scenario, fmus, plan_launches(scenario), component_names(scenario))


def plan_launches(scenario: Any, import_classes: bool = True) -> list[PythonComponentLaunch]:
    """The Python components (sources included) to launch, in file order.

    Args:
        scenario: a validated `cosim.scenario.loader.Scenario`.
        import_classes: import every class here (checks it early). When False,
            only the classes whose period the scenario leaves to the class's
            `default_period` are imported; a component process then reports a
            missing or bad class in its handshake, with the same message.
    Raises:
        UserError naming the component (class, period).

    The scenario's folder and the working directory go in front of the import
    path here, and into each launch for the processes (`cosim.scenario.imports`).
    """
    roots = import_roots(scenario.source_file)
    add_import_roots(roots)  # for the classes imported here and by the in-process host
    launches = []
    for name, spec in scenario.python_components().items():
        default = None
        # sources are the platform's own classes, which declare no default period
        if import_classes or (spec.period is None and name not in scenario.sources):
            cls = _import_class(scenario, name, spec.python)
            default = getattr(cls, "default_period", None)
        period = scenario.period_ticks(name, default)
        parameters = with_data_files(dict(spec.parameters), scenario.base_dir)
        launches.append(PythonComponentLaunch(name, spec.python, parameters, period, roots,
                                              steps=scenario.total_ticks // period))
    return launches


DATA_FILE_KEYS = ("opendrive",)  # parameter keys, at any depth, whose value is a data file


def with_data_files(parameters: Any, base_dir: Path) -> Any:
    """The parameters with each relative data-file path resolved against the scenario's folder.

    A component runs in another process (or on another host) whose working
    folder is not the scenario's: paths such as a planner road's `opendrive:
    track.xodr` must reach it absolute, like FMU paths.
    """
    if isinstance(parameters, dict):
        return {k: (str(base_dir / v) if k in DATA_FILE_KEYS and isinstance(v, str)
                    and not Path(v).is_absolute() else with_data_files(v, base_dir))
                for k, v in parameters.items()}
    if isinstance(parameters, list):
        return [with_data_files(v, base_dir) for v in parameters]
    return parameters


def _import_class(scenario: Any, name: str, class_path: str) -> type:
    """A component's class; a class that cannot be imported is named at its `python:` line."""
    from cosim.transport.inproc import import_component_class

    try:
        return import_component_class(class_path, name)
    except UserError as exc:
        section = "sources" if name in scenario.sources else "components"
        raise UserError(f"{scenario.where((section, name, 'python'))}: {exc}") from None


def plan_fmus(scenario: Any) -> list[FmuPlan]:
    """The FMU components, built if needed, described and parameter-checked.

    Args:
        scenario: a validated `cosim.scenario.loader.Scenario`.
    """
    return [plan_fmu(scenario, name, spec) for name, spec in scenario.fmu_components().items()]


def component_names(scenario: Any) -> list[str]:
    """Every component name in declaration order (components, then sources)."""
    return [*scenario.components, *scenario.sources]


def plan_fmu(scenario: Any, name: str, spec: Any) -> FmuPlan:
    from cosim.errors import FmuInterfaceError
    from cosim.fmu.interface import check_parameters, describe_fmu

    where = scenario.resolve_fmu_path(spec)
    if isinstance(where, str):
        from cosim.fmu.build import FmuBuildError
        from cosim.fmu.cache import builtin_fmu

        try:
            path = Path(builtin_fmu(where))
        except FmuBuildError as exc:
            raise UserError(f"{scenario.where(('components', name, 'fmu'))}: cannot build "
                            f"the built-in FMU {where!r}: {exc}") from exc
    else:
        path = Path(where)
    origin = scenario.where(("components", name, "variables"))
    try:
        interface = describe_fmu(path, dict(spec.variables), origin=origin, kind=spec.interface)
    except FmuInterfaceError as exc:
        raise _located(exc, scenario.where(("components", name, "fmu")), path) from None
    path = _checked_archive(scenario, name, spec, path, interface)
    parameters = scenario.plant_parameters(name, _start_values(interface))
    check_parameters(interface, parameters, name, scenario=scenario)
    return FmuPlan(name, path, interface, parameters, scenario.period_ticks(name),
                   _solver_settings(scenario, name, spec, interface))


def _located(exc: Exception, where: str, path: Path) -> Exception:
    """An FMU's own error (archive, modelDescription.xml: it starts with the FMU's path)
    on one line after the scenario field that names the FMU; other errors as they are."""
    text = str(exc)
    if not text.startswith(str(path)):
        return exc
    first, *details = text.splitlines()
    details = [line.strip().removeprefix("- ") for line in details if line.strip()]
    return type(exc)(f"{where}: {first}" + (" " + "; ".join(details) if details else ""))


def _checked_archive(scenario: Any, name: str, spec: Any, path: Path, interface: Any) -> Path:
    """The archive checks (cosim.fmu.archive) and the variables no host can run; the path to load."""
    from cosim.fmu.archive import check_archive
    from cosim.errors import FmuInterfaceError

    where = scenario.where(("components", name, "fmu"))
    if interface.fmi_type == "ModelExchange" and spec.host != "local":
        raise FmuInterfaceError(f"{scenario.where(('components', name, 'host'))}: a Model "
                                "Exchange FMU runs in the master's process, not on a worker")
    try:
        return check_archive(path, interface, local=spec.host == "local")
    except FmuInterfaceError as exc:
        raise FmuInterfaceError(f"{where}: {exc}") from None


def _solver_settings(scenario: Any, name: str, spec: Any, interface: Any) -> dict[str, Any] | None:
    """Resolved `solver:` of a Model Exchange FMU (defaults as fmpy's); None for co-simulation."""
    if interface.fmi_type != "ModelExchange":
        if spec.solver is not None:
            raise UserError(f"{scenario.where(('components', name, 'solver'))}: solver: applies "
                            "to Model Exchange only, and this FMU runs as co-simulation "
                            "(set interface: model_exchange to integrate it here)")
        return None
    from cosim.scenario.models import SolverSpec

    settings = (spec.solver or SolverSpec()).model_dump()
    if settings["max_step"] is None:
        settings["max_step"] = (scenario.duration / 50 if settings["method"] == "cvode"
                                else scenario.period_ticks(name) * scenario.tick)
    return settings


def _start_values(interface: Any) -> dict[str, float]:
    """Parameter start values of an FMU interface (name -> float)."""
    starts = {}
    for key, value in dict(getattr(interface, "parameters", {}) or {}).items():
        start = getattr(value, "start", value)
        with contextlib.suppress(TypeError, ValueError):
            starts[str(key)] = float(start)
    return starts


def _check_hosts(scenario: Any) -> None:
    from cosim.distributed.placement import resolve_placement

    resolve_placement(scenario)  # unknown worker names and FMUs on workers fail here
