"""Assemble and execute one run of a scenario.

`prepare_run` resolves and checks everything that can be checked before any
component starts (FMUs built and described, parameters checked, Python classes
imported, periods in ticks); `run_scenario` then starts the hosts (FMUs
in-process via fmpy; Python components in-process or as Zenoh processes),
resolves the wiring from the hosted ports, runs the master with the recorder
(plus progress bar, real-time pacer and live publisher) and writes the run
folder: signals.csv, arrays/, manifest.json, metrics.json.
"""

from __future__ import annotations

import contextlib
import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cosim.errors import UserError
from cosim.fmu_component import FmuComponent
from cosim.inproc import InprocComponent, PythonComponentLaunch, import_component_class
from cosim.manifest import base_manifest, finish_manifest
from cosim.master import Master
from cosim.pacing import RealtimePacer
from cosim.progress import ProgressBar
from cosim.recorder import Recorder, write_json

TRANSPORTS = ("inproc", "zenoh")
DEFAULT_DEADLINE_S = 10.0


@dataclass
class FmuPlan:
    """One FMU component, resolved and checked."""

    name: str
    path: Path
    interface: Any
    parameters: dict[str, float]
    period_ticks: int


@dataclass
class PreparedRun:
    """Everything checked before any component starts.

    Attributes:
        fmus: the FMU components in file order.
        launches: the Python components (sources included) in file order.
        names: every component name in declaration order (components, then sources).
    """

    scenario: Any
    fmus: list[FmuPlan]
    launches: list[PythonComponentLaunch]
    names: list[str]
    placement: dict[str, str] = field(default_factory=dict)
    deploy: Any = None


@dataclass
class RunResult:
    """What a run produced (paths, status, timings, metrics)."""

    out_dir: Path
    status: str
    error: str | None
    ticks: int
    sim_time_s: float
    wall_time_s: float
    real_time_factor: float
    metrics: dict[str, float] = field(default_factory=dict)  # "component.metric" -> value
    realtime: dict[str, Any] | None = None

    @property
    def signals(self) -> Path:
        """The run's signals.csv."""
        return self.out_dir / "signals.csv"

    @property
    def manifest(self) -> Path:
        """The run's manifest.json."""
        return self.out_dir / "manifest.json"


def prepare_run(scenario: Any) -> PreparedRun:
    """Resolve FMUs and Python classes and check them, without starting anything.

    Args:
        scenario: a validated `cosim.scenario.Scenario`.
    Raises:
        UserError (FmuInterfaceError, ScenarioError, ...) naming the component.
    """
    _check_hosts(scenario)
    fmus = [_plan_fmu(scenario, name, spec) for name, spec in scenario.fmu_components().items()]
    launches = []
    for name, spec in scenario.python_components().items():
        cls = import_component_class(spec.python, name)
        period = scenario.period_ticks(name, getattr(cls, "default_period", None))
        launches.append(PythonComponentLaunch(name, spec.python, dict(spec.parameters), period))
    names = [*scenario.components, *scenario.sources]
    return PreparedRun(scenario, fmus, launches, names)


def _plan_fmu(scenario: Any, name: str, spec: Any) -> FmuPlan:
    from cosim.fmu_interface import check_parameters, describe_fmu

    where = scenario.resolve_fmu_path(spec)
    if isinstance(where, str):
        from cosim.fmu_build import FmuBuildError, ensure_fmu

        try:
            path = Path(ensure_fmu(where))
        except FmuBuildError as exc:
            raise UserError(f"{scenario.where(('components', name, 'fmu'))}: cannot build "
                            f"the built-in FMU {where!r}: {exc}") from exc
    else:
        path = Path(where)
    origin = scenario.where(("components", name, "variables"))
    interface = describe_fmu(path, dict(spec.variables), origin=origin)
    parameters = scenario.plant_parameters(name, _start_values(interface))
    check_parameters(interface, parameters, name, scenario=scenario)
    return FmuPlan(name, path, interface, parameters, scenario.period_ticks(name))


def _start_values(interface: Any) -> dict[str, float]:
    """Parameter start values of an FMU interface (name -> float)."""
    starts = {}
    for key, value in dict(getattr(interface, "parameters", {}) or {}).items():
        start = getattr(value, "start", value)
        with contextlib.suppress(TypeError, ValueError):
            starts[str(key)] = float(start)
    return starts


def _check_hosts(scenario: Any) -> None:
    from cosim.placement import resolve_placement

    resolve_placement(scenario)  # unknown worker names and FMUs on workers fail here


