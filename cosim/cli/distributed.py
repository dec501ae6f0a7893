"""The distributed-run commands of the `cosim` CLI: worker, workers, router.

`register(app)` adds them to the Typer app of `cosim.cli.app`; the endpoint
options mean the same everywhere and add to those of a `--deploy` file.
"""

from __future__ import annotations

import faulthandler
import signal
import sys
from pathlib import Path
from typing import Any, Optional

import typer

from cosim.cli.common import check_endpoint, user_error_exit
from cosim.errors import UserError


def load_settings(deploy: Optional[Path], listen: list[str], connect: list[str]) -> Any:
    """Deployment settings from `--deploy FILE` plus `--listen/--connect` (command line first).

    Args:
        deploy: the deployment YAML, or None.
        listen / connect: endpoints from the command line.
    """
    from cosim.distributed.deploy import load_deploy, merge_endpoints

    for option, values in (("--listen", listen), ("--connect", connect)):
        for endpoint in values:
            check_endpoint(endpoint, option)
    return merge_endpoints(load_deploy(deploy) if deploy else None, listen, connect)


def worker(
    name: str = typer.Option(..., "--name", help="worker name, used in --place and host:"),
    listen: list[str] = typer.Option([], "--listen", help="endpoint to accept masters on"),
    connect: list[str] = typer.Option([], "--connect", help="endpoint to join (a router)"),
    allow: list[str] = typer.Option([], "--allow",
                                    help="allowed module prefix (default: controllers., "
                                         "cosim.sources), repeatable"),
    allow_fmu: bool = typer.Option(False, "--allow-fmu",
                                   help="run plant FMUs that masters send (native code)"),
    deploy: Optional[Path] = typer.Option(None, "--deploy", help="deployment settings YAML "
                                          "(TLS client certificates or an auth: credential)"),
    insecure: bool = typer.Option(False, "--insecure",
                                  help="start components for masters it cannot authenticate"),
    max_components: int = typer.Option(16, "--max-components",
                                       help="most component processes hosted at once"),
    orphan_timeout: float = typer.Option(30.0, "--orphan-timeout",
                                         help="seconds a component waits for its run's master"),
) -> None:
    """Serve as a worker: start components on this host for masters that ask."""
    from cosim.distributed import protocol as worker_protocol
    from cosim.distributed.worker import Worker

    try:
        settings = load_settings(deploy, listen, connect)
        agent = Worker(name, settings, allow or worker_protocol.DEFAULT_ALLOW, allow_fmu,
                       insecure=insecure, max_components=max_components,
                       orphan_timeout_s=orphan_timeout)
    except (UserError, ValueError) as error:
        raise user_error_exit(UserError(str(error))) from None
    _print_security(agent)
    # `kill -USR1 <pid>` prints where a stuck worker is (a long-running service must be debuggable).
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    print(f"worker {agent.name!r} on {agent.host}: listen {settings.listen or '-'}, "
          f"connect {settings.connect or '-'}, allow {', '.join(agent.allow)}"
          f"{', FMUs' if agent.allow_fmu else ''}", flush=True)
    try:
        agent.serve(on_ready=lambda: print(f"worker {agent.name!r} ready", flush=True))
    except UserError as error:
        raise user_error_exit(error) from None


def _print_security(agent: Any) -> None:
    """Say, at start, how the worker decides whom it serves."""
    if agent.authenticated:
        return
    if agent.insecure:
        print(f"warning: worker {agent.name!r} runs with --insecure: any process that can "
              f"reach its endpoints can start components on this host", file=sys.stderr,
              flush=True)
    else:
        print(f"worker {agent.name!r}: no credential and no TLS client certificates in "
              f"--deploy, so it refuses every start request (see docs/security.md)",
              file=sys.stderr, flush=True)


def workers(
    connect: list[str] = typer.Option([], "--connect", help="endpoint of a worker or router"),
    deploy: Optional[Path] = typer.Option(None, "--deploy", help="deployment settings YAML"),
    timeout: float = typer.Option(1.0, "--timeout", help="seconds to look for workers"),
) -> None:
    """List the workers that can be reached."""
    from rich.console import Console
    from rich.table import Table

    from cosim.distributed.client import list_workers

    try:
        found = list_workers(load_settings(deploy, [], connect), timeout)
    except UserError as error:
        raise user_error_exit(error) from None
    table = Table(title=f"{len(found)} worker(s)")
    for column in ("name", "host", "pid", "allowed modules", "running"):
        table.add_column(column)
    for info in found:
        table.add_row(str(info["name"]), str(info.get("host")), str(info.get("pid")),
                      ", ".join(info.get("allow", [])), str(info.get("running")))
    Console(highlight=False).print(table)


def router(
    listen: list[str] = typer.Option([], "--listen", help="endpoint to listen on"),
    connect: list[str] = typer.Option([], "--connect", help="another router to join"),
    deploy: Optional[Path] = typer.Option(None, "--deploy", help="deployment settings YAML"),
) -> None:
    """Run a Zenoh router (for networks where peers cannot reach each other)."""
    from cosim.distributed.router import run_router

    try:
        settings = load_settings(deploy, listen or ([] if deploy else ["tcp/0.0.0.0:7447"]),
                                 connect)
        run_router(settings, on_ready=lambda: print(
            f"router listening on {', '.join(settings.listen)}", flush=True))
    except UserError as error:
        raise user_error_exit(error) from None


def register(app: typer.Typer) -> None:
    """Add the worker, workers and router commands to `app`.

    Args:
        app: the `cosim` Typer application.
    """
    app.command("worker")(worker)
    app.command("workers")(workers)
    app.command("router")(router)
