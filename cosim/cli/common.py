"""What every `cosim` command shares: the exit status of a user error and how it is shown.

A user error (`cosim.errors.UserError`) prints one line on stderr, "error: ...",
without a traceback, and ends the command with status 2.
"""

from __future__ import annotations

import typer
from rich.console import Console

from cosim.errors import UserError

EXIT_USER_ERROR = 2


def user_error_exit(error: UserError) -> typer.Exit:
    """Print a user error on stderr and return the Exit (status 2) for the caller to raise.

    Args:
        error: the error; its text is printed as is (no markup read from it).
    """
    console = Console(stderr=True, highlight=False, soft_wrap=True)
    console.print("[red]error:[/red] ", markup=True, end="")
    console.print(str(error), markup=False)
    return typer.Exit(EXIT_USER_ERROR)
