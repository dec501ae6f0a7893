"""Execute one run of a scenario.

`cosim.execution.prepare` resolves and checks everything that can be checked
before any component starts; `run_scenario` starts the hosts (FMUs in-process
via fmpy; Python components in-process or as Zenoh processes), resolves the
wiring from the hosted ports, runs the master with the recorder (plus progress
bar, real-time pacer and live publisher) and writes the run folder:
signals.csv, arrays/, manifest.json (with the start-up marks and
`time_to_tick0_s`), metrics.json.

This module loads numpy, fmpy and the component classes only where they are
needed, after the Zenoh component processes have been spawned: their start-up
then overlaps the master's (see `run_scenario`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import operator
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cosim.errors import UserError
from cosim.execution import fmu_hosting, out_folder, supervisor
from cosim.transport.launch import STARTUP_TIMEOUT_S, PythonComponentLaunch
from cosim.execution.abort import (locate_parameter_problem, start_failure_text,
                                   write_pending_manifest, write_start_failure)
from cosim.execution.limits import RunLimits, check_formats, check_recorded_size, check_ticks
from cosim.execution.prepare import PreparedRun, component_names, plan_fmu, plan_fmus, plan_launches
from cosim.engine import one_cpu
from cosim.engine.startup import StartupClock

if TYPE_CHECKING:  # loaded when needed: the Zenoh processes start before numpy/fmpy load
    from cosim.engine.master import Master
    from cosim.results.recorder import Recorder

TRANSPORTS = ("inproc", "zenoh")
DEFAULT_DEADLINE_S = 10.0
MIN_REALTIME = 1e-3  # slower pacing looks like a hang: one tick of 10 ms would take 10 s
RUN_FOLDER_MODE = 0o700  # a run folder is its owner's: `chmod` it to share it


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
    time_to_tick0_s: float | None = None  # from the clock's origin; None: tick 0 not reached
    startup: dict[str, Any] = field(default_factory=dict)  # StartupClock marks and origin
    live: dict[str, Any] | None = None  # {"run_id", "endpoint"} of the live view (zenoh)
    stopped_by: dict[str, Any] | None = None  # {"component", "tick", "time", "reason"}
    # (columns, every tick's row) of the recorded scalars, for the metrics; None without a record
    full_signals: tuple[list[str], Any] | None = None
    # wall time of ticks 1..N alone (wall_time_s also counts tick 0, the initialization
    # phase); None when tick 0 was not completed
    loop_time_s: float | None = None
    lockstep_cpu: int | None = None  # the CPU the chain ran on from tick 0 (None: the OS placed it)

    @property
    def signals(self) -> Path:
        """The run's signals.csv."""
        return self.out_dir / "signals.csv"

    @property
    def manifest(self) -> Path:
        """The run's manifest.json."""
        return self.out_dir / "manifest.json"


