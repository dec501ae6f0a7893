"""The `cosim` command line: the typer app, with the subcommands registered from
one module per group (run; validate, schema, scenarios; export-ssp; build-fmus; recover; mcap;
worker/workers/router; plot/compare/sweep; watch), and the entry point `main`.
`-h`/`--help` everywhere, `--version`, and shell completion
(`cosim --install-completion`, `cosim --show-completion`).

Every user error (bad scenario, FMU, wiring, parameters) prints one clear
message on stderr and exits with status 2, without a traceback; a run whose
component fails mid-way exits with status 1 after writing what it has.
"""

from __future__ import annotations

import sys

from cosim import quick_exit, startup_gc
from cosim.cli import interrupts

interrupts.quiet_until_started(__name__)  # before typer and rich load (about 0.2 s)
if interrupts.is_cosim_program(__name__):  # until the command is under way (tick 0 for `run`)
    startup_gc.pause()

from collections.abc import Sequence  # noqa: E402

import typer  # noqa: E402

from cosim.cli import (analysis, distributed, fmus, foxglove, results, run, scenario,  # noqa: E402
                       ssp, watch)
from cosim.cli.common import EXIT_USER_ERROR, user_error_exit  # noqa: E402
from cosim.errors import UserError  # noqa: E402

app = typer.Typer(add_completion=True, no_args_is_help=True,
                  context_settings={"help_option_names": ["-h", "--help"]},
                  help="Co-simulation of closed-loop vehicle control (FMU plants, Python components)."
                       "\n\nStart with: cosim scenarios, then cosim run lane_change."
                       " Shell completion: cosim --install-completion.")
for _commands in (run, scenario, ssp, fmus, results, foxglove, distributed, analysis, watch):
    _commands.register(app)


def _print_version(value: bool) -> None:
    if value:
        import cosim

        print(f"cosim {cosim.__version__}")
        raise typer.Exit(0)


@app.callback()
def _options(version: bool = typer.Option(False, "--version", "-V", is_eager=True,
                                          callback=_print_version,
                                          help="print the version and exit")) -> None:
    """Co-simulation of closed-loop vehicle control (FMU plants, Python components)."""


FOXGLOVE_PORT = 8765  # Foxglove's usual port (cosim.foxglove.live.DEFAULT_PORT; not imported: no SDK load here)


def normalize_realtime(argv: Sequence[str]) -> list[str]:
    """Give a bare `--realtime` its default factor 1.0 and a bare `--foxglove` its port 8765
    (click has no optional values).

    Args:
        argv: command-line arguments after the program name.
    """
    args = list(argv)
    result: list[str] = []
    for i, arg in enumerate(args):
        result.append(arg)
        following = args[i + 1] if i + 1 < len(args) else None
        if arg == "--realtime" and not _is_number(following):
            result.append("1.0")
        if arg == "--foxglove" and not _is_integer(following):  # "-1": its range check says why
            result.append(str(FOXGLOVE_PORT))
    return result


def _is_integer(text: str | None) -> bool:
    return text is not None and text.lstrip("+-").isdigit()


def _is_number(text: str | None) -> bool:
    try:
        float(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
    return True


def main(argv: Sequence[str] | None = None) -> int:
    """Console-script entry point; returns the exit status.

    In the `cosim` command's own process (not a test calling `main`) the process then
    ends without the interpreter's teardown (`cosim.quick_exit`), with that status.

    Args:
        argv: arguments (default: sys.argv[1:]).
    """
    if interrupts.is_cosim_command():
        quick_exit.skip_teardown()
    return quick_exit.exit_status(_command(argv))


def _command(argv: Sequence[str] | None) -> int:
    """Run the command line `argv`; its exit status."""
    args = normalize_realtime(sys.argv[1:] if argv is None else argv)
    if args[:1] != ["run"]:  # `run` keeps the quiet Ctrl-C until its own handling starts
        interrupts.restore()  # and collection paused until tick 0
        startup_gc.resume()
    command = typer.main.get_command(app)
    try:
        result = command.main(args=args, prog_name="cosim", standalone_mode=False)
    except typer.Abort:
        print("Aborted!", file=sys.stderr)
        return 1
    except _click_errors() as exc:  # a bad option, argument or command
        return _option_error(exc)
    except SystemExit as exc:  # a command that exits itself
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    return result if isinstance(result, int) else 0


def _click_errors() -> tuple[type[Exception], ...]:
    """The base classes of click's errors (typer >= 0.20 carries its own click)."""
    errors: list[type[Exception]] = []
    if hasattr(typer, "TyperException"):
        errors.append(typer.TyperException)
    try:
        import click
    except ImportError:
        return tuple(errors)
    return (*errors, click.ClickException)


def _option_error(exc: Exception) -> int:
    """Print click's error as one line naming the command and its help; its exit status.

    `cosim` alone (no arguments) still prints the help.
    """
    code = int(getattr(exc, "exit_code", EXIT_USER_ERROR))
    if type(exc).__name__ == "NoArgsIsHelpError":
        exc.show()  # type: ignore[attr-defined]
        return code
    ctx = getattr(exc, "ctx", None)
    path = ctx.command_path if ctx is not None else "cosim"
    message = exc.format_message() if hasattr(exc, "format_message") else str(exc)
    user_error_exit(UserError(f"{path}: {message} (see '{path} --help')"))
    return code


if __name__ == "__main__":
    sys.exit(main())
