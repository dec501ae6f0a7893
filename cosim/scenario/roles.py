"""Which component is the vehicle, the controller and the planner, for the run metrics and figures.

The scenario's `metrics:` section names them (`metrics: {vehicle: car, controller: ctl,
planner: plan}`); a role left out falls back to the component of the role's own name
(`vehicle`, `controller`, `planner`) when the run has one, else the role is unfilled.
Nothing is guessed from signal names: a run that fills no role is not a vehicle run,
and gets the generic signal statistics and figure (cosim.analysis.generic).

`MetricRoles` is the schema of the three fields (the base of the `metrics:` model);
`role_problems` is the load-time check that a role names a component of the scenario;
`resolve_roles` turns a scenario document (as a run's manifest stores it) into the
role -> component map the analysis reads.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, model_serializer

from cosim.errors import did_you_mean

#: the roles, each also the name of its default component
ROLES = ("vehicle", "controller", "planner")

_ROLE_HELP = {
    "vehicle": "the plant whose pose, speeds and friction the vehicle metrics and figures read",
    "controller": "the path-tracking controller whose errors (yc, yL, psiL, ex) and commands "
                  "(delta) are read",
    "planner": "the trajectory planner whose windows, road, gap and lead input are read",
}


def _role_field(role: str) -> Any:
    return Field(None, min_length=1, description=(
        f"The component that is the {role}: {_ROLE_HELP[role]}. Default: the component "
        f"named '{role}' when the scenario has one; without any role the run gets the "
        "generic signal statistics and figure."))


class MetricRoles(BaseModel):
    """The components that the vehicle metrics and figures read (see cosim.scenario.roles)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)
    vehicle: str | None = _role_field("vehicle")
    controller: str | None = _role_field("controller")
    planner: str | None = _role_field("planner")

    @model_serializer(mode="wrap")
    def _without_unset_roles(self, handler: Any) -> Any:
        dumped = handler(self)
        if isinstance(dumped, dict):  # dumps (manifests) of scenarios without roles stay as they were
            for role in ROLES:
                if dumped.get(role, "") is None:
                    del dumped[role]
        return dumped


def role_problems(data: Mapping[str, Any]) -> list[tuple[tuple[str | int, ...], str]]:
    """A role that names no component of the scenario, as (document path, message) pairs.

    Args:
        data: the raw scenario document (after `system:` merge and overrides).
    """
    metrics, components = data.get("metrics"), data.get("components")
    if not isinstance(metrics, Mapping) or not isinstance(components, Mapping):
        return []  # the schema reports a section of the wrong type
    problems: list[tuple[tuple[str | int, ...], str]] = []
    for role in ROLES:
        name = metrics.get(role)
        if isinstance(name, str) and name and name not in components:
            known = [str(c) for c in components]
            problems.append((("metrics", role), f"{name!r} is not a component of this scenario "
                                                f"(its components: {', '.join(known)})"
                                                + did_you_mean(name, known)))
    return problems


def resolve_roles(scenario: Mapping[str, Any], present: Iterable[str] = ()) -> dict[str, str | None]:
    """role -> the component that plays it, or None when no component does.

    Args:
        scenario: a scenario document (a run manifest's "scenario").
        present: further component names the run is known to have (those that
            recorded a signal or appear in a connection), for run folders whose
            manifest lists no components.
    """
    metrics = scenario.get("metrics")
    metrics = metrics if isinstance(metrics, Mapping) else {}
    known = set(present)
    for section in ("components", "sources"):
        entries = scenario.get(section)
        if isinstance(entries, Mapping):
            known.update(str(name) for name in entries)
    roles: dict[str, str | None] = {}
    for role in ROLES:
        named = metrics.get(role)
        roles[role] = named if isinstance(named, str) and named else (role if role in known else None)
    return roles
