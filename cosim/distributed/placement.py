"""Where each component of a run goes: its `host:` in the scenario, or `--place`.

    placement = resolve_placement(scenario, ["controller=w1", "planner=w2"])
    # {"controller": "w1", "planner": "w2"}: components not listed run locally

The command line wins over the YAML; `--place NAME=local` brings a component
back to the master's host, and `--place NAME=inproc` puts a Python component
into the master's own process (over Zenoh, where each otherwise gets a process
of its own: one round trip less per step; `in_master_process`). Python
components (controllers, planner, sources) and FMU components can be placed on
workers; an FMU then travels to its worker
(see cosim.fmu.remote), which must be started with --allow-fmu.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from cosim.errors import UserError
from cosim.transport.zenoh.config import check_key_chunk

LOCAL = "local"
INPROC = "inproc"  # a Python component in the master's process
RESERVED_HOSTS = {LOCAL: "the master's host", INPROC: "the master's own process"}   # never worker names


def parse_place(items: Sequence[str]) -> dict[str, str]:
    """Parse `--place COMPONENT=WORKER` options.

    Args:
        items: the option values, e.g. ["controller=w1"].
    Raises:
        UserError for an item that is not NAME=WORKER or names a component twice.
    """
    placed: dict[str, str] = {}
    for item in items:
        name, sep, worker = item.partition("=")
        name, worker = name.strip(), worker.strip()
        if not sep or not name or not worker:
            raise UserError(f"--place {item!r}: expected COMPONENT=WORKER")
        if name in placed:
            raise UserError(f"--place {item!r}: component {name!r} placed twice")
        try:
            check_key_chunk(worker, "worker name")
        except ValueError as exc:
            raise UserError(f"--place {item!r}: {exc}") from None
        placed[name] = worker
    return placed


def resolve_placement(scenario: Any, place: Sequence[str] = ()) -> dict[str, str]:
    """Component name -> worker name for every component not run on the master's host.

    Args:
        scenario: a validated cosim.scenario.loader.Scenario (its `host:` fields).
        place: `--place COMPONENT=WORKER` values (they override `host:`).
    Raises:
        UserError naming an unknown component (with the known ones), a bad worker
        name, or an FMU placed `inproc`.
    """
    wanted = _wanted(scenario, place)
    placement = {name: host for name, host in wanted.items() if host not in (LOCAL, INPROC)}
    for name, host in placement.items():
        try:
            check_key_chunk(host, "worker name")
        except ValueError as exc:
            raise UserError(f"component {name!r}: host: {exc}") from None
    return placement


def in_master_process(scenario: Any, place: Sequence[str] = ()) -> set[str]:
    """The Python components placed `inproc`: hosted in the master's own process.

    Args and errors as resolve_placement.
    """
    return {name for name, host in _wanted(scenario, place).items() if host == INPROC}


def _wanted(scenario: Any, place: Sequence[str]) -> dict[str, str]:
    """Component name -> its `host:`, overridden by `--place` (UserError for an unknown name or an FMU inproc)."""
    fmus = dict(scenario.fmu_components())
    pythons = dict(scenario.python_components())
    known = {**fmus, **pythons}
    wanted = {name: spec.host for name, spec in known.items()}
    for name, worker in parse_place(place).items():
        if name not in known:
            raise UserError(f"--place {name}={worker}: no component {name!r} in scenario "
                            f"{scenario.name!r} (components: {', '.join(sorted(known))})")
        wanted[name] = worker
    for name in fmus:
        if wanted[name] == INPROC:
            raise UserError(f"component {name!r}: host: {INPROC!r} puts a Python component in the "
                            f"master's process; {name!r} is an FMU (leave it {LOCAL!r} or name a worker)")
    return wanted
