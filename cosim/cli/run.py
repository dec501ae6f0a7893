"""`cosim run`: load a scenario, run it, then print its summary and draw its figures.

The run's folder is announced as soon as it exists; a user error prints one
line and exits 2, a run that fails or is interrupted exits 1 after writing what
it has (see `cosim.execution.run`).
"""

from __future__ import annotations

import contextlib
import functools
import sys
import datetime
import signal
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, Optional

import typer

from cosim import startup_gc
from cosim.cli import interrupts
from cosim.cli.common import STRICT_HELP, print_warning, user_error_exit
from cosim.engine import one_cpu
from cosim.errors import StartFault, UserError
from cosim.execution.figure_process import FigureProcess
from cosim.execution.finish import analyse_run_folder  # shared with cosim.run (the Python API)
from cosim.scenario.shipped import resolve_scenario
from cosim.execution.limits import DEFAULT_MAX_TICKS, RunLimits
from cosim.transport.launch import STARTUP_TIMEOUT_S

DEFAULT_TRANSPORT = "zenoh"  # DESIGN.md: each Python component its own OS process
EXIT_FAILED_RUN = 1


def default_run_dir(name: str, now: datetime.datetime | None = None) -> Path:
    """A fresh folder runs/<name>-<UTC timestamp> (a suffix when it exists).

    Args:
        name: the scenario's name.
        now: the time to stamp (default: now, UTC).
    """
    from cosim.cli.analysis import stamped_folder

    return stamped_folder("runs", name, now)


def run(
    scenario: Optional[str] = typer.Argument(
        None, help="scenario YAML file, or a shipped scenario's name (none: list them)",
        show_default=False),
    out: Optional[str] = typer.Option(None, "--out", help="run folder (default: runs/<name>-<UTC time>)"),
    transport: str = typer.Option(DEFAULT_TRANSPORT, "--transport", help="inproc | zenoh"),
    set_: list[str] = typer.Option([], "--set", help="override PATH=VALUE (YAML value), repeatable"),
    realtime: Optional[float] = typer.Option(
        None, "--realtime", help="pace to wall clock at FACTOR (bare --realtime: 1.0)"),
    figures: bool = typer.Option(True, "--figures/--no-figures", help="draw the run's figures"),
    place: list[str] = typer.Option([], "--place", help="COMPONENT=WORKER (overrides host:), repeatable; "
                                    "WORKER 'local': this host, 'inproc': the master's own process"),
    listen: list[str] = typer.Option([], "--listen", help="master endpoint the workers reach"),
    connect: list[str] = typer.Option([], "--connect", help="worker or router endpoint, repeatable"),
    deploy: Optional[Path] = typer.Option(None, "--deploy", help="deployment settings YAML (endpoints, TLS, ACL)"),
    deadline: float = typer.Option(10.0, "--deadline",
                                   help="deadline of a component call (FMI call, step, remote "
                                        "exchange), s; a component's `deadline:` overrides it"),
    startup_timeout: float = typer.Option(
        STARTUP_TIMEOUT_S, "--startup-timeout",
        help="longest a Python component may take to start (its process and handshake, or its "
             "constructor in the master's process), s"),
    prestart: bool = typer.Option(True, "--prestart/--no-prestart",
                                  help="start component processes while the scenario loads"),
    mcap: bool = typer.Option(False, "--mcap", help="also write run.mcap (as record: {mcap: true})"),
    foxglove: Optional[int] = typer.Option(
        None, "--foxglove", help="serve the run live to Foxglove on PORT (bare --foxglove: 8765)"),
    foxglove_host: str = typer.Option("127.0.0.1", "--foxglove-host",
                                      help="loopback address of the Foxglove server"),
    max_ticks: int = typer.Option(DEFAULT_MAX_TICKS, "--max-ticks",
                                  help="refuse a run of more ticks than this"),
    allow_large: bool = typer.Option(False, "--allow-large",
                                     help="no limit on ticks or CSV size (10 GB by default)"),
    force: bool = typer.Option(False, "--force", help="let --out replace an earlier run's folder "
                                                      "(its files are removed first)"),
    fmu_log: bool = typer.Option(False, "--fmu-log", help="every FMU's log messages to run.log"),
    supervise: bool = typer.Option(True, "--supervise/--no-supervise",
                                   help="a parent process that completes the run folder if "
                                        "the master dies or hangs in native code"),
    strict: bool = typer.Option(False, "--strict", help=STRICT_HELP),
    lockstep_cpu: str = typer.Option(
        "auto", "--lockstep-cpu",
        help="auto | off | CPU: the master and the processes it starts on one CPU (auto: the one "
             "it starts on; faster in lockstep), off: wherever the OS puts them"),
) -> None:
    """Run a scenario and write its run folder.

    Examples (quoted, so they paste into any shell):

        cosim run lane_change --transport inproc --set 'duration=10'

        cosim run scenarios/lane_change.yaml --set 'components.vehicle.fmu=Bicycle'
    """
    from cosim.execution.run import check_run_options
    from cosim.engine.startup import StartupClock

    clock = StartupClock.from_process_start()  # time to tick 0 as the user sees it
    # until `_start_and_run` gives Ctrl-C back to Python, the early handler ends the command
    # (the supervisor too, before its fork) with one line: nothing before can be left behind
    if scenario is None:
        raise _list_shipped()
    try:
        check_run_options(transport, realtime, deadline, startup_timeout)  # before anything else
        scenario_file = resolve_scenario(scenario)
        if mcap:
            from cosim.cli.foxglove import require_foxglove
            require_foxglove("--mcap")
        limits = RunLimits(max_ticks, allow_large)
        chain_setting = one_cpu.check_setting(lockstep_cpu)
        out_dir = check_out_option(out, force)
    except UserError as error:
        raise user_error_exit(error) from None
    if supervise and interrupts.is_cosim_command():  # not under a test's in-process CLI
        from cosim.execution.supervisor import fork_supervisor

        cpu_before_fork = time.process_time()
        status = fork_supervisor()
        if status is not None:  # the supervisor: the master has ended
            raise typer.Exit(status)
        clock.after_fork(cpu_before_fork)  # the master's CPU time counts the parsing too
    drawer = FigureProcess() if figures else None  # started after tick 0: its imports overlap the run
    try:
        result = _start_and_run(scenario_file, set_, out_dir, (deploy, listen, connect), clock,
                                (foxglove, foxglove_host), prestart and transport == "zenoh"
                                and not (place or listen or connect or deploy),
                                transport=transport, realtime=realtime, place=place,
                                deadline_s=deadline, startup_timeout_s=startup_timeout, replace=force,
                                limits=limits, fmu_log=fmu_log,
                                strict=strict, lockstep_cpu=chain_setting,
                                at_tick0=functools.partial(_tick0_done, drawer))
        with _sigterm_interrupts():  # a SIGTERM while drawing ends the drawing process too
            _finish_run(result, figures, mcap, drawer)
    finally:
        startup_gc.resume()  # a run that ended before tick 0
        if drawer is not None:
            drawer.close()


