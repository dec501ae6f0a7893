"""The trajectory window the planner sends and the controllers read.

A window is a fixed number of points along the planned path, each with world
position, heading, curvature, arc length (from the window's first point),
reference speed and reference acceleration. It travels as one float64 array
port per field, named `<prefix>_<field>`: the recommended trajectory uses the
prefix "ref", the alternative one "alt". Points are ordered along the path and
strictly increasing in arc length; the first point lies at or behind the
vehicle's projection so the controller can project its CG and its preview
point on the window.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from cosim.component import Port

WINDOW_POINTS = 64
FIELDS: tuple[tuple[str, str, str], ...] = (
    ("x", "m", "world x of the path point"),
    ("y", "m", "world y of the path point"),
    ("psi", "rad", "path heading (unwrapped)"),
    ("kappa", "1/m", "path curvature, positive turning left"),
    ("s", "m", "arc length from the window's first point"),
    ("v", "m/s", "reference speed"),
    ("a", "m/s2", "reference longitudinal acceleration"),
)


@dataclass(frozen=True)
class TrajectoryWindow:
    """One window of planned points (all arrays of equal length)."""

    x: np.ndarray
    y: np.ndarray
    psi: np.ndarray
    kappa: np.ndarray
    s: np.ndarray
    v: np.ndarray
    a: np.ndarray

    def to_signals(self, prefix: str) -> dict[str, np.ndarray]:
        """Port values `<prefix>_<field>` for this window."""
        return {f"{prefix}_{name}": np.ascontiguousarray(getattr(self, name), dtype=float)
                for name, _, _ in FIELDS}

    @classmethod
    def from_signals(cls, signals: Mapping[str, np.ndarray], prefix: str) -> "TrajectoryWindow":
        """Rebuild a window from the port values `<prefix>_<field>`."""
        return cls(**{name: np.asarray(signals[f"{prefix}_{name}"], dtype=float)
                      for name, _, _ in FIELDS})


def window_ports(prefix: str, points: int = WINDOW_POINTS, role: str = "") -> tuple[Port, ...]:
    """Port declarations of one trajectory window (`role` goes into descriptions)."""
    label = f"{role} trajectory: " if role else "trajectory: "
    return tuple(Port(f"{prefix}_{name}", size=points, unit=unit, description=label + text)
                 for name, unit, text in FIELDS)
