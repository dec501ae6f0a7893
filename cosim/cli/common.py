"""What every `cosim` command shares: the exit status of a user error and how it is shown.

A user error (`cosim.errors.UserError`) prints one line on stderr, "error: ...",
without a traceback, and ends the command with status 2.
"""

from __future__ import annotations

import typer
from rich.console import Console

from cosim.errors import UserError

EXIT_USER_ERROR = 2
STRICT_HELP = ("a plant-contract output the plant lacks, or an input left unconnected, "
               "is an error (default: a warning)")


def print_warning(text: str) -> None:
    """Print one warning line on stderr ("warning: ...").

    Args:
        text: the warning; printed as is (no markup read from it).
    """
    console = Console(stderr=True, highlight=False, soft_wrap=True)
    console.print("[yellow]warning:[/yellow] ", markup=True, end="")
    console.print(text, markup=False)


def user_error_exit(error: UserError) -> typer.Exit:
    """Print a user error on stderr and return the Exit (status 2) for the caller to raise.

    Args:
        error: the error; its text is printed as is (no markup read from it).
    """
    console = Console(stderr=True, highlight=False, soft_wrap=True)
    console.print("[red]error:[/red] ", markup=True, end="")
    console.print(str(error), markup=False)
    return typer.Exit(EXIT_USER_ERROR)
