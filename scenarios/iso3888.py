"""ISO 3888-2 obstacle-avoidance lane layout as a function of the vehicle width.

The standard (ISO 3888-2:2011, severe lane change, obstacle avoidance) fixes
the section lengths and makes the widths functions of the vehicle width W:

    section 1  entry lane         12.0 m   width 1.1 W + 0.25
    section 2  lane change        13.5 m
    section 3  offset lane        11.0 m   width W + 1,  offset 1 m to the left
    section 4  lane change        12.5 m
    section 5  exit lane          12.0 m   width min(1.3 W + 0.25, 3)

Total 61 m. The offset is the gap between the left edge of section 1 and the
right edge of section 3; sections 1 and 5 share their right edge. Lanes are
marked by cones on both edges; here a cone stands at both ends of a section
and then every `spacing` metres at most (the standard's cone count varies by
edition, and a cone is a point for the cone-hit metric). Coordinates: the
entry starts at x = x0 on a road heading east, the right edge of section 1
at y = -(1.1 W + 0.25) / 2 so the entry lane is centred on y = 0.

`python -m scenarios.iso3888 [W] [x0]` prints the cones and lane-change
offsets that scenarios/iso3888_2.yaml uses (a test holds the file to it).
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

SECTION_LENGTHS = (12.0, 13.5, 11.0, 12.5, 12.0)
OFFSET = 1.0  # m, lateral gap between section 1's left edge and section 3's right edge


@dataclass(frozen=True)
class Lane:
    """One coned section: x extent and right/left edges (y, left positive)."""

    x_start: float
    x_end: float
    right: float
    left: float

    @property
    def centre(self) -> float:
        """Lateral position of the lane centre."""
        return 0.5 * (self.right + self.left)


def section_widths(vehicle_width: float) -> tuple[float, float, float]:
    """Widths of sections 1, 3 and 5 for a vehicle of width `vehicle_width` (m).

    Args:
        vehicle_width: the vehicle's overall width W, m (> 0).
    Raises:
        ValueError: W not a positive finite number.
    """
    if not (math.isfinite(vehicle_width) and vehicle_width > 0.0):
        raise ValueError(f"vehicle width must be a positive number of metres, got {vehicle_width!r}")
    return (1.1 * vehicle_width + 0.25, vehicle_width + 1.0,
            min(1.3 * vehicle_width + 0.25, 3.0))


def lanes(vehicle_width: float, x0: float = 0.0) -> tuple[Lane, Lane, Lane]:
    """The three coned lanes (sections 1, 3, 5).

    Args:
        vehicle_width: W, m.
        x0: x where section 1 starts, m.
    """
    w1, w3, w5 = section_widths(vehicle_width)
    starts = [x0]
    for length in SECTION_LENGTHS:
        starts.append(starts[-1] + length)
    right1 = -0.5 * w1
    entry = Lane(starts[0], starts[1], right1, right1 + w1)
    offset_lane = Lane(starts[2], starts[3], entry.left + OFFSET, entry.left + OFFSET + w3)
    exit_lane = Lane(starts[4], starts[5], right1, right1 + w5)
    return entry, offset_lane, exit_lane


def cones(vehicle_width: float, x0: float = 0.0, spacing: float = 3.0) -> list[list[float]]:
    """Cone positions [[x, y], ...] along both edges of the three lanes.

    Args:
        vehicle_width: W, m.
        x0: x where section 1 starts, m.
        spacing: largest distance between two cones of an edge, m.
    """
    result = []
    for lane in lanes(vehicle_width, x0):
        count = math.ceil((lane.x_end - lane.x_start) / spacing - 1e-9)
        xs = [lane.x_start + i * (lane.x_end - lane.x_start) / count for i in range(count + 1)]
        for y in (lane.right, lane.left):
            result += [[round(x, 4), round(y, 4)] for x in xs]
    return result


def main(argv: list[str]) -> int:
    """Print the layout for W (default 1.8 m) and x0 (default 100 m)."""
    width = float(argv[0]) if argv else 1.8
    x0 = float(argv[1]) if len(argv) > 1 else 100.0
    for i, lane in zip((1, 3, 5), lanes(width, x0)):
        print(f"section {i}: x {lane.x_start:g}..{lane.x_end:g} m, y {lane.right:.4g}..{lane.left:.4g} m, "
              f"centre {lane.centre:.4g} m")
    print("cones:", cones(width, x0))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
