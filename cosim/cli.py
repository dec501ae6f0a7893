"""The `cosim` command line: run, validate, schema, build-fmus, recover (and, registered
from their modules: watch, worker/workers/router, plot/compare/sweep).

Every user error (bad scenario, FMU, wiring, parameters) prints one clear
message on stderr and exits with status 2, without a traceback; a run whose
component fails mid-way exits with status 1 after writing what it has.
"""

from __future__ import annotations

import signal
import sys


def _early_interrupt(signum: int, frame: object) -> None:
    """Ctrl-C while the command line loads: one line and the failed-run status, no traceback."""
    running = sys.argv[1:2] == ["run"]
    sys.stderr.write("run failed: interrupted before tick 0\n" if running else "cosim: interrupted\n")
    raise SystemExit(1)


def _is_cosim_program() -> bool:
    """True when this process is the `cosim` command (not a test importing the module)."""
    program = sys.argv[0].replace("\\", "/").rsplit("/", 1)[-1] if sys.argv else ""
    return program in ("cosim", "cli.py") or __name__ == "__main__"


if _is_cosim_program() and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
    try:
        signal.signal(signal.SIGINT, _early_interrupt)  # typer and rich take ~0.2 s to import
    except ValueError:  # not the main thread: leave signals alone
        pass

import contextlib  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
from collections.abc import Iterator, Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, Optional  # noqa: E402

import typer  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.markup import escape  # noqa: E402

from cosim.cli_common import user_error_exit  # noqa: E402
from cosim.errors import UserError  # noqa: E402

DEFAULT_TRANSPORT = "zenoh"  # DESIGN.md: each Python component its own OS process
EXIT_FAILED_RUN = 1

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="Co-simulation of closed-loop vehicle control (FMU plants, Python components).")


def default_run_dir(name: str, now: datetime.datetime | None = None) -> Path:
    """A fresh folder runs/<name>-<UTC timestamp> (a suffix when it exists).

    Args:
        name: the scenario's name.
        now: the time to stamp (default: now, UTC).
    """
    from cosim.cli_analysis import stamped_folder

    return stamped_folder("runs", name, now)


@app.command()
def run(
    scenario: Path = typer.Argument(..., help="scenario YAML file"),
    out: Optional[Path] = typer.Option(None, "--out", help="run folder (default: runs/<name>-<UTC time>)"),
    transport: str = typer.Option(DEFAULT_TRANSPORT, "--transport", help="inproc | zenoh"),
    set_: list[str] = typer.Option([], "--set", help="override PATH=VALUE (YAML value), repeatable"),
    realtime: Optional[float] = typer.Option(
        None, "--realtime", help="pace to wall clock at FACTOR (bare --realtime: 1.0)"),
    figures: bool = typer.Option(True, "--figures/--no-figures", help="draw the run's figures"),
    place: list[str] = typer.Option([], "--place", help="COMPONENT=WORKER (overrides host:), repeatable"),
    listen: list[str] = typer.Option([], "--listen", help="master endpoint the workers reach"),
    connect: list[str] = typer.Option([], "--connect", help="worker or router endpoint, repeatable"),
    deploy: Optional[Path] = typer.Option(None, "--deploy", help="deployment settings YAML (endpoints, TLS, ACL)"),
    deadline: float = typer.Option(10.0, "--deadline", help="per-exchange deadline of remote components, s"),
    prestart: bool = typer.Option(True, "--prestart/--no-prestart",
                                  help="start component processes while the scenario loads"),
) -> None:
    """Run a scenario and write its run folder."""
    from cosim.run import check_run_options
    from cosim.startup import StartupClock

    clock = StartupClock.from_process_start()  # time to tick 0 as the user sees it
    _restore_interrupts()  # from here a Ctrl-C is handled below and by the run
    try:
        check_run_options(transport, realtime)  # option errors come before anything else
    except UserError as error:
        raise user_error_exit(error) from None
    early = None
    try:
        if prestart and transport == "zenoh" and not (place or listen or connect or deploy):
            from cosim.prestart import prestart_components

            early = prestart_components(scenario)  # their start overlaps the scenario's load
        result = _load_and_run(scenario, set_, out, (deploy, listen, connect), clock,
                               transport=transport, realtime=realtime, place=place,
                               deadline_s=deadline, prestart=early)
    except UserError as error:
        raise user_error_exit(error) from None
    except KeyboardInterrupt:  # Ctrl-C before tick 0 (after it, the run records it itself)
        raise _interrupted_exit() from None
    except Exception as exc:
        if not isinstance(exc.__context__, KeyboardInterrupt):
            raise
        raise _interrupted_exit(f"{type(exc).__name__}: {exc}") from None  # while stopping
    finally:
        if early is not None:
            early.close()
    _finish_run(result, figures)


