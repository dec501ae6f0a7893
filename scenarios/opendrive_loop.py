"""Write scenarios/opendrive_loop.xodr: a closed test loop of lines, clothoids and arcs.

    python -m scenarios.opendrive_loop [OUT.xodr]

A stand-in for the Satory track (whose geometry is not public) as an ASAM
OpenDRIVE 1.5 file, written by the `scenariogeneration` package (so the
platform's reader is tested on a file it did not write itself). One road,
id 1, about 2.4 km: two driving lanes in the direction of the reference line
(ids -1, -2) and one the other way (id 1), 3.5 m each. Its successor is
itself: a loop.

The loop is point-symmetric like `controllers.road.builders.satory_standin`:
the turns of one half add up to exactly 180 degrees, the second half is the
same pieces again, so the end meets the start exactly (up to the rounding of
the file's numbers). Each turn is clothoid, arc, clothoid.
"""

from __future__ import annotations

import math
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

from scenariogeneration import xodr

OUT = Path(__file__).with_name("opendrive_loop.xodr")
LANE_WIDTH = 3.5
DATE = "2026-01-01T00:00:00"   # fixed, so the generator's output is the shipped file byte for byte

# One half of the loop: (straight m, radius m, signed angle deg, clothoid length m)
HALF = (
    (250.0, 120.0, 90.0, 35.0),
    (120.0, 250.0, -30.0, 30.0),
    (80.0, 250.0, 30.0, 30.0),
    (150.0, 60.0, 90.0, 25.0),
)


def turn(radius: float, angle_deg: float, clothoid: float) -> list:
    """Clothoid in, arc, clothoid out: `angle_deg` (left positive) at `radius`."""
    k = math.copysign(1.0 / radius, angle_deg)
    arc = radius * math.radians(abs(angle_deg)) - clothoid   # the two clothoids turn one arc length
    return [xodr.Spiral(0.0, k, length=clothoid), xodr.Arc(k, length=arc),
            xodr.Spiral(k, 0.0, length=clothoid)]


def loop_geometry() -> list:
    """The pieces of the whole loop, in order."""
    pieces = []
    for straight, radius, angle, clothoid in HALF * 2:
        pieces.append(xodr.Line(straight))
        pieces.extend(turn(radius, angle, clothoid))
    return pieces


def build() -> xodr.OpenDrive:
    """The OpenDRIVE document of the loop."""
    road = xodr.create_road(loop_geometry(), id=1, left_lanes=1, right_lanes=2,
                            lane_width=LANE_WIDTH)
    road.add_successor(xodr.ElementType.road, 1, xodr.ContactPoint.start)
    road.add_predecessor(xodr.ElementType.road, 1, xodr.ContactPoint.end)
    odr = xodr.OpenDrive("opendrive_loop")
    odr.add_road(road)
    odr.adjust_roads_and_lanes()
    return odr


def main(argv: list[str]) -> None:
    """Write the loop to argv[0] (default: beside this script)."""
    out = Path(argv[0]) if argv else OUT
    root = build().get_element()
    root.find("header").set("date", DATE)
    ET.indent(root, space="  ")
    ET.ElementTree(root).write(out, encoding="utf-8", xml_declaration=True)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1:])
