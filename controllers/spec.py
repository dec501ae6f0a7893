"""Errors and number fields of the YAML specs of roads, paths, speeds and manoeuvres.

Every spec reader of the controllers package raises `SpecError` with the
field's location in the message, so the scenario loader can show it as is.
"""

from __future__ import annotations

import numpy as np


class SpecError(ValueError):
    """A user error in a road, path, speed or manoeuvre description."""


def spec_number(value, where: str, positive: bool = False) -> float:
    """A finite float from a spec field, or a SpecError naming the field.

    Args:
        value: the field's value as read from YAML.
        where: the field's location, for the message.
        positive: also require value > 0.
    """
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise SpecError(f"{where}: expected a number, got {value!r}") from None
    if not np.isfinite(out) or (positive and out <= 0):
        raise SpecError(f"{where}: expected a {'positive ' if positive else ''}finite number, got {value!r}")
    return out