def run_scenario(scenario: Any, out_dir: str | Path, transport: str = "inproc",
                 realtime: float | None = None, progress: bool = True,
                 deadline_s: float = DEFAULT_DEADLINE_S, place: Sequence[str] = (),
                 deploy: Any = None, clock: StartupClock | None = None,
                 on_live: Callable[[str, str], None] | None = None,
                 prestart: Any = None,
                 on_folder: Callable[[Path], None] | None = None,
                 observers: Sequence[Any] = (),
                 limits: RunLimits | None = None,
                 fmu_log: bool = False, strict: bool = False,
                 on_warning: Callable[[str], None] | None = None,
                 before_tick0: Callable[[], None] | None = None,
                 at_tick0: Callable[[], None] | None = None,
                 lockstep_cpu: str | int = "auto", runs_in_process: int | None = None,
                 startup_timeout_s: float = STARTUP_TIMEOUT_S, replace: bool = False) -> RunResult:
    """Run a scenario and write its run folder.

    Start-up is ordered so that tick 0 comes early: the component processes
    (zenoh) are spawned first, the FMUs are built, described and loaded while
    they start, and only then does the master wait for their handshakes.

    Args:
        scenario: a validated `cosim.scenario.loader.Scenario` (overrides applied).
        out_dir: the run folder (created; files in it are overwritten).
        transport: "inproc" or "zenoh" (Python components as OS processes).
        realtime: pace to wall clock at this factor (1.0 = real time); None: as fast as possible.
        progress: draw a progress bar (on stderr).
        deadline_s: the deadline of a component call (remote exchange, FMI call,
            in-process step), unless the component sets its own `deadline:`.
        place: `--place COMPONENT=WORKER` values (override the scenario's `host:`).
        deploy: cosim.distributed.deploy.DeploySettings (endpoints, TLS, ACL), or None.
        clock: start-up clock whose marks go into the manifest (`cosim run`
            passes one that starts with the process); None: starts now.
        on_live: called with (run_id, endpoint) as soon as the run can be
            watched live (zenoh transport only), before tick 0.
        prestart: a `cosim.execution.prestart.Prestart` (component processes started
            while the scenario loaded): used for a local zenoh run, ended
            otherwise; always closed before returning.
        on_folder: called with the run folder (as given) once it is created (after the
            checks that need no component running); from then on a run that
            fails before tick 0 leaves a manifest.json with status "failed".
        observers: more master observers (e.g. cosim.foxglove.live.FoxgloveLive),
            after the recorder; they must only read the signal store.
        limits: how large the run may be (cosim.execution.limits; default: the defaults).
        fmu_log: every FMU's log messages go to run.log (`--fmu-log`).
        strict: interface gaps (`cosim.execution.completeness`) are errors.
        on_warning: prints one interface-gap warning (once each, before tick 0).
        before_tick0: called once everything is hosted, just before the master starts
            (`cosim run` raises there a Ctrl-C that a library swallowed during start-up).
        at_tick0: called once tick 0 is done, in the loop's thread, pinned when the chain
            is (`cosim run` starts its figure's process there: a process started there is
            given the other CPUs with `cosim.engine.one_cpu.release`).
        lockstep_cpu: "auto", "off" or a CPU number: from tick 0, the one CPU of the master
            and of the processes it started, when there are any (`cosim.engine.one_cpu`);
            the manifest's `lockstep_cpu` says which CPU, null for none.
        runs_in_process: how many runs this process hosts, this one included (`cosim
            run`: 1; a sweep's own cluster: its samples, an upper bound of the count):
            its in-process components are told this run's steps times that
            (`cosim.component.expected_steps`), as component processes (one run each) are
            told theirs; an estimate when the runs differ in length (a sweep that varies
            the duration or a period); None (a Python session, a cluster that outlives
            the sweep): unknown, not told. At least 1.
        replace: an earlier run's folder at `out_dir` is emptied before the run writes
            (`check_out_folder` with force); False: the run's files replace those of the
            same name.
        startup_timeout_s: the longest a component may take to start: a component
            process's start and handshake, or the constructor of a component in this
            process (a supervised run's supervisor ends the master past it).
    Returns:
        RunResult; status "failed" with the error message when a component
        failed mid-run (the folder then holds everything up to the last tick).
    Raises:
        UserError for anything wrong before tick 0 (scenario, FMU, wiring).
    """
    check_run_options(transport, realtime, deadline_s, startup_timeout_s)
    runs_in_process = _count_of_runs(runs_in_process)
    one_cpu.check_setting(lockstep_cpu, "lockstep_cpu")
    limits = limits or RunLimits()
    check_ticks(scenario, limits)  # before the run folder: a refused run leaves nothing
    check_formats(scenario)
    clock = clock or StartupClock.from_now()
    with contextlib.ExitStack() as stack:
        if prestart is not None:
            stack.callback(prestart.close)
        placement = _placement(scenario, place, transport)
        in_master = _in_master_process(scenario, place, transport)
        prestart = _usable_prestart(prestart, transport, placement, deploy)  # prestart skips `inproc` ones
        launches = plan_launches(scenario, import_classes=transport != "zenoh")
        launches += _placed_fmu_launches(scenario, placement)
        remote_launches = [launch for launch in launches if launch.name not in in_master]
        chain = stack.enter_context(one_cpu.PinnedChain(lockstep_cpu))  # pinned before tick 0
        out = _make_run_folder(Path(out_dir), replace)
        run_id = prestart.run_id if prestart is not None else uuid.uuid4().hex[:12]
        page = supervisor.current()
        try:
            if page is not None:
                page.announce(out)
                _temporary_folder_of_the_run(page, stack)
            if on_folder is not None:
                on_folder(Path(out_dir))  # as the user gave it; the run uses it absolute
            remote = None
            if transport == "zenoh" and remote_launches:  # spawned before the FMUs load: start-ups overlap
                remote = _spawn_remote(remote_launches, run_id, (deadline_s, startup_timeout_s),
                                       placement, deploy, stack, prestart, clock, on_live)
            all_fmus = plan_fmus(scenario)
            local_fmus = [p for p in all_fmus if p.name not in placement]
            prepared = PreparedRun(scenario, local_fmus, launches, component_names(scenario),
                                   placement, deploy, limits)
            options = _Options(fmu_hosting.start_time(scenario, all_fmus),
                               fmu_hosting.deadlines(scenario, prepared.names, deadline_s),
                               fmu_log, page, tuple(observers), chain, runs_in_process, at_tick0,
                               startup_timeout_s, (run_id, transport))
            hosted = _host_components(prepared, remote, in_master, clock, out, options)
            _check_gaps(scenario, hosted, all_fmus, strict, on_warning)
            if before_tick0 is not None:
                before_tick0()
            return _execute(prepared, hosted, remote, out, transport, run_id, realtime,
                            progress, clock, options)
        except BaseException as exc:  # the announced folder says why the run never started
            located = locate_parameter_problem(scenario, exc)
            write_start_failure(out, scenario, run_id, transport,
                                start_failure_text(located or exc), clock.as_dict())
            if page is not None:
                page.done()
            if located is not None:
                raise located from None
            raise


