"""What every `cosim` command shares: the exit status of a user error and how it is shown,
and the syntax check of endpoint options.

A user error (`cosim.errors.UserError`) prints one line on stderr, "error: ...",
without a traceback, and ends the command with status 2.
"""

from __future__ import annotations

import re

import typer

from cosim.errors import UserError

EXIT_USER_ERROR = 2
STRICT_HELP = ("a plant-contract output the plant lacks, or an input left unconnected, "
               "is an error (default: a warning)")


def print_warning(text: str) -> None:
    """Print one warning line on stderr ("warning: ...").

    Args:
        text: the warning; printed as is (no markup read from it).
    """
    from rich.console import Console  # rich loads in 0.05 s: not before a run needs it

    console = Console(stderr=True, highlight=False, soft_wrap=True)
    console.print("[yellow]warning:[/yellow] ", markup=True, end="")
    console.print(text, markup=False)


def user_error_exit(error: UserError) -> typer.Exit:
    """Print a user error on stderr and return the Exit (status 2) for the caller to raise.

    Args:
        error: the error; its text is printed as is (no markup read from it).
    """
    from rich.console import Console

    console = Console(stderr=True, highlight=False, soft_wrap=True)
    console.print("[red]error:[/red] ", markup=True, end="")
    console.print(str(error), markup=False)
    return typer.Exit(EXIT_USER_ERROR)


_ENDPOINT = re.compile(r"^([a-z][a-z0-9+-]*)/([^?#]+)(\?[^#]*)?(#.*)?$")
_HOST_PORT = ("tcp", "tls", "udp", "quic", "ws")


def check_endpoint(endpoint: str, option: str) -> str:
    """A Zenoh endpoint option that reads PROTOCOL/ADDRESS (host:port for tcp, tls, udp, ...).

    Zenoh reports a malformed endpoint late and in its own words (or as a failure
    to listen), so the command line is checked first.

    Args:
        endpoint: the option's value, e.g. "tcp/127.0.0.1:7447".
        option: the option's name for the message, e.g. "--connect".
    Raises:
        UserError naming the option and the expected form.
    """
    example = "e.g. tcp/127.0.0.1:7447"
    match = _ENDPOINT.match(endpoint)
    if match is None:
        raise UserError(f"{option} {endpoint!r}: an endpoint reads PROTOCOL/ADDRESS, {example}")
    proto, address = match.group(1), match.group(2)
    if proto in _HOST_PORT:
        host, sep, port = address.rpartition(":")
        if not sep or not host or not port.isdigit() or int(port) > 65535:
            raise UserError(f"{option} {endpoint!r}: a {proto} endpoint reads "
                            f"{proto}/HOST:PORT (port 0..65535), {example}")
    return endpoint
