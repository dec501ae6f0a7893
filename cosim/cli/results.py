"""`cosim recover`: rebuild the CSV files and the manifest of a run whose master was killed
or whose folder could not be written."""

from __future__ import annotations

from pathlib import Path

import typer

from cosim.cli.common import user_error_exit
from cosim.errors import UserError


def recover(run_dir: Path = typer.Argument(..., help="run folder of a master that was killed"),
            keep_spool: bool = typer.Option(False, "--keep-spool", help="keep the *.f64 spools")) -> None:
    """Rebuild a run folder's CSV files from its recording spools."""
    from cosim.results.recover import recover as recover_csv

    try:
        done = recover_csv(run_dir, keep_spool=keep_spool)
    except UserError as error:
        raise user_error_exit(error) from None
    for path, rows, ignored in done:
        note = f" (ignored {ignored} bytes of a partial last row)" if ignored else ""
        print(f"{path}: {rows} rows{note}")


def register(app: typer.Typer) -> None:
    """Add `recover` to the main typer app."""
    app.command()(recover)