@dataclass
class _Options:
    """What the run settled before hosting: start time, deadlines, FMU logging, supervision."""

    t0: float
    deadlines: dict[str, float]  # component -> call deadline, s
    fmu_log: bool
    page: Any  # cosim.execution.supervisor.ControlPage, or None (not supervised)
    observers: tuple[Any, ...] = ()  # more master observers, after the recorder
    chain: Any = None  # cosim.engine.one_cpu.PinnedChain: the CPU of the lockstep chain
    runs_in_process: int | None = None  # most runs this process hosts (see run_scenario)
    at_tick0: Callable[[], None] | None = None  # see run_scenario
    startup_timeout_s: float = STARTUP_TIMEOUT_S  # the deadline of a constructor here
    identity: tuple[str, str] = ("", "inproc")  # (run id, transport), for a manifest before hosting


def check_out_folder(out: str | Path, force: bool = False, option: str = "--out") -> Path:
    """The run folder a run may write: not an empty name, and not an existing non-empty
    folder unless `force`, and then only an earlier run folder (one with a manifest.json),
    which the run replaces whole (`run_scenario(replace=True)`); the folder of a run that
    failed before tick 0 (`never_started`) is replaced without `force`.

    Args:
        out: the folder asked for.
        force: replace an earlier run folder there.
        option: how the user named it, for the message ("--out", "out").
    Raises:
        UserError for an empty name, an occupied folder without `force`, or with it a
        folder that is not a run folder (`--out / --force` must not empty /).
    """
    folder, in_use = out_folder.occupied(out, option)
    if in_use and not force and not never_started(folder):
        raise UserError(f"{option} {out}: the folder exists and is not empty (another run?); "
                        f"choose another folder, or replace that run with "
                        f"{'--force' if option.startswith('--') else 'force=True'}")
    if in_use and not (folder / "manifest.json").is_file():
        raise UserError(f"{option} {out}: the folder is not empty and is not a run folder (no "
                        f"manifest.json); --force replaces only an earlier run's folder")
    return folder


def _temporary_folder_of_the_run(page: Any, stack: contextlib.ExitStack) -> None:
    """Under a supervisor, the temporary files this process makes during the run (the FMUs'
    extractions, the Zenoh credentials' folder) go into one folder noted on the
    supervisor's page, which removes it if the master dies (in an FMU, most likely) and
    they would be left behind; `stack` removes it at the run's end."""
    import shutil
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix=supervisor.SCRATCH_PREFIX))
    stack.callback(shutil.rmtree, folder, ignore_errors=True)
    if page.note_scratch(folder):
        previous, tempfile.tempdir = tempfile.tempdir, str(folder)
        stack.callback(setattr, tempfile, "tempdir", previous)


