"""`cosim validate`, `cosim schema`, `cosim scenarios`: check a scenario without running it;
the JSON schema; the shipped scenarios."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from cosim.cli.common import STRICT_HELP, print_warning, user_error_exit
from cosim.errors import UserError
from cosim.execution.limits import DEFAULT_MAX_TICKS, RunLimits


def validate(file: str = typer.Argument(..., help="scenario YAML file, or a shipped scenario's name"),
             set_: list[str] = typer.Option([], "--set", help="override PATH=VALUE"),
             max_ticks: int = typer.Option(DEFAULT_MAX_TICKS, "--max-ticks",
                                           help="refuse a run of more ticks than this"),
             allow_large: bool = typer.Option(False, "--allow-large",
                                              help="no limit on ticks or CSV size"),
             strict: bool = typer.Option(False, "--strict", help=STRICT_HELP)) -> None:
    """Check a scenario (schema, FMUs, parameters, wiring, run size) without running it.

    Example: cosim validate lane_change --set 'duration=10'
    """
    from cosim.execution.validate import validate_scenario
    from cosim.scenario.loader import load_scenario
    from cosim.scenario.shipped import resolve_scenario

    try:
        limits = RunLimits(max_ticks, allow_large)
        checked = validate_scenario(load_scenario(resolve_scenario(file), overrides=set_), limits,
                                     strict=strict)
    except UserError as error:
        raise user_error_exit(error) from None
    for gap in checked["warnings"]:
        print_warning(gap)
    print(f"{file}: ok ({len(checked['components'])} components, {len(checked['edges'])} "
          f"connections; step order: {', '.join(checked['order'])})")


def schema(out: Optional[Path] = typer.Option(
        None, "--out", help="write the schema to this file instead of printing it")) -> None:
    """Print (or write) the scenario JSON schema, for editors with a YAML language server.

    The shipped scenarios' first line points at scenarios/scenario.schema.json, this schema.
    Example: cosim schema --out 'scenario.schema.json'
    """
    from cosim.scenario.schema import schema_text

    text = schema_text()
    if out is None:
        print(text, end="")
        return
    try:
        out.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise user_error_exit(UserError(
            f"{out}: cannot write the schema: {exc.strerror or exc}")) from None
    print(f"wrote {out}")


def scenarios() -> None:
    """List the shipped scenarios, one line each (name, duration, what it shows).

    Run one by name from any folder: cosim run lane_change
    """
    from cosim.scenario.shipped import listing

    print(listing())


def register(app: typer.Typer) -> None:
    """Add `validate`, `schema` and `scenarios` to the main typer app."""
    app.command()(validate)
    app.command()(schema)
    app.command()(scenarios)
