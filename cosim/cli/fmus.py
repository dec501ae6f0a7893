"""`cosim build-fmus`: build the built-in plant FMUs from their C sources."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from cosim.cli.common import user_error_exit
from cosim.errors import UserError


def build_fmus(out: Optional[Path] = typer.Option(None, "--out", help="output folder")) -> None:
    """Build the built-in FMUs."""
    from cosim.fmu.build import FmuBuildError, build_all

    try:
        paths = build_all(out)
    except (UserError, FmuBuildError) as error:
        raise user_error_exit(UserError(str(error))) from None
    for path in paths:
        print(path)


def register(app: typer.Typer) -> None:
    """Add `build-fmus` to the main typer app."""
    app.command("build-fmus")(build_fmus)