def run_scenario(scenario: Any, out_dir: str | Path, transport: str = "inproc",
                 realtime: float | None = None, progress: bool = True,
                 deadline_s: float = DEFAULT_DEADLINE_S, place: Sequence[str] = (),
                 deploy: Any = None) -> RunResult:
    """Run a scenario and write its run folder.

    Args:
        scenario: a validated `cosim.scenario.Scenario` (overrides applied).
        out_dir: the run folder (created; files in it are overwritten).
        transport: "inproc" or "zenoh" (Python components as OS processes).
        realtime: pace to wall clock at this factor (1.0 = real time); None: as fast as possible.
        progress: draw a progress bar (on stderr).
        deadline_s: per-tick deadline of remote components (zenoh).
        place: `--place COMPONENT=WORKER` values (override the scenario's `host:`).
        deploy: cosim.deploy.DeploySettings (endpoints, TLS, ACL), or None.
    Returns:
        RunResult; status "failed" with the error message when a component
        failed mid-run (the folder then holds everything up to the last tick).
    Raises:
        UserError for anything wrong before tick 0 (scenario, FMU, wiring).
    """
    if transport not in TRANSPORTS:
        raise UserError(f"unknown transport {transport!r} (choose from {', '.join(TRANSPORTS)})")
    if realtime is not None and not realtime > 0:
        raise UserError(f"--realtime factor must be > 0, got {realtime!r}")
    prepared = prepare_run(scenario)
    from cosim.placement import resolve_placement

    prepared.placement = resolve_placement(scenario, place)
    prepared.deploy = deploy
    if prepared.placement and transport != "zenoh":
        raise UserError("components placed on workers need --transport zenoh: "
                        + ", ".join(f"{c} on {w!r}" for c, w in prepared.placement.items()))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    run_id = uuid.uuid4().hex[:12]
    with contextlib.ExitStack() as stack:
        hosted, publisher = _start_hosts(prepared, transport, run_id, deadline_s, stack)
        return _execute(prepared, hosted, publisher, out, transport, run_id, realtime, progress)


def _start_hosts(prepared: PreparedRun, transport: str, run_id: str, deadline_s: float,
                 stack: contextlib.ExitStack) -> tuple[dict[str, Any], Any]:
    """Host every component; returns (name -> HostedComponent in declaration order, publisher)."""
    hosted: dict[str, Any] = {}
    for plan in prepared.fmus:
        hosted[plan.name] = FmuComponent(plan.name, plan.path, plan.interface,
                                         plan.parameters, plan.period_ticks)
    publisher = None
    if transport == "zenoh":
        try:
            from cosim.zenoh_transport import ZenohComponents
        except ImportError as exc:
            raise UserError(f"the zenoh transport is not available ({exc}); "
                            "use --transport inproc") from exc
        if prepared.placement or prepared.deploy is not None:
            from cosim.worker_client import DistributedComponents

            publisher = stack.enter_context(DistributedComponents(
                prepared.launches, run_id, deadline_s, placement=prepared.placement,
                settings=prepared.deploy))
        else:
            publisher = stack.enter_context(ZenohComponents(prepared.launches, run_id, deadline_s))
        hosted.update(publisher.components)
    else:
        hosted.update({l.name: InprocComponent(l) for l in prepared.launches})
    return {name: hosted[name] for name in prepared.names}, publisher


class _LivePublisher:
    """Master observer publishing the scalar signal vector every tick (zenoh transport)."""

    def __init__(self, transport: Any) -> None:
        self.transport = transport

    def begin(self, master: Master) -> None:
        columns = master.layout.scalar_columns()
        self.names = [n for n, _ in columns]
        self.index = [i for _, i in columns]

    def after_tick(self, tick: int, t: float, values: list[float], arrays: Any) -> None:
        if getattr(self.transport, "live_matching", True):  # nobody listening: no cost
            self.transport.publish(tick, t, self.names,
                                   np.array([values[i] for i in self.index], dtype=np.float64))