def _tick0_done(drawer: Any) -> None:
    """Once tick 0 is done: collect again, the start-up's objects frozen
    (cosim.startup_gc), and start the drawing process."""
    startup_gc.resume(freeze=True)
    if drawer is not None:
        drawer.start()


def _start_and_run(scenario_file: Path, overrides: list[str], out: Optional[Path],
                   endpoints: tuple[Optional[Path], list[str], list[str]], clock: Any,
                   foxglove: tuple[Optional[int], str], prestart: bool, **run_options: Any) -> Any:
    """`_load_and_run`, the components started while the scenario loads when `prestart`;
    a user error or a Ctrl-C before tick 0 becomes the command's exit."""
    early = None
    try:
        interrupts.restore()  # from here a Ctrl-C is handled below and by the run
        if prestart:
            from cosim.execution.prestart import prestart_components

            early = prestart_components(scenario_file)  # their start overlaps the scenario's load
        return _load_and_run(scenario_file, overrides, out, endpoints, clock, foxglove,
                             prestart=early, **run_options)
    except StartFault as fault:  # a component process died or hung before tick 0
        raise _failed_run_exit(str(fault)) from None
    except UserError as error:
        raise user_error_exit(error) from None
    except KeyboardInterrupt as exc:  # Ctrl-C before tick 0 (after it, the run records it itself)
        raise _interrupted_exit(where=str(exc)) from None
    except Exception as exc:
        if isinstance(exc.__context__, KeyboardInterrupt):
            raise _interrupted_exit(f"{type(exc).__name__}: {exc}") from None  # while stopping
        if interrupts.seen():  # the Ctrl-C, turned into a library's own error
            raise _interrupted_exit() from None
        raise
    finally:
        if early is not None:
            early.close()


def _list_shipped() -> typer.Exit:
    """`cosim run` without a scenario: say how to run one and list the shipped ones (exit 0)."""
    from cosim.scenario.shipped import listing

    print("usage: cosim run SCENARIO [OPTIONS]  (a YAML file or a shipped name; "
          "cosim run -h for the options)\nshipped scenarios:")
    print(listing())
    return typer.Exit(0)


def check_out_option(out: Optional[str], force: bool) -> Optional[Path]:
    """The `--out` folder (None: a fresh folder under runs/); see
    `cosim.execution.run.check_out_folder`, which raises the UserError."""
    from cosim.execution.run import check_out_folder

    return None if out is None else check_out_folder(out, force)


def _failed_run_exit(line: str) -> typer.Exit:
    """Print `run failed: LINE` on stderr (LINE as it is, no markup read from it); the exit
    of a failed run (status 1)."""
    from rich.console import Console
    from rich.markup import escape

    Console(stderr=True, highlight=False, soft_wrap=True).print(
        f"[red]run failed:[/red] {escape(line)}", markup=True)
    return typer.Exit(EXIT_FAILED_RUN)


