"""The manifest of a run that ended before tick 0.

Once `cosim run` has announced a run folder, the folder must say what became of
the run even when it never reached tick 0 (a component that rejects its
parameters, a wiring typo, Ctrl-C during start-up): `write_start_failure`
leaves a readable manifest.json with status "failed" and the error, and replaces
a half-written manifest.json.tmp. `locate_parameter_problem` gives a parameter
that a component's constructor rejected its YAML file, line and path.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from cosim.errors import UserError

INTERRUPTED_BEFORE_TICK0 = "interrupted before tick 0"


def start_failure_text(exc: BaseException) -> str:
    """The manifest's error for an exception raised before tick 0.

    Args:
        exc: a UserError or KeyboardInterrupt (anything else is an internal error).
    """
    if isinstance(exc, KeyboardInterrupt):
        return INTERRUPTED_BEFORE_TICK0 + (f" ({exc})" if str(exc) else "")
    if isinstance(exc, UserError):
        return str(exc)
    return f"internal error: {type(exc).__name__}: {exc}"


def write_start_failure(out: Path, scenario: Any, run_id: str, transport: str,
                        error: str, startup: dict[str, Any]) -> None:
    """Write out/manifest.json for a run that failed before tick 0, unless the run
    wrote its own complete manifest already.

    Args:
        out: the run folder (exists).
        scenario: the scenario as it was to run.
        run_id: the run's id.
        transport: "inproc" or "zenoh".
        error: the error text (see start_failure_text).
        startup: the start-up clock's marks (StartupClock.as_dict()).
    """
    from cosim.results.manifest import run_identity
    from cosim.results.recorder import write_json

    manifest_path = out / "manifest.json"
    if _final_status(manifest_path) is not None:
        return
    try:
        write_json(manifest_path, {
            **run_identity(scenario, run_id, transport, "failed", error, "failed_utc"),
            "ticks": 0,
            "sim_time_s": 0.0,
            "time_to_tick0_s": None,
            "startup": startup,
        })
    except UserError:  # the folder cannot be written: the error itself is reported
        pass


def write_pending_manifest(out: Path, scenario: Any, run_id: str, transport: str,
                           startup: dict[str, Any]) -> None:
    """Write out/manifest.json with status "running" before tick 0's own manifest: what a
    supervisor completes if the master dies first (in a component's constructor).

    Args: as `write_start_failure`, without the error.
    """
    from cosim.results.manifest import run_identity
    from cosim.results.recorder import write_json

    write_json(out / "manifest.json", {
        **run_identity(scenario, run_id, transport, "running", None, "started_utc"),
        "ticks": 0,
        "sim_time_s": 0.0,
        "time_to_tick0_s": None,
        "startup": startup,
    })


def _final_status(manifest_path: Path) -> str | None:
    """The status of a finished run's manifest; None if absent, unreadable or "running"."""
    import json

    try:
        status = json.loads(manifest_path.read_text(encoding="utf-8")).get("status")
    except (OSError, ValueError, AttributeError):
        return None
    return None if status == "running" else status


def locate_parameter_problem(scenario: Any, exc: BaseException) -> UserError | None:
    """A component's rejected parameter (cosim.transport.inproc.ParameterProblem) as a
    UserError starting with the parameter's YAML file, line and path, an algebraic loop
    at its connections (`Scenario.locate`); None for any other exception.

    Args:
        scenario: the scenario being run.
        exc: what starting the components raised.
    """
    component, parameter = getattr(exc, "component", None), getattr(exc, "parameter", None)
    if not isinstance(exc, UserError) or parameter is None:
        return scenario.locate(exc)  # an algebraic loop: at its connections
    spec = scenario.components.get(component)
    if spec is None or parameter not in (getattr(spec, "parameters", None) or {}):
        return None
    path, problem = _field_of(("components", component, "parameters", parameter),
                              str(exc.problem))  # type: ignore[attr-defined]
    return UserError(f"{scenario.where(path)}: {problem}")


_FIELD = re.compile(r"((?:\.[A-Za-z_]\w*|\[\d+\])*): (.*)", re.DOTALL)


def _field_of(path: tuple[str | int, ...], problem: str) -> tuple[tuple[str | int, ...], str]:
    """A problem that starts with a field inside the parameter ("road.radius: must be > 0")
    gives that field's path and the rest of the message; otherwise both unchanged."""
    name = str(path[-1])
    match = _FIELD.match(problem, len(name)) if problem.startswith(name) else None
    if match is None:
        return path, problem
    keys = [int(k[1:-1]) if k.startswith("[") else k[1:]
            for k in re.findall(r"\.[A-Za-z_]\w*|\[\d+\]", match.group(1))]
    return path + tuple(keys), match.group(2)
