"""The metrics of a run that is not a vehicle run: four statistics of every recorded signal.

A run where no component plays a role (cosim.scenario.roles: no vehicle, controller
or planner) gets, for every scalar column of signals.csv, over the ticks from
t0 = first tick + `metrics.skip_s`:

- min(c), max(c): its smallest and largest value;
- rms(c): its time-weighted RMS, as the vehicle metrics' rms_* (trapezoid rule, so it
  does not depend on the tick);
- final(c): its value at the last tick.

A signal with a non-finite value from t0 on gets none of the four, and a note naming
the first bad tick. Nothing is inferred from signal names; a component that records
the plant contract's pose (x, y, psi, vx) is named in a note, as the one to give
`metrics: {vehicle: ...}` for the vehicle metrics.
"""

from __future__ import annotations

import re

import numpy as np

from cosim.analysis.rundata import RunData
from cosim.analysis.stats import finite_or_note, rms

STATISTICS = ("min", "max", "rms", "final")
PLANT_POSE = ("x", "y", "psi", "vx")
_NAME = re.compile(r"^(" + "|".join(STATISTICS) + r")\((.+)\)$")


def statistic_name(statistic: str, signal: str) -> str:
    """The metric name of a statistic of a signal: "max(ball.h)"."""
    return f"{statistic}({signal})"


def parse_statistic_name(name: str) -> tuple[str, str] | None:
    """(statistic, signal) of a generic metric name ("max(ball.h)"), else None."""
    match = _NAME.match(name)
    return None if match is None else (match.group(1), match.group(2))


def signal_statistics(run: RunData, mask: np.ndarray) -> tuple[dict[str, float], list[str]]:
    """The four statistics of every recorded scalar signal, and notes on what was left out.

    Args:
        run: a loaded run folder.
        mask: the ticks from t0 on (at least one).
    """
    values: dict[str, float] = {}
    notes: list[str] = []
    t = run.time[mask]
    for name, column in run.columns.items():
        v = column[mask]
        if not finite_or_note(", ".join(statistic_name(s, name) for s in STATISTICS), t, v, notes):
            continue
        values[statistic_name("min", name)] = float(np.min(v))
        values[statistic_name("max", name)] = float(np.max(v))
        values[statistic_name("rms", name)] = rms(t, v)
        values[statistic_name("final", name)] = float(v[-1])
    return values, notes


def plant_shaped_components(run: RunData) -> list[str]:
    """The components that recorded the plant contract's pose and speed (x, y, psi, vx)."""
    components = dict.fromkeys(name.split(".", 1)[0] for name in run.columns)
    return [c for c in components if all(f"{c}.{s}" in run.columns for s in PLANT_POSE)]


def no_roles_note(run: RunData) -> str:
    """Why the run got the generic metrics, and which component could be its vehicle."""
    note = ("no vehicle, controller or planner (metrics.vehicle/controller/planner, or "
            "components of those names): generic signal statistics instead of vehicle metrics")
    shaped = plant_shaped_components(run)
    if shaped:
        note += (f"; {', '.join(shaped)} records the plant contract's {', '.join(PLANT_POSE)}: "
                 f"`metrics: {{vehicle: {shaped[0]}}}` makes it the vehicle")
    return note