def _interrupted_exit(stop_error: str | None = None, where: str = "") -> typer.Exit:
    """Say the run was interrupted before tick 0; the exit of a failed run (status 1).

    Args:
        stop_error: an error raised while the interrupted start-up was undone.
        where: what the run was doing, when known ("in the constructor of component 'x'").
    """
    from cosim.execution.abort import INTERRUPTED_BEFORE_TICK0

    note = (f" ({where})" if where else "") + (f" (then, while stopping: {stop_error})"
                                                if stop_error else "")
    return _failed_run_exit(INTERRUPTED_BEFORE_TICK0 + note)


def _load_and_run(scenario_file: Path, overrides: list[str], out: Optional[Path],
                  endpoints: tuple[Optional[Path], list[str], list[str]], clock: Any,
                  foxglove: tuple[Optional[int], str] = (None, ""),
                  at_tick0: Optional[Callable[[], None]] = None, **run_options: Any) -> Any:
    """Load the scenario, name its run folder, then run it (SIGTERM ends it cleanly).

    Args:
        scenario_file: the scenario YAML.
        overrides: the `--set PATH=VALUE` values.
        out: the run folder, or None for a fresh one under runs/.
        endpoints: `--deploy` file, `--listen` and `--connect` values.
        clock: the cosim.engine.startup.StartupClock of the command (marks "scenario_loaded").
        foxglove: `--foxglove` port (None: no live server) and `--foxglove-host`.
        at_tick0: called once tick 0 is done (`run_scenario(at_tick0=)`): the start-up
            has had the CPUs to itself.
        run_options: passed on to `cosim.execution.run.run_scenario`.
    Returns:
        The cosim.execution.run.RunResult.
    """
    from cosim.cli.foxglove import live_server
    from cosim.execution.run import run_scenario
    from cosim.scenario.loader import load_scenario

    loaded = load_scenario(scenario_file, overrides=overrides)
    clock.mark("scenario_loaded")
    folder = out if out is not None else default_run_dir(loaded.name)
    settings = None
    if endpoints[0] is not None or endpoints[1] or endpoints[2]:
        from cosim.cli.distributed import load_settings
        settings = load_settings(*endpoints)
    if loaded.record.mcap:
        from cosim.cli.foxglove import require_foxglove
        require_foxglove(loaded.where(("record", "mcap")))
    with _sigterm_interrupts(), live_server(loaded, *foxglove) as observers:
        result = run_scenario(loaded, folder, progress=sys.stdout.isatty(), deploy=settings,
                              clock=clock, on_live=_print_live, on_folder=_print_folder,
                              observers=observers, on_warning=print_warning,
                              before_tick0=interrupts.raise_if_swallowed, at_tick0=at_tick0,
                              runs_in_process=1 if interrupts.is_cosim_command() else None, **run_options)
    result.mcap = loaded.record.mcap
    return result


def _print_folder(folder: Path) -> None:
    """Tell the user where the run is written (called once the folder exists)."""
    print(f"run folder: {folder}", flush=True)


def _finish_run(result: Any, figures: bool, mcap: bool = False, drawer: Any = None) -> None:
    """Analyse the run folder and print the summary; a failed run exits with status 1.

    Args:
        result: the cosim.execution.run.RunResult.
        figures: draw the run's figures.
        mcap: write run.mcap (also when the scenario's record.mcap is set).
        drawer: the FigureProcess started with the run, or None (drawn here).
    """
    from cosim.cli.summary import print_summary

    if result.ticks > 0 and result.out_dir.is_dir():  # a removed folder has nothing to analyse
        for note in analyse_run_folder(result, figures, drawer):
            print(note)
        if mcap or getattr(result, "mcap", False):
            from cosim.cli.foxglove import write_mcap_note
            for note in write_mcap_note(result.out_dir):
                print(note)
    print_summary(result)  # run table, then metrics table
    stopped = result.stopped_by
    if stopped is not None:
        print(f"stopped by component {stopped['component']!r} at tick {stopped['tick']} "
              f"(t={stopped['time']:.10g} s): {stopped['reason']}")
    if result.status != "ok":
        raise _failed_run_exit(str(result.error))


def _print_live(run_id: str, endpoint: str) -> None:
    """Tell the user how to watch the run live (called before tick 0)."""
    print(f"run id: {run_id}  live: {endpoint}  (watch: cosim watch RUN_FOLDER, "
          f"which holds the run's credential)", flush=True)


@contextlib.contextmanager
def _sigterm_interrupts() -> Iterator[None]:
    """Turn SIGTERM into KeyboardInterrupt so the run records and closes its files."""
    def interrupt(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt("terminated by SIGTERM")

    try:
        previous = signal.signal(signal.SIGTERM, interrupt)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def register(app: typer.Typer) -> None:
    """Add `run` to the main typer app."""
    app.command()(run)