def never_started(folder: Path) -> bool:
    """Whether `folder` holds only what a run that failed before tick 0 left (its manifest,
    ticks 0, and its live credential or run.log): nothing a new run there would lose, so
    the command run again after a fixed mistake needs no --force."""
    import json

    leftovers = {"manifest.json", "live.credential", "run.log"}
    try:
        names = {entry.name for entry in folder.iterdir()}
        manifest = json.loads((folder / "manifest.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return (names <= leftovers and isinstance(manifest, dict)
            and manifest.get("status") == "failed" and manifest.get("ticks") == 0)


def _make_run_folder(out: Path, replace: bool) -> Path:
    """Create the run folder, absolute (an FMU may change the working directory) and
    private (0700: other local users cannot read the run's signals, whatever the umask
    gives its files); with `replace`, an earlier run's folder there is emptied first
    (see check_out_folder). One that cannot be made (a file there, no permission) is a
    UserError."""
    out = out.absolute()
    try:
        if out.is_dir() and any(out.iterdir()) and (replace or never_started(out)):
            check_out_folder(out, force=True)
            out_folder.empty_folder(out)
        out.mkdir(mode=RUN_FOLDER_MODE, parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create the run folder {str(out)!r}: "
                        f"{exc.strerror or exc}") from None
    with contextlib.suppress(OSError):  # a folder that was there (not ours, read-only: as it is)
        out.chmod(RUN_FOLDER_MODE)
    return out


def _count_of_runs(runs: Any) -> int | None:
    """`runs_in_process` as an int (a numpy integer too), None kept; UserError for anything
    but a whole number from 1 up (a bool is not a count)."""
    if runs is None:
        return None
    try:
        count = operator.index(runs) if not isinstance(runs, bool) else 0
    except TypeError:
        count = 0
    if count < 1:
        raise UserError(f"runs_in_process must be a whole number from 1 up, or None; got {runs!r}")
    return count


def check_run_options(transport: str, realtime: float | None,
                      deadline_s: float = DEFAULT_DEADLINE_S,
                      startup_timeout_s: float = STARTUP_TIMEOUT_S) -> None:
    """Reject an unknown transport, a non-positive real-time factor, deadline or start-up
    timeout (UserError).

    Args:
        transport: the `--transport` value.
        realtime: the `--realtime` factor, or None.
        deadline_s: the `--deadline`, s.
        startup_timeout_s: the `--startup-timeout`, s.
    """
    if transport not in TRANSPORTS:
        raise UserError(f"unknown transport {transport!r} "
                        f"(--transport: choose from {', '.join(TRANSPORTS)})")
    if realtime is not None and not MIN_REALTIME <= realtime < float("inf"):
        raise UserError(f"--realtime factor must be a number from {MIN_REALTIME:g} "
                        f"(1000 times slower than real time) up, got {realtime!r}")
    for option, seconds in (("--deadline", deadline_s), ("--startup-timeout", startup_timeout_s)):
        if not 0.0 < seconds < float("inf"):
            raise UserError(f"{option} must be a positive number of seconds, got {seconds!r}")


def _placement(scenario: Any, place: Sequence[str], transport: str) -> dict[str, str]:
    """Component -> worker from `host:` and `--place`; placing anything needs zenoh."""
    from cosim.distributed.placement import resolve_placement

    placement = resolve_placement(scenario, place)
    if placement and transport != "zenoh":
        raise UserError("components placed on workers need --transport zenoh: "
                        + ", ".join(f"{c} on {w!r}" for c, w in placement.items()))
    return placement


def _in_master_process(scenario: Any, place: Sequence[str], transport: str) -> set[str]:
    """The Python components placed `inproc` over Zenoh (none with --transport inproc, where every
    Python component is in this process anyway)."""
    from cosim.distributed.placement import in_master_process

    return in_master_process(scenario, place) if transport == "zenoh" else set()


def _usable_prestart(prestart: Any, transport: str, placement: dict[str, str],
                     deploy: Any) -> Any:
    """The prestarted processes if this run can use them (a local zenoh run), else None.

    Prestarted processes that this run cannot use are ended at once, to free the CPU.
    """
    if prestart is not None and (transport != "zenoh" or placement or deploy is not None):
        prestart.close()
        return None
    return prestart


def _placed_fmu_launches(scenario: Any, placement: dict[str, str]) -> list[PythonComponentLaunch]:
    """FMU components placed on workers, as launches of the remote FMU host."""
    specs = scenario.fmu_components()
    if not set(specs) & set(placement):
        return []  # and no import: numpy must not load before the processes are spawned
    from cosim.fmu.remote import fmu_launch

    plans = [plan_fmu(scenario, name, spec) for name, spec in specs.items() if name in placement]
    if any(p.solver is not None for p in plans):
        raise UserError("a Model Exchange FMU runs in the master's process, not on a worker: "
                        + ", ".join(p.name for p in plans if p.solver is not None))
    return [fmu_launch(p.name, p.path, dict(specs[p.name].variables), p.parameters,
                       p.period_ticks) for p in plans]


def _spawn_remote(launches: list[PythonComponentLaunch], run_id: str,
                  timeouts: tuple[float, float], placement: dict[str, str], deploy: Any,
                  stack: contextlib.ExitStack, prestart: Any, clock: StartupClock,
                  on_live: Callable[[str, str], None] | None) -> Any:
    """Start the component processes (without waiting for them); closed with `stack`.

    `timeouts`: (call deadline, start-up timeout), s. Marks "spawned" on `clock`, then
    tells `on_live` where the run can be watched.
    """
    deadline_s, startup_s = timeouts
    try:
        from cosim.transport.zenoh import ZenohComponents
    except ImportError as exc:
        raise UserError(f"the zenoh transport is not available ({exc}); "
                        "use --transport inproc") from exc
    if placement or deploy is not None:
        from cosim.distributed.client import DistributedComponents

        remote = DistributedComponents(launches, run_id, deadline_s, placement=placement,
                                       settings=deploy, startup_timeout_s=startup_s)
    elif prestart is not None:
        remote = ZenohComponents(launches, run_id, deadline_s, prestart.endpoint,
                                 prestarted=prestart.children, credential=prestart.credential,
                                 startup_timeout_s=startup_s)
    else:
        remote = ZenohComponents(launches, run_id, deadline_s, startup_timeout_s=startup_s)
    stack.callback(remote.close)
    remote.spawn()
    clock.mark("spawned")
    if on_live is not None:
        on_live(run_id, remote.endpoint)
    return remote


def _write_live_credential(out: Path, remote: Any) -> None:
    """The run's credential, for `cosim watch FOLDER`: owner-only, before the manifest."""
    credential = getattr(remote, "live_credential", None)
    if credential is not None:
        from cosim.transport.zenoh.auth import LIVE_CREDENTIAL_FILE, write_credential_file

        path = out / LIVE_CREDENTIAL_FILE
        path.unlink(missing_ok=True)
        write_credential_file(path, credential)


def _host_components(prepared: PreparedRun, remote: Any, in_master: set[str], clock: StartupClock,
                     out: Path, options: _Options) -> dict[str, Any]:
    """Host every component; name -> HostedComponent in declaration order.

    Python components run in this process without `remote` (--transport inproc), else those
    of `in_master` (placed `inproc`), constructed while the component processes start.
    """
    hosted = fmu_hosting.host_fmus(prepared.scenario, prepared.fmus, out, options.deadlines,
                                   options.fmu_log)
    clock.mark("fmus_ready")
    here = [launch for launch in prepared.launches if remote is None or launch.name in in_master]
    if here:
        runs = options.runs_in_process  # None: this process may run again, the run's steps say little
        here = [dataclasses.replace(launch, steps=None if runs is None or launch.steps is None
                                    else launch.steps * runs) for launch in here]
        hosted.update(_construct_here(here, prepared.scenario, clock, out, options))
    if remote is not None:
        _preload()
        hosted.update(remote.wait_ready())
    fmu_hosting.wait_ready(hosted)
    clock.mark("components_ready")
    return {name: hosted[name] for name in prepared.names}


def _construct_here(launches: list[PythonComponentLaunch], scenario: Any, clock: StartupClock,
                    out: Path, options: _Options) -> dict[str, Any]:
    """Construct the Python components hosted in this process; name -> InprocComponent.

    Supervised, each constructor is a call with the start-up timeout as its deadline,
    and a manifest (status "running") is written first, which the supervisor completes
    if a constructor kills or hangs this process.
    """
    from cosim.transport.inproc import InprocComponent

    page = options.page
    if page is not None:
        write_pending_manifest(out, scenario, *options.identity, clock.as_dict())
    built = {}
    for index, launch in enumerate(launches):
        watched = (page.constructing(index, launch.name, options.startup_timeout_s)
                   if page is not None else contextlib.nullcontext())
        try:
            with watched:
                built[launch.name] = InprocComponent(launch)
        except KeyboardInterrupt:  # the run's error says where the Ctrl-C came
            raise KeyboardInterrupt(f"in the constructor of component {launch.name!r}") from None
    return built


def _check_gaps(scenario: Any, hosted: dict[str, Any], plans: list[Any], strict: bool,
                on_warning: Callable[[str], None] | None) -> None:
    """Interface gaps of the hosted components: warnings, or one error with `strict`;
    then the FMU outputs (of every plan) that are not recorded, as warnings."""
    from cosim.engine.wiring import resolve_wiring
    from cosim.execution.completeness import interface_gaps, report_gaps, unrecorded_outputs

    ports = {n: (c.inputs, c.outputs) for n, c in hosted.items()}
    edges = resolve_wiring(scenario, ports, _unsupported(hosted))
    report_gaps(interface_gaps(scenario, ports, edges), strict, on_warning)
    for line in unrecorded_outputs(scenario, plans) if on_warning is not None else ():
        on_warning(line)


def _unsupported(hosted: dict[str, Any]) -> dict[str, Any]:
    """FMU component -> its variables that cannot be connected."""
    return {n: c.interface.unsupported for n, c in hosted.items()
            if hasattr(getattr(c, "interface", None), "unsupported")}


def _preload() -> None:
    """Load what the run needs after the handshake, while the processes still start."""
    import cosim.engine.master  # noqa: F401
    import cosim.results.recorder  # noqa: F401
    import cosim.engine.wiring  # noqa: F401
    from cosim.results.manifest import package_versions

    package_versions()


class _LivePublisher:
    """Master observer publishing the scalar signal vector of every tick (zenoh
    transport), building the vector only while a watcher listens."""

    def __init__(self, live: Any) -> None:
        self.live = live  # cosim.transport.zenoh.live.LivePublisher

    def begin(self, master: Master) -> None:
        import numpy as np

        columns = master.layout.scalar_columns()
        self.names = [n for n, _ in columns]
        self.index = [i for _, i in columns]
        self.vector = lambda values: np.array([values[i] for i in self.index], dtype=np.float64)

    def after_tick(self, tick: int, t: float, values: list[float], arrays: Any) -> None:
        if self.live.matching:  # a plain attribute: nobody listening costs one test
            self.live.publish(tick, t, self.names, self.vector(values))


def _execute(prepared: PreparedRun, hosted: dict[str, Any], remote: Any, out: Path,
             transport: str, run_id: str, realtime: float | None, progress: bool,
             clock: StartupClock, options: _Options) -> RunResult:
    """Run the master over the hosted components and write the run folder."""
    from cosim.results.manifest import base_manifest, finish_manifest
    from cosim.results.recorder import write_json, write_json_in_place

    scenario = prepared.scenario
    master, recorder, pacer, bar = _build_master(scenario, hosted, remote, out,
                                                 realtime, progress, options)
    check_recorded_size(scenario, master.layout,
                        {n: c.period_ticks for n, c in hosted.items()}, prepared.limits)
    manifest = base_manifest(scenario, prepared, hosted, transport, run_id, master.order)
    manifest["start_time"] = master.t0
    # everything has started (on every CPU): from tick 0 on, a chain of several processes
    # on this machine shares one CPU (a chain of this process alone gains nothing)
    chain_processes = _local_processes(hosted, remote)
    manifest["lockstep_cpu"] = (options.chain.pin(chain_processes)
                                if chain_processes and options.chain else None)
    local = {n for n, c in hosted.items() if fmu_hosting.is_local_call(c)}
    manifest["supervision"] = supervisor.supervision_entry(master.order, local, options.deadlines)
    live = None
    if remote is not None:  # where a watcher connects to see the run live
        live = {"run_id": run_id, "endpoint": remote.endpoint}
        manifest["live"] = live
        _write_live_credential(out, remote)
        manifest["startup_processes_s"] = dict(getattr(remote, "process_startup_s", {}))
    manifest["hosts"].update(getattr(remote, "hosts", {}))
    manifest["startup"] = clock.as_dict()
    write_json(out / "manifest.json", manifest)
    failure: BaseException | None = None
    started = time.perf_counter()
    loop_started: list[float] = []  # when tick 0 was complete

    def tick0_done() -> None:
        clock.mark("tick0")
        loop_started.append(time.perf_counter())
        if options.at_tick0 is not None:  # counted in the loop's time
            options.at_tick0()

    try:
        master.run(after_initialize=tick0_done)
    except BaseException as exc:  # recorded below; bugs are re-raised after the files
        failure = exc
    finally:
        ended = time.perf_counter()
        wall = ended - started
        try:
            recorder.close()
        except UserError as exc:  # the run folder cannot be written (RunFolderError)
            failure = failure if failure is not None else exc
        if bar is not None:
            bar.close()
        by_component, stop_failures = master.stop_all()
        metrics = {f"{c}.{k}": v for c in master.order if c in by_component
                   for k, v in sorted(by_component[c].items())}
        try:
            write_json(out / "metrics.json", metrics)
        except UserError as exc:
            failure = failure if failure is not None else exc
    errors = ([_failure_text(failure)] if failure is not None else []) + list(map(str, stop_failures))
    ticks = max(master.ticks_done, 0)
    result = RunResult(out, "failed" if errors else "ok", "; ".join(errors) or None, ticks,
                       ticks * scenario.tick, wall,
                       (ticks * scenario.tick / wall) if wall > 0 else float("inf"),
                       metrics, pacer.stats() if pacer else None,
                       clock.marks.get("tick0"), clock.as_dict(), live,
                       _stopped_by(master.stop_request), recorder.full_signals,
                       ended - loop_started[0] if loop_started else None, manifest["lockstep_cpu"])
    write_json_in_place(out / "manifest.json", finish_manifest(
        manifest, result, failure if failure is not None else next(iter(stop_failures), None)))
    if options.page is not None:
        options.page.done()
    if failure is not None and not isinstance(failure, (UserError, KeyboardInterrupt)):
        raise failure
    return result


def _local_processes(hosted: dict[str, Any], remote: Any) -> list[int]:
    """The process ids of the lockstep chain on this machine besides the master's: component
    processes it spawned, isolated FMUs."""
    from cosim.fmu.isolated import IsolatedFmu

    pids = list(remote.local_pids()) if remote is not None else []
    return pids + [c.pid for c in hosted.values() if isinstance(c, IsolatedFmu)]


def _build_master(scenario: Any, hosted: dict[str, Any], remote: Any, out: Path,
                  realtime: float | None, progress: bool,
                  options: _Options) -> tuple[Master, Recorder, Any, Any]:
    """Wire the hosted components and attach the observers."""
    from cosim.engine.master import Master
    from cosim.results.manifest import signal_info
    from cosim.results.recorder import Recorder
    from cosim.engine.wiring import outputs_read, resolve_wiring

    edges = resolve_wiring(scenario, {n: (c.inputs, c.outputs) for n, c in hosted.items()},
                           _unsupported(hosted))
    page = options.page
    recorder = Recorder(out, scenario.record.include, scenario.record.exclude,
                        on_writer=page.note_writer if page is not None else None,
                        every=scenario.record.every, formats=scenario.record.format,
                        column_info=signal_info(hosted))
    # an extra observer (the Foxglove view) may read any output: then nothing is told
    read = (None if options.observers else
            outputs_read(edges, {n: (c.inputs, c.outputs) for n, c in hosted.items()},
                         recorder.records))
    pacer = bar = None
    if realtime is not None:
        from cosim.engine.pacing import RealtimePacer

        pacer = RealtimePacer(realtime, scenario.tick)
    if progress:
        from cosim.execution.progress import ProgressBar

        bar = ProgressBar(scenario.total_ticks, scenario.tick)
    observers: list[Any] = [o for o in (recorder, pacer, bar) if o is not None]
    if getattr(remote, "live", None) is not None:
        observers.append(_LivePublisher(remote.live))
    observers.extend(options.observers)
    master = Master(hosted, edges, scenario.tick, scenario.total_ticks, options.t0, observers,
                    crumb=page.crumb if page is not None else None, outputs_read=read)
    return master, recorder, pacer, bar


def _stopped_by(request: Any) -> dict[str, Any] | None:
    """RunResult.stopped_by for a component's request to end the run (or None)."""
    return None if request is None else {"component": request.component, "tick": request.tick,
                                         "time": request.time, "reason": request.reason}


def _failure_text(exc: BaseException) -> str:
    if isinstance(exc, UserError):
        return str(exc)
    if isinstance(exc, KeyboardInterrupt):
        return f"interrupted: {exc}" if str(exc) else "interrupted by the user (Ctrl-C)"
    return f"internal error: {type(exc).__name__}: {exc}"
