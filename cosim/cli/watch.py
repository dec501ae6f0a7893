"""`cosim watch`: print a running simulation's signals live, from another process.

    cosim watch runs/lane_change-20261122T003000Z     # run id, endpoint, credential from it
    cosim watch RUN_ID --connect tcp/127.0.0.1:PORT --credential FOLDER/live.credential
    cosim watch RUN_ID --connect tls/10.0.0.1:7447 --deploy master.yaml   # a TLS run
    cosim watch '*' --connect ENDPOINT --deploy FILE  # every run reachable there

`cosim run` prints its run id and live endpoint before tick 0 and writes them
into manifest.json under "live"; the run's credential is in the owner-only
file `live.credential` of the run folder (every session of a run
authenticates: without it nothing can be seen). The watcher prints one compact line per
`--every` ticks, e.g.

    tick 1200  t=12  vehicle.x=115.2  vehicle.y=3.41  controller.delta=0.0123

and ends when the run ends (or after `--count` lines, or on Ctrl-C). The run
publishes its signals only while somebody watches, so watching is free when
nobody does.
"""

from __future__ import annotations

import fnmatch
import json
import socket
import sys
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, Optional

import typer

from cosim.cli.common import check_endpoint, user_error_exit
from cosim.errors import UserError

MANIFEST_WAIT_S = 10.0  # a run folder named just after `cosim run` printed it
CONNECT_TIMEOUT_S = 3.0  # a live endpoint that does not accept TCP by then is not there


def select_names(names: Iterable[str], patterns: Sequence[str]) -> list[str]:
    """The names matching any of the glob patterns, in the run's order.

    Args:
        names: the run's signal names ("component.signal").
        patterns: shell-style globs (comma-separated lists allowed); none: every name.
    """
    globs = [g.strip() for p in patterns for g in p.split(",") if g.strip()]
    if not globs:
        return list(names)
    return [n for n in names if any(fnmatch.fnmatchcase(n, g) for g in globs)]


def format_line(tick: int, t: float, values: dict[str, float], names: Sequence[str],
                run_id: str | None = None) -> str:
    """One compact line: [run id] tick, time and name=value for the selected names.

    Args:
        tick: the master tick.
        t: its simulation time, s.
        values: every signal value of that tick by name.
        names: which of them to print, in this order.
        run_id: prefix the line with it (when watching every run).
    """
    fields = [f"tick {tick}", f"t={t:.6g}"] + [f"{n}={values[n]:.6g}" for n in names]
    return "  ".join(([f"[{run_id}]"] if run_id else []) + fields)


def resolve_target(target: str, connect: str | None,
                   wait_s: float = 0.0) -> tuple[str, str]:
    """(run id, endpoint) from a run id, "*" or a run folder, and `--connect`.

    Args:
        target: a run id, "*" (every run) or a run folder holding manifest.json.
        connect: the endpoint given on the command line, or None.
        wait_s: how long to wait for the folder's manifest to appear (a run
            writes it just before tick 0, after printing its folder).
    Raises:
        UserError when the endpoint is unknown or the folder's run has ended.
    """
    folder = Path(target)
    if folder.is_dir():
        manifest_path = folder / "manifest.json"
        end = time.monotonic() + wait_s
        while not manifest_path.exists() and time.monotonic() < end:
            time.sleep(0.05)
        try:
            manifest = json.loads(manifest_path.read_text())
        except (OSError, ValueError) as exc:
            raise UserError(f"{manifest_path}: cannot read the run's manifest: {exc}") from None
        live = manifest.get("live") or {}
        if not live.get("run_id") or not live.get("endpoint"):
            raise UserError(f"{manifest_path}: the run has no live view (field 'live'; "
                            f"only --transport zenoh runs publish their signals)")
        if manifest.get("status") != "running":
            raise UserError(f"{manifest_path}: run {live['run_id']} has already ended "
                            f"(status {manifest.get('status')!r})")
        return str(live["run_id"]), str(connect or live["endpoint"])
    if target != "*":
        from cosim.transport.zenoh.config import check_key_chunk

        try:
            check_key_chunk(target, "run id")
        except ValueError as exc:
            raise UserError(f"{exc}; or give a run folder") from None
    if connect is None:
        raise UserError(f"watching run {target!r} needs --connect ENDPOINT (`cosim run` prints "
                        f"it before tick 0; it is also under 'live' in the run's manifest.json)")
    return target, connect