def _execute(prepared: PreparedRun, hosted: dict[str, Any], publisher: Any, out: Path,
             transport: str, run_id: str, realtime: float | None, progress: bool) -> RunResult:
    """Run the master over the hosted components and write the run folder."""
    scenario = prepared.scenario
    master, recorder, pacer, bar = _build_master(scenario, hosted, publisher, out,
                                                 realtime, progress)
    manifest = base_manifest(scenario, prepared, hosted, transport, run_id, master.order)
    if publisher is not None:  # where a watcher connects to see the run live
        manifest["live"] = {"run_id": run_id, "endpoint": getattr(publisher, "endpoint", None)}
    manifest["hosts"].update(getattr(publisher, "hosts", {}))
    write_json(out / "manifest.json", manifest)
    failure: BaseException | None = None
    started = time.perf_counter()
    try:
        master.run()
    except BaseException as exc:  # recorded below; bugs are re-raised after the files
        failure = exc
    finally:
        wall = time.perf_counter() - started
        recorder.close()
        if bar is not None:
            bar.close()
        by_component, stop_errors = master.stop_all()
        metrics = {f"{c}.{k}": v for c in master.order if c in by_component
                   for k, v in sorted(by_component[c].items())}
        write_json(out / "metrics.json", metrics)
    errors = ([_failure_text(failure)] if failure is not None else []) + stop_errors
    ticks = max(master.ticks_done, 0)
    result = RunResult(out, "failed" if errors else "ok", "; ".join(errors) or None, ticks,
                       ticks * scenario.tick, wall,
                       (ticks * scenario.tick / wall) if wall > 0 else float("inf"),
                       metrics, pacer.stats() if pacer else None)
    write_json(out / "manifest.json", finish_manifest(manifest, result))
    if failure is not None and not isinstance(failure, (UserError, KeyboardInterrupt)):
        raise failure
    return result


def _build_master(scenario: Any, hosted: dict[str, Any], publisher: Any, out: Path,
                  realtime: float | None, progress: bool) -> tuple[Master, Recorder, Any, Any]:
    """Wire the hosted components and attach the observers."""
    from cosim.wiring import resolve_wiring

    unsupported = {n: c.interface.unsupported for n, c in hosted.items()
                   if isinstance(c, FmuComponent)}
    edges = resolve_wiring(scenario, {n: (c.inputs, c.outputs) for n, c in hosted.items()},
                           unsupported)
    recorder = Recorder(out, scenario.record.include, scenario.record.exclude)
    pacer = RealtimePacer(realtime, scenario.tick) if realtime is not None else None
    bar = ProgressBar(scenario.total_ticks, scenario.tick) if progress else None
    observers: list[Any] = [o for o in (recorder, pacer, bar) if o is not None]
    if publisher is not None:
        observers.append(_LivePublisher(publisher))
    master = Master(hosted, edges, scenario.tick, scenario.total_ticks,
                    scenario.start_time, observers)
    return master, recorder, pacer, bar


def _failure_text(exc: BaseException) -> str:
    if isinstance(exc, UserError):
        return str(exc)
    if isinstance(exc, KeyboardInterrupt):
        return f"interrupted: {exc}" if str(exc) else "interrupted by the user (Ctrl-C)"
    return f"internal error: {type(exc).__name__}: {exc}"


def validate_scenario(scenario: Any) -> dict[str, Any]:
    """Check a scenario as far as possible without running it.

    Resolves and describes the FMUs, checks parameters, constructs the Python
    components in this process to read their ports, resolves the wiring and
    derives the step order (an algebraic loop is an error).

    Args:
        scenario: a validated `cosim.scenario.Scenario`.
    Returns:
        {"components": name -> (inputs, outputs), "edges": [...], "order": [...]}.
    Raises:
        UserError describing the first class of problems found.
    """
    from cosim.inproc import construct_component
    from cosim.schedule import step_order
    from cosim.signals import build_layout
    from cosim.wiring import resolve_wiring

    prepared = prepare_run(scenario)
    ports: dict[str, tuple[Any, Any]] = {}
    feedthrough: dict[str, bool] = {}
    for plan in prepared.fmus:
        ports[plan.name] = (plan.interface.inputs, plan.interface.outputs)
        feedthrough[plan.name] = False
    for launch in prepared.launches:
        comp = construct_component(launch)
        ports[launch.name] = (tuple(comp.inputs), tuple(comp.outputs))
        feedthrough[launch.name] = True
    ports = {name: ports[name] for name in prepared.names}
    edges = resolve_wiring(scenario, ports,
                           {plan.name: plan.interface.unsupported for plan in prepared.fmus})
    build_layout({n: _Ports(*p) for n, p in ports.items()}, edges)
    order = step_order(prepared.names, feedthrough, edges)
    return {"components": ports, "edges": edges, "order": order}


@dataclass
class _Ports:
    inputs: Any
    outputs: Any
