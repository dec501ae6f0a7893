"""`cosim build-fmus`: build the built-in plant FMUs from their C sources.

In a checkout the default output is `build/fmus/`; in an installed package it
is the per-user cache that runs use (`cosim.fmu.cache`). No model sources at
all (an incomplete install) is a user error: one line, exit 2.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from cosim.cli.common import user_error_exit
from cosim.errors import UserError


def build_fmus(out: Optional[Path] = typer.Option(
        None, "--out", help="output folder (default: build/fmus in a checkout, "
                            "else the per-user FMU cache that runs use)")) -> None:
    """Build the built-in FMUs (every folder of fmus/ with a variables.def), FMI 2.0 and 3.0.

    Example: cosim build-fmus --out /tmp/fmus
    """
    from cosim.fmu.build import build_all
    from cosim.fmu.cache import build_all_cached
    from cosim.resources import is_checkout

    created = out is not None and not out.exists()
    try:
        if out is not None:  # before compiling: an unwritable --out fails at once
            out.mkdir(parents=True, exist_ok=True)
        paths = build_all(out) if out is not None or is_checkout() else build_all_cached()
    except UserError as error:
        if created and out is not None and out.is_dir() and not any(out.iterdir()):
            out.rmdir()  # nothing was built: leave no empty folder behind
        raise user_error_exit(error) from None
    except OSError as error:  # --out in a folder that cannot be made or written
        raise user_error_exit(UserError(
            f"--out {out}: cannot write the FMUs there ({error.filename}: "
            f"{error.strerror or error})")) from None
    for path in paths:
        print(path)


def register(app: typer.Typer) -> None:
    """Add `build-fmus` to the main typer app."""
    app.command("build-fmus")(build_fmus)
