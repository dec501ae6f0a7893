"""Where each component of a run goes: its `host:` in the scenario, or `--place`.

    placement = resolve_placement(scenario, ["controller=w1", "planner=w2"])
    # {"controller": "w1", "planner": "w2"}: components not listed run locally

The command line wins over the YAML; `--place NAME=local` brings a component
back to the master's host. Python components (controllers, planner, sources)
and FMU components can be placed on workers; an FMU then travels to its worker
(see cosim.fmu.remote), which must be started with --allow-fmu.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from cosim.errors import UserError
from cosim.transport.zenoh.config import check_key_chunk

LOCAL = "local"


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
    """Component name -> worker name for every component not run locally.

    Args:
        scenario: a validated cosim.scenario.loader.Scenario (its `host:` fields).
        place: `--place COMPONENT=WORKER` values (they override `host:`).
    Raises:
        UserError naming an unknown component (with the known ones) or a bad worker name.
    """
    fmus = dict(scenario.fmu_components())
    pythons = dict(scenario.python_components())
    known = {**fmus, **pythons}
    wanted = {name: spec.host for name, spec in known.items()}
    for name, worker in parse_place(place).items():
        if name not in known:
            raise UserError(f"--place {name}={worker}: no component {name!r} in scenario "
                            f"{scenario.name!r} (components: {', '.join(sorted(known))})")
        wanted[name] = worker
    placement = {name: host for name, host in wanted.items() if host != LOCAL}
    for name, host in placement.items():
        try:
            check_key_chunk(host, "worker name")
        except ValueError as exc:
            raise UserError(f"component {name!r}: host: {exc}") from None
    return placement
