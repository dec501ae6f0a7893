"""Errors, number fields and size limits of the YAML specs of roads, paths, speeds
and manoeuvres.

Every spec reader of the controllers package raises `SpecError` with the
field's location in the message, so the scenario loader can show it as is.
Numbers are strict (a bool or a string is not a number), and lengths are
bounded (`MAX_LENGTH`), since the planner samples a road and its route
finely: a road of 1e12 m must be refused, not allocated.
"""

from __future__ import annotations

import numpy as np


MAX_LENGTH = 100_000.0  # m: a road, a path or a route (the planner samples it every 0.25 m)
MAX_REACH = 1_000.0     # m: preview, window and launch distances
MAX_LANES = 16


class SpecError(ValueError):
    """A user error in a road, path, speed or manoeuvre description."""


def spec_number(value, where: str, positive: bool = False, at_most: float | None = None) -> float:
    """A finite float from a spec field, or a SpecError naming the field.

    Args:
        value: the field's value as read from YAML (a bool or a string is refused).
        where: the field's location, for the message.
        positive: also require value > 0.
        at_most: also require |value| <= at_most.
    """
    if isinstance(value, (bool, str, bytes)):
        raise SpecError(f"{where}: expected a number, got {value!r}")
    try:
        out = float(value)
    except (TypeError, ValueError, OverflowError):
        raise SpecError(f"{where}: expected a number, got {value!r}") from None
    if not np.isfinite(out) or (positive and out <= 0):
        raise SpecError(f"{where}: expected a {'positive ' if positive else ''}finite number, got {value!r}")
    if at_most is not None and abs(out) > at_most:
        raise SpecError(f"{where}: must be at most {at_most:g} in size, got {value!r}")
    return out
