"""`cosim validate` and `cosim schema`: check a scenario without running it; the JSON schema."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from cosim.cli.common import user_error_exit
from cosim.errors import UserError


def validate(file: Path = typer.Argument(..., help="scenario YAML file"),
             set_: list[str] = typer.Option([], "--set", help="override PATH=VALUE")) -> None:
    """Check a scenario (schema, FMUs, parameters, wiring) without running it."""
    from cosim.execution.validate import validate_scenario
    from cosim.scenario.loader import load_scenario

    try:
        checked = validate_scenario(load_scenario(file, overrides=set_))
    except UserError as error:
        raise user_error_exit(error) from None
    print(f"{file}: ok ({len(checked['components'])} components, {len(checked['edges'])} "
          f"connections; step order: {', '.join(checked['order'])})")


def schema() -> None:
    """Print the scenario JSON schema (for editors)."""
    from cosim.scenario.loader import json_schema

    print(json.dumps(json_schema(), indent=2))


def register(app: typer.Typer) -> None:
    """Add `validate` and `schema` to the main typer app."""
    app.command()(validate)
    app.command()(schema)
