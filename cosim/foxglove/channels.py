"""The Foxglove channels of a run, shared by the MCAP writer and the live server.

Topics (log time = simulation time in nanoseconds, so Foxglove's timeline is
the run's time):
- `/tf` (foxglove.FrameTransform): the pose of each vehicle, frame `world`
  (x east, y north, z up; DESIGN.md's world frame) to the frame named after the
  component, from its x, y, psi and phi (roll) signals;
- `/scene/road` (foxglove.SceneUpdate, once): the road's lane edges and dividers
  as line strips in `world`;
- `/scene/body` (foxglove.SceneUpdate, once): a box of the vehicle's size
  locked to its frame, so the 3D panel shows the car moving;
- `/scene/<component>.<window>` (foxglove.SceneUpdate): each planned trajectory
  window (array signals `<window>_x`, `<window>_y`) as a line strip, replaced at
  every update;
- `/signals/<component>` (JSON with a JSON schema): every scalar signal of the
  component, one message per tick, plottable as `/signals/vehicle.vx`.

A `Layout` says which columns feed which channel; `RunChannels` creates the
channels in a `foxglove.Context` (one per output: a file and a server never
share channels) and logs to them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import foxglove
from foxglove import channels as fc
from foxglove import messages as fm

WORLD = "world"
POSE_SIGNALS = ("x", "y", "psi")
ROAD_COLOUR = fm.Color(r=0.6, g=0.6, b=0.6, a=1.0)
BODY_COLOUR = fm.Color(r=0.15, g=0.45, b=0.9, a=0.8)
WINDOW_COLOURS = (fm.Color(r=0.1, g=0.8, b=0.2, a=1.0), fm.Color(r=1.0, g=0.6, b=0.1, a=1.0))


@dataclass(frozen=True)
class Layout:
    """Which signals go where.

    Attributes:
        scalars: every scalar column "component.signal", in record order.
        vehicles: components with x, y and psi outputs (their pose goes to /tf).
        windows: (component.window, x array name, y array name) of each trajectory window.
    """

    scalars: tuple[str, ...]
    vehicles: tuple[str, ...]
    windows: tuple[tuple[str, str, str], ...]

    @classmethod
    def of(cls, scalars: Sequence[str], arrays: Sequence[str]) -> "Layout":
        """The layout of these scalar columns and array signal names."""
        names = set(scalars)
        components = dict.fromkeys(n.split(".", 1)[0] for n in scalars)
        vehicles = tuple(c for c in components if all(f"{c}.{s}" in names for s in POSE_SIGNALS))
        windows = tuple((a[:-2], a, a[:-2] + "_y") for a in arrays
                        if a.endswith("_x") and a[:-2] + "_y" in arrays)
        return cls(tuple(scalars), vehicles, windows)

    def groups(self) -> dict[str, list[tuple[int, str]]]:
        """component -> [(column index, signal name)] of its scalar signals."""
        out: dict[str, list[tuple[int, str]]] = {}
        for i, name in enumerate(self.scalars):
            comp, signal = name.split(".", 1)
            out.setdefault(comp, []).append((i, signal))
        return out


def nanoseconds(t: float) -> int:
    """A simulation time as MCAP/Foxglove nanoseconds (times before 0 are not representable)."""
    return max(0, round(t * 1e9))


def _stamp(ns: int) -> fm.Timestamp:
    return fm.Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)


def _line(xs: Sequence[float], ys: Sequence[float], colour: fm.Color, thickness: float,
          dashed: bool = False) -> fm.LinePrimitive:
    points = [fm.Point3(x=float(x), y=float(y)) for x, y in zip(xs, ys) if math.isfinite(x) and math.isfinite(y)]
    kind = fm.LinePrimitiveLineType.LineList if dashed else fm.LinePrimitiveLineType.LineStrip
    if dashed:   # a line list joins points pairwise: every other step is drawn
        points = points[: len(points) // 2 * 2]
    return fm.LinePrimitive(type=kind, thickness=thickness, points=points, color=colour,
                            pose=fm.Pose(position=fm.Vector3(), orientation=fm.Quaternion(w=1.0)))


class RunChannels:
    """The channels of one output (an MCAP file or a server), created in `context`."""

    def __init__(self, context: foxglove.Context, layout: Layout):
        self.layout = layout
        self.tf = fc.FrameTransformChannel("/tf", context=context)
        self.road = fc.SceneUpdateChannel("/scene/road", context=context)
        self.body = fc.SceneUpdateChannel("/scene/body", context=context)
        self.windows = {name: fc.SceneUpdateChannel(f"/scene/{name}", context=context)
                        for name, _, _ in layout.windows}
        self.groups = layout.groups()
        self.signals = {}
        for comp, members in self.groups.items():
            schema = {"type": "object", "title": f"cosim.signals.{comp}",
                      "properties": {"t": {"type": "number"},
                                     **{s: {"type": "number"} for _, s in members}}}
            self.signals[comp] = foxglove.Channel(f"/signals/{comp}", schema=schema, context=context)
        self._pose = {v: tuple(layout.scalars.index(f"{v}.{s}") for s in POSE_SIGNALS)
                      + ((layout.scalars.index(f"{v}.phi"),) if f"{v}.phi" in layout.scalars else ())
                      for v in layout.vehicles}

    def log_static(self, lines: Sequence, body: tuple[float, float, float], ns: int) -> None:
        """The road (LaneLine objects of cosim.analysis.road) and the vehicle boxes, once."""
        prims = [_line(l.x, l.y, ROAD_COLOUR, 0.15 if l.edge else 0.08, dashed=not l.edge) for l in lines]
        self.road.log(fm.SceneUpdate(entities=[fm.SceneEntity(
            timestamp=_stamp(ns), frame_id=WORLD, id="road", lines=prims)]), log_time=ns)
        length, width, front = body
        entities = [fm.SceneEntity(timestamp=_stamp(ns), frame_id=v, id=f"{v}.body", frame_locked=True,
                                   cubes=[fm.CubePrimitive(
                                       pose=fm.Pose(position=fm.Vector3(x=front - 0.5 * length, z=0.7),
                                                    orientation=fm.Quaternion(w=1.0)),
                                       size=fm.Vector3(x=length, y=width, z=1.4), color=BODY_COLOUR)])
                    for v in self.layout.vehicles]
        self.body.log(fm.SceneUpdate(entities=entities), log_time=ns)

    def log_tick(self, t: float, row: Sequence[float]) -> None:
        """One tick's scalars (in `layout.scalars` order): poses and signal messages."""
        ns = nanoseconds(t)
        for vehicle, idx in self._pose.items():
            psi, phi = row[idx[2]], (row[idx[3]] if len(idx) > 3 else 0.0)
            # yaw psi about z, then roll phi about the body x axis: q = q_z(psi) q_x(phi)
            cy, sy, cr, sr = math.cos(psi / 2), math.sin(psi / 2), math.cos(phi / 2), math.sin(phi / 2)
            self.tf.log(fm.FrameTransform(
                timestamp=_stamp(ns), parent_frame_id=WORLD, child_frame_id=vehicle,
                translation=fm.Vector3(x=row[idx[0]], y=row[idx[1]]),
                rotation=fm.Quaternion(x=cy * sr, y=sy * sr, z=sy * cr, w=cy * cr)), log_time=ns)
        for comp, members in self.groups.items():
            message = {"t": t}
            for i, signal in members:
                message[signal] = row[i]
            self.signals[comp].log(message, log_time=ns)

    def log_window(self, k: int, t: float, xs: Sequence[float], ys: Sequence[float]) -> None:
        """Trajectory window number k of `layout.windows` as a line strip in `world`."""
        ns = nanoseconds(t)
        name = self.layout.windows[k][0]
        colour = WINDOW_COLOURS[min(k, len(WINDOW_COLOURS) - 1)]
        self.windows[name].log(fm.SceneUpdate(entities=[fm.SceneEntity(
            timestamp=_stamp(ns), frame_id=WORLD, id=name, lines=[_line(xs, ys, colour, 0.12)])]),
            log_time=ns)
