"""`cosim export-ssp`: write the FMU part of a scenario as an SSP package
(`cosim run system.ssp` and `system: file.ssp` read one back; docs/ssp.md)."""

from __future__ import annotations

from pathlib import Path

import typer

from cosim.cli.common import user_error_exit
from cosim.errors import UserError


def export_ssp(file: str = typer.Argument(..., help="scenario YAML file, or a shipped scenario's name"),
               out: Path = typer.Argument(..., help="the .ssp file to write (its folder created if missing)"),
               set_: list[str] = typer.Option([], "--set", help="override PATH=VALUE"),
               ssp_version: str = typer.Option("1.0", "--ssp-version",
                                               help="SSP version to write: 1.0 or 2.0")) -> None:
    """Write the FMU components, their connections and parameters as an .ssp.

    Example: cosim export-ssp lane_change plant.ssp
    """
    from cosim.analysis.outputs import check_output_file
    from cosim.execution.ssp_export import export_ssp as write
    from cosim.scenario.loader import load_scenario
    from cosim.scenario.shipped import resolve_scenario

    try:
        if out.suffix.lower() != ".ssp":
            raise UserError(f"{out}: the output file must end in .ssp")
        check_output_file(out)
        report = write(load_scenario(resolve_scenario(file), overrides=set_), out, ssp_version)
    except UserError as error:
        raise user_error_exit(error) from None
    print(f"wrote {out}: {report.components} FMU components, {report.connections} connections "
          f"(SSP {ssp_version})")
    if report.left_out:
        print(f"left out (not FMU-to-FMU): {', '.join(report.left_out)}")


def register(app: typer.Typer) -> None:
    """Add `export-ssp` to the main typer app."""
    app.command(name="export-ssp")(export_ssp)
