"""`cosim mcap RUN_DIR`, and the Foxglove parts of `cosim run` (--mcap, --foxglove [PORT]).

run.mcap is written after the run from the run folder (cosim.foxglove.mcap_export);
the live server is a master observer (cosim.foxglove.live). Both need the
`foxglove` extra (foxglove-sdk); asking for either without it is a user error
before anything starts.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import typer

from cosim.cli.common import user_error_exit
from cosim.errors import UserError

INSTALL_HINT = "pip install 'cosim-vehicle[foxglove]' (the foxglove-sdk package)"


def require_foxglove(what: str) -> None:
    """A UserError naming `what` when foxglove-sdk is not installed."""
    try:
        import foxglove  # noqa: F401
    except ImportError:
        raise UserError(f"{what} needs the Foxglove SDK: {INSTALL_HINT}") from None


@contextlib.contextmanager
def live_server(scenario: Any, port: int | None, host: str) -> Iterator[list[Any]]:
    """The observers of `--foxglove PORT` (none when port is None), server up while inside."""
    if port is None:
        yield []
        return
    require_foxglove("--foxglove")
    from cosim.foxglove.live import FoxgloveLive, static_scene

    with FoxgloveLive(port, host, static=static_scene(scenario)) as live:
        print(f"foxglove: {live.url}  (open it in Foxglove: Open connection, Foxglove WebSocket)",
              flush=True)
        yield [live]


def write_mcap_note(run_dir: Path) -> list[str]:
    """Write run.mcap into a finished run folder; the notes to print (best effort)."""
    try:
        from cosim.foxglove.mcap_export import write_run_mcap

        path, notes = write_run_mcap(run_dir)
    except Exception as exc:  # the run's own files are complete: say why, do not fail it
        return [f"run.mcap not written: {exc}"]
    return [f"mcap: {path}"] + notes


def mcap(run_dir: Path = typer.Argument(..., help="a run folder (signals.csv, manifest.json)")) -> None:
    """Write run.mcap (Foxglove's schemas) from a run folder's recorded signals."""
    try:
        require_foxglove("cosim mcap")
        from cosim.foxglove.mcap_export import write_run_mcap

        path, notes = write_run_mcap(run_dir)
    except UserError as error:
        raise user_error_exit(error) from None
    for line in [str(path), *notes]:
        print(line)


def register(app: typer.Typer) -> None:
    """Add `mcap` to the main typer app."""
    app.command()(mcap)