def _restore_interrupts() -> None:
    """Give Ctrl-C back to Python (KeyboardInterrupt) once the command has started."""
    if signal.getsignal(signal.SIGINT) is _early_interrupt:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def _interrupted_exit(stop_error: str | None = None) -> typer.Exit:
    """Say the run was interrupted before tick 0; the exit of a failed run (status 1).

    Args:
        stop_error: an error raised while the interrupted start-up was undone.
    """
    from cosim.run_abort import INTERRUPTED_BEFORE_TICK0

    note = f" (then, while stopping: {stop_error})" if stop_error else ""
    Console(stderr=True, highlight=False, soft_wrap=True).print(
        f"[red]run failed:[/red] {INTERRUPTED_BEFORE_TICK0}{escape(note)}", markup=True)
    return typer.Exit(EXIT_FAILED_RUN)


def _load_and_run(scenario_file: Path, overrides: list[str], out: Optional[Path],
                  endpoints: tuple[Optional[Path], list[str], list[str]], clock: Any,
                  **run_options: Any) -> Any:
    """Load the scenario, name its run folder, then run it (SIGTERM ends it cleanly).

    Args:
        scenario_file: the scenario YAML.
        overrides: the `--set PATH=VALUE` values.
        out: the run folder, or None for a fresh one under runs/.
        endpoints: `--deploy` file, `--listen` and `--connect` values.
        clock: the cosim.startup.StartupClock of the command (marks "scenario_loaded").
        run_options: passed on to `cosim.run.run_scenario`.
    Returns:
        The cosim.run.RunResult.
    """
    from cosim.run import run_scenario
    from cosim.scenario import load_scenario

    loaded = load_scenario(scenario_file, overrides=overrides)
    clock.mark("scenario_loaded")
    folder = out if out is not None else default_run_dir(loaded.name)
    settings = None
    if endpoints[0] is not None or endpoints[1] or endpoints[2]:
        from cosim.worker_cli import load_settings
        settings = load_settings(*endpoints)
    with _sigterm_interrupts():
        return run_scenario(loaded, folder, progress=sys.stdout.isatty(), deploy=settings,
                            clock=clock, on_live=_print_live, on_folder=_print_folder,
                            **run_options)


def _print_folder(folder: Path) -> None:
    """Tell the user where the run is written (called once the folder exists)."""
    print(f"run folder: {folder}", flush=True)


def _finish_run(result: Any, figures: bool) -> None:
    """Analyse the run folder and print the summary; a failed run exits with status 1.

    Args:
        result: the cosim.run.RunResult.
        figures: draw the run's figures.
    """
    from cosim.summary import print_summary

    if result.ticks > 0:
        for note in analyse_run_folder(result, figures):
            print(note)
    print_summary(result)  # run table, then metrics table
    if result.status != "ok":
        Console(stderr=True, highlight=False, soft_wrap=True).print(
            f"[red]run failed:[/red] {escape(str(result.error))}", markup=True)
        raise typer.Exit(EXIT_FAILED_RUN)


def _print_live(run_id: str, endpoint: str) -> None:
    """Tell the user how to watch the run live (called before tick 0)."""
    print(f"run id: {run_id}  live: {endpoint}  (watch: cosim watch {run_id} "
          f"--connect {endpoint})", flush=True)


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


