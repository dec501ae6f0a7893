"""Signal sources: components that produce a disturbance signal `value`.

A scenario's `sources:` entries become these components (see
cosim.scenario.sources for the YAML fields, which are these classes' keyword
arguments). All are pure functions of time, except `Table(over="distance")`,
which integrates the distance travelled by the point on its inputs x, y.
Times are absolute simulation times (the scenario's start_time included).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping, Sequence
from typing import Any

from cosim.component import Component, ComponentError, Port, Value


def _finite(name: str, value: Any) -> float:
    """A parameter as a finite float, or a ComponentError naming it."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ComponentError(f"parameter {name!r} must be a number (got {value!r})") from None
    if not math.isfinite(number):
        raise ComponentError(f"parameter {name!r} must be finite (got {value!r})")
    return number


class _Source(Component):
    """A source with one output `value` carrying the given unit."""

    def __init__(self, unit: str = ""):
        self.outputs = (Port("value", unit=unit, description=type(self).__doc__ or ""),)


class Constant(_Source):
    """value(t) = value."""

    def __init__(self, value: float, unit: str = ""):
        """Args: value: the constant output; unit: unit of `value`."""
        super().__init__(unit)
        self.value = _finite("value", value)

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Return the constant."""
        return {"value": self.value}


class Step(_Source):
    """value(t) = initial for t < at, final from t = at on."""

    def __init__(self, initial: float, final: float, at: float, unit: str = ""):
        """Args: initial, final: values before and after; at: switch time (s); unit."""
        super().__init__(unit)
        self.initial = _finite("initial", initial)
        self.final = _finite("final", final)
        self.at = _finite("at", at)

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Return initial or final by the time."""
        return {"value": self.final if t >= self.at else self.initial}


class Ramp(_Source):
    """start until t_start, linear from start to end over [t_start, t_end], then end."""

    def __init__(self, start: float, end: float, t_start: float, t_end: float, unit: str = ""):
        """Args: start, end: values; t_start < t_end: ramp times (s); unit."""
        super().__init__(unit)
        self.start, self.end = _finite("start", start), _finite("end", end)
        self.t_start, self.t_end = _finite("t_start", t_start), _finite("t_end", t_end)
        if not self.t_end > self.t_start:
            raise ComponentError(f"t_end ({t_end}) must be after t_start ({t_start})")

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Return the ramp value at t."""
        if t <= self.t_start:
            return {"value": self.start}
        if t >= self.t_end:
            return {"value": self.end}
        fraction = (t - self.t_start) / (self.t_end - self.t_start)
        return {"value": self.start + (self.end - self.start) * fraction}


class Gust(_Source):
    """1-cos gust: base + amplitude/2 (1 - cos(2 pi (t - start) / duration)) on
    [start, start + duration], base elsewhere; peaks at base + amplitude mid-gust."""

    def __init__(self, amplitude: float, start: float, duration: float, base: float = 0.0,
                 unit: str = ""):
        """Args: amplitude: peak over base; start: onset (s); duration (s, > 0); base; unit."""
        super().__init__(unit)
        self.amplitude = _finite("amplitude", amplitude)
        self.start = _finite("start", start)
        self.duration = _finite("duration", duration)
        self.base = _finite("base", base)
        if not self.duration > 0:
            raise ComponentError(f"duration must be > 0 (got {duration})")

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Return the gust value at t."""
        phase = (t - self.start) / self.duration
        if not 0.0 <= phase <= 1.0:
            return {"value": self.base}
        return {"value": self.base + 0.5 * self.amplitude * (1.0 - math.cos(2.0 * math.pi * phase))}


class Table(_Source):
    """A value tabulated over time, or over the distance travelled by the point (x, y).

    Outside the table the first or last value holds. Over distance, the
    distance is the sum of the straight segments between the successive
    positions the source sees (0 at initialization).
    """

    def __init__(self, points: Sequence[Sequence[float]], over: str = "time",
                 interpolation: str = "linear", unit: str = ""):
        """Args:
            points: [[abscissa, value], ...], abscissas strictly increasing.
            over: "time" (s) or "distance" (m; adds inputs x, y in m).
            interpolation: "linear" or "previous" (last point at or before).
            unit: unit of `value`.
        """
        super().__init__(unit)
        if over not in ("time", "distance"):
            raise ComponentError(f"over must be 'time' or 'distance' (got {over!r})")
        if interpolation not in ("linear", "previous"):
            raise ComponentError(
                f"interpolation must be 'linear' or 'previous' (got {interpolation!r})")
        self.abscissas, self.values = _table_points(points)
        self.over, self.interpolation = over, interpolation
        if over == "distance":
            self.inputs = (Port("x", unit="m", description="world x of the tracked point"),
                           Port("y", unit="m", description="world y of the tracked point"))
        self.distance = 0.0
        self._last: tuple[float, float] | None = None

    def initialize(self, t0: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Start the travelled distance at 0 from the initial position."""
        self.distance = 0.0
        self._last = None
        return self.step(t0, inputs)

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Return the table value at the current time or travelled distance."""
        if self.over == "time":
            return {"value": self.lookup(t)}
        x, y = float(inputs["x"]), float(inputs["y"])
        if self._last is not None:
            self.distance += math.hypot(x - self._last[0], y - self._last[1])
        self._last = (x, y)
        return {"value": self.lookup(self.distance)}

    def lookup(self, abscissa: float) -> float:
        """The table's value at an abscissa (time or distance)."""
        xs, vs = self.abscissas, self.values
        i = bisect.bisect_right(xs, abscissa)  # xs[i-1] <= abscissa < xs[i]
        if i == 0:
            return vs[0]
        if i == len(xs) or self.interpolation == "previous":
            return vs[i - 1]
        fraction = (abscissa - xs[i - 1]) / (xs[i] - xs[i - 1])
        return vs[i - 1] + (vs[i] - vs[i - 1]) * fraction


def _table_points(points: Sequence[Sequence[float]]) -> tuple[list[float], list[float]]:
    """Split and check table points: pairs of finite numbers, abscissas increasing."""
    if isinstance(points, (str, bytes)) or not isinstance(points, Sequence) or not points:
        raise ComponentError(f"points must be a non-empty list of [abscissa, value] (got {points!r})")
    xs: list[float] = []
    vs: list[float] = []
    for i, point in enumerate(points):
        if isinstance(point, (str, bytes)) or not isinstance(point, Sequence) or len(point) != 2:
            raise ComponentError(f"points[{i}] must be [abscissa, value] (got {point!r})")
        x, v = _finite(f"points[{i}][0]", point[0]), _finite(f"points[{i}][1]", point[1])
        if xs and not x > xs[-1]:
            raise ComponentError(f"points[{i}] abscissa {x} is not greater than the previous "
                                 f"one {xs[-1]}: abscissas must strictly increase")
        xs.append(x)
        vs.append(v)
    return xs, vs