def check_reachable(endpoint: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """Raise UserError when nothing accepts a TCP connection at a tcp/ or tls/ endpoint.

    A Zenoh peer whose endpoint is dead opens anyway and waits in silence, so
    watching an ended run (or a mistyped port) would print nothing forever.

    Args:
        endpoint: e.g. "tcp/127.0.0.1:7447"; other protocols are not checked.
        timeout_s: how long to wait for the connection.
    """
    proto, _, address = endpoint.partition("/")
    host, _, port = address.rpartition(":")
    if proto not in ("tcp", "tls") or not host or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s).close()
    except OSError as exc:
        reason = exc.strerror or f"no answer within {timeout_s:g} s"
        raise UserError(f"nothing answers at {endpoint} ({reason}): the run has ended, "
                        f"or the endpoint is not the one `cosim run` printed") from None


def session_for(target: str, endpoint: str, deploy: Path | None,
                credential: Path | None) -> tuple[Any, Any]:
    """(credential, Zenoh config) of the watching session: a deployment file's
    session (TLS, shared credential), else `--credential`, else the run folder's
    `live.credential`; (None, None) when none of them is there.

    Args:
        target: the RUN argument (a run folder, a run id or "*").
        endpoint: the master's live endpoint.
        deploy: `--deploy FILE`, or None.
        credential: `--credential FILE`, or None.
    """
    from cosim.transport.zenoh.auth import LIVE_CREDENTIAL_FILE, read_credential_file

    if deploy is not None:
        from cosim.distributed.deploy import load_deploy, zenoh_config

        return None, zenoh_config(load_deploy(deploy), "peer", [], [endpoint])
    if credential is None and (Path(target) / LIVE_CREDENTIAL_FILE).is_file():
        credential = Path(target) / LIVE_CREDENTIAL_FILE
    return (read_credential_file(credential) if credential is not None else None), None


def watch_lines(run_id: str, endpoint: str, patterns: Sequence[str], every: int,
                count: int, session: tuple[Any, Any] = (None, None)) -> Iterable[str]:
    """The lines `cosim watch` prints, until the run ends or `count` lines (0: no limit).

    Args:
        run_id: the run to watch, or "*".
        endpoint: the master's live endpoint.
        patterns: --signals globs.
        every: print one tick in `every` (ticks whose number is a multiple of it).
        count: stop after this many lines; 0 for no limit.
        session: (credential, Zenoh config) from `session_for`.
    Raises:
        UserError when no signal matches the patterns.
    """
    from cosim.transport.zenoh.live import watch_runs

    selected: dict[tuple[str, int], list[str]] = {}  # (run, number of names) -> names
    printed = 0
    for run, tick, t, values in watch_runs(run_id, endpoint, *session):
        if tick % every:
            continue
        key = (run, len(values))
        if key not in selected:
            selected[key] = select_names(values, patterns)
            if not selected[key]:
                raise UserError(f"run {run}: no signal matches --signals "
                                f"{', '.join(patterns)}; its signals: {', '.join(values)}")
        yield format_line(tick, t, values, selected[key], run if run_id == "*" else None)
        printed += 1
        if count and printed >= count:
            return


def watch(
    target: str = typer.Argument("*", metavar="RUN",
                                 help="run id, '*' for every run, or a run folder"),
    connect: Optional[str] = typer.Option(None, "--connect",
                                          help="the run's live endpoint, e.g. tcp/127.0.0.1:PORT"),
    signals: list[str] = typer.Option([], "--signals", help="glob of signal names, repeatable"),
    every: int = typer.Option(10, "--every", help="print one line every N ticks"),
    count: int = typer.Option(0, "--count", help="stop after N lines (0: until the run ends)"),
    deploy: Optional[Path] = typer.Option(None, "--deploy",
                                          help="deployment settings YAML (TLS, shared credential)"),
    credential: Optional[Path] = typer.Option(
        None, "--credential", help="the run's credential file (default: the run folder's "
                                   "live.credential)"),
) -> None:
    """Print a running simulation's signals live (one line per N ticks)."""
    try:
        if every < 1 or count < 0:
            raise UserError(f"--every must be >= 1 and --count >= 0, got {every} and {count}")
        if connect is not None:
            check_endpoint(connect, "--connect")
        run_id, endpoint = resolve_target(target, connect, MANIFEST_WAIT_S)
        session = session_for(target, endpoint, deploy, credential)
        check_reachable(endpoint)
        what = "every run" if run_id == "*" else f"run {run_id}"
        print(f"watching {what} at {endpoint} (Ctrl-C to stop)", file=sys.stderr,
              flush=True)
        printed = 0
        for line in watch_lines(run_id, endpoint, signals, every, count, session):
            print(line, flush=True)
            printed += 1
        if not count or printed < count:
            print(f"run {run_id} ended", file=sys.stderr, flush=True)
    except (UserError, TimeoutError, ConnectionError) as error:
        raise user_error_exit(UserError(str(error))) from None
    except KeyboardInterrupt:
        raise typer.Exit(0) from None


def register(app: typer.Typer) -> None:
    """Add the `watch` command to the `cosim` Typer app.

    Args:
        app: the main app of `cosim.cli.app`.
    """
    app.command("watch")(watch)