def analyse_run_folder(result: Any, figures: bool) -> list[str]:
    """Merge the run metrics into metrics.json and draw the figures; notes to print.

    A run folder that cannot be analysed (e.g. a scenario without a vehicle)
    gives a note, not an error: the run itself succeeded.

    Args:
        result: a cosim.run.RunResult (its metrics are refreshed from metrics.json).
        figures: draw the PNG figures too.
    """
    from cosim.metrics import write_metrics
    from cosim.metrics_rundata import load_run

    try:
        run = load_run(result.out_dir)  # signals.csv parsed once, for metrics and figures
    except Exception as exc:  # analysis is best effort after a run
        return [f"metrics not computed: {exc}"] + ([f"figures not drawn: {exc}"] if figures else [])
    notes: list[str] = []
    try:
        write_metrics(result.out_dir, run=run)
        result.metrics = json.loads((result.out_dir / "metrics.json").read_text())
    except Exception as exc:
        notes.append(f"metrics not computed: {exc}")
    if figures:
        try:
            from cosim.figures import draw_figures

            notes += [f"figure: {path}" for path in draw_figures(result.out_dir, run=run)]
        except Exception as exc:
            notes.append(f"figures not drawn: {exc}")
    return notes


@app.command()
def validate(file: Path = typer.Argument(..., help="scenario YAML file"),
             set_: list[str] = typer.Option([], "--set", help="override PATH=VALUE")) -> None:
    """Check a scenario (schema, FMUs, parameters, wiring) without running it."""
    from cosim.run import validate_scenario
    from cosim.scenario import load_scenario

    try:
        checked = validate_scenario(load_scenario(file, overrides=set_))
    except UserError as error:
        raise user_error_exit(error) from None
    print(f"{file}: ok ({len(checked['components'])} components, {len(checked['edges'])} "
          f"connections; step order: {', '.join(checked['order'])})")


@app.command()
def schema() -> None:
    """Print the scenario JSON schema (for editors)."""
    from cosim.scenario import json_schema

    print(json.dumps(json_schema(), indent=2))


@app.command("build-fmus")
def build_fmus(out: Optional[Path] = typer.Option(None, "--out", help="output folder")) -> None:
    """Build the built-in FMUs."""
    from cosim.fmu_build import FmuBuildError, build_all

    try:
        paths = build_all(out)
    except (UserError, FmuBuildError) as error:
        raise user_error_exit(UserError(str(error))) from None
    for path in paths:
        print(path)


@app.command()
def recover(run_dir: Path = typer.Argument(..., help="run folder of a master that was killed"),
            keep_spool: bool = typer.Option(False, "--keep-spool", help="keep the *.f64 spools")) -> None:
    """Rebuild a run folder's CSV files from its recording spools."""
    from cosim.recorder import recover as recover_csv

    try:
        done = recover_csv(run_dir, keep_spool=keep_spool)
    except UserError as error:
        raise user_error_exit(error) from None
    for path, rows, ignored in done:
        note = f" (ignored {ignored} bytes of a partial last row)" if ignored else ""
        print(f"{path}: {rows} rows{note}")


from cosim.worker_cli import register as _register_distributed  # noqa: E402

_register_distributed(app)

from cosim.cli_analysis import register as _register_analysis  # noqa: E402

_register_analysis(app)

from cosim.cli_watch import register as _register_watch  # noqa: E402

_register_watch(app)


def normalize_realtime(argv: Sequence[str]) -> list[str]:
    """Give a bare `--realtime` its default factor 1.0 (click has no optional values).

    Args:
        argv: command-line arguments after the program name.
    """
    args = list(argv)
    result: list[str] = []
    for i, arg in enumerate(args):
        result.append(arg)
        if arg == "--realtime" and not _is_number(args[i + 1] if i + 1 < len(args) else None):
            result.append("1.0")
    return result


def _is_number(text: str | None) -> bool:
    try:
        float(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
    return True


def main(argv: Sequence[str] | None = None) -> int:
    """Console-script entry point; returns the exit status.

    Args:
        argv: arguments (default: sys.argv[1:]).
    """
    args = normalize_realtime(sys.argv[1:] if argv is None else argv)
    if args[:1] != ["run"]:  # `run` keeps the quiet Ctrl-C until its own handling starts
        _restore_interrupts()
    command = typer.main.get_command(app)
    try:
        command.main(args=args, prog_name="cosim", standalone_mode=True)
    except SystemExit as exc:  # standalone mode always ends with SystemExit
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
