"""Checks of a scenario that span several fields, and exact tick arithmetic.

The pydantic schema checks each field on its own; these checks relate fields:
names are identifiers and unique across components and sources, periods and
the duration are whole multiples of the tick, FMU files exist (as files), and
the `parameters:` of a shipped class fit its parameter model
(cosim.scenario.known_classes). They run on the raw document and skip whatever
the schema already rejects, so that one load reports the schema's problems and
these together.

Tick arithmetic is exact: a float is taken as the decimal its shortest repr
shows ("0.01" is 1/100), so 20.0 / 0.01 is exactly 2000 ticks.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from fractions import Fraction
from pathlib import Path
from typing import Any

from cosim.resources import builtin_fmu_names
from cosim.scenario.known_classes import parameter_problems
from cosim.scenario.roles import role_problems
from cosim.scenario.shipped import not_a_file

#: Built-in plant FMUs, built by the platform on demand: discovered from the folders of fmus/.
BUILTIN_FMUS: tuple[str, ...] = builtin_fmu_names()

IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
TIME_RESOLUTION = 1e-3  # the coarsest float64 spacing of the run's times, in ticks

Loc = tuple[str | int, ...]


def exact(value: float) -> Fraction:
    """The decimal value a float shows, as an exact fraction (0.1 -> 1/10)."""
    return Fraction(repr(float(value)))


def whole_ticks(value: float, tick: float) -> int | None:
    """How many ticks make `value` seconds, or None if it is not a whole number of ticks.

    Args:
        value: a duration in seconds (> 0).
        tick: the master tick in seconds (> 0).
    """
    ratio = exact(value) / exact(tick)
    return ratio.numerator if ratio.denominator == 1 else None


def _finite(value: Any) -> float | None:
    """A finite number from raw data (of any sign), or None (the schema reports the rest)."""
    if isinstance(value, bool):
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


def _number(value: Any) -> float | None:
    """A positive finite number from raw data, or None (the schema reports the rest)."""
    number = _finite(value)
    return number if number is not None and number > 0 else None


def semantic_problems(data: Any, base_dir: Path | None,
                      also_set: Callable[[Loc], str] | None = None) -> list[tuple[Loc, str]]:
    """Every cross-field problem of a raw scenario document.

    Args:
        data: the document as loaded from YAML (after overrides).
        base_dir: folder against which relative FMU paths resolve; None skips
            the file existence check.
        also_set: path -> " (tick set by --set tick=20)" when an override set that
            field, else "" (`LineMap.also_set`): a problem located at one field
            (a duration, a period) names the override of the tick it is measured in.
    Returns:
        (document path, message) pairs.
    """
    if not isinstance(data, dict):
        return []
    problems: list[tuple[Loc, str]] = []
    tick = _number(data.get("tick"))
    tick_note = also_set(("tick",)) if also_set is not None else ""
    duration = _number(data.get("duration"))
    if tick is not None and duration is not None and whole_ticks(duration, tick) is None:
        problems.append((("duration",), f"duration {duration:g} s is not a whole number "
                                        f"of ticks of {tick:g} s{tick_note}"))
    start = _finite(data.get("start_time"))
    if tick is not None and duration is not None and start is not None:
        problems += _time_resolution_problems(start, duration, tick, tick_note)
    seen: dict[str, str] = {}
    for section in ("components", "sources"):
        entries = data.get(section)
        if not isinstance(entries, dict):
            continue
        for name, spec in entries.items():
            problems += _name_problems(section, name, seen)
            if isinstance(spec, dict):
                problems += _period_problems((section, str(name)), spec, tick, tick_note)
                problems += _fmu_problems((section, str(name)), spec, base_dir)
                if section == "components":
                    problems += parameter_problems((section, str(name)), spec)
    return problems + role_problems(data)


def _time_resolution_problems(start: float, duration: float, tick: float,
                              tick_note: str) -> list[tuple[Loc, str]]:
    """The run's times t0 + k tick must be told apart: float64's spacing at the largest
    time at most a thousandth of a tick (a Unix time in seconds with 10 ms ticks passes;
    start_time 1e17 s gave every row the same time)."""
    latest = abs(start) + abs(duration)
    if not math.isfinite(latest) or math.ulp(latest) > TIME_RESOLUTION * tick:
        return [(("start_time",), f"start_time {start:g} s is too far from 0 for ticks of "
                                  f"{tick:g} s{tick_note}: times near {latest:g} s are only "
                                  f"resolved to {math.ulp(latest):g} s (at most "
                                  f"{TIME_RESOLUTION:g} of a tick); use a start time nearer 0")]
    return []


def _name_problems(section: str, name: Any, seen: dict[str, str]) -> list[tuple[Loc, str]]:
    """A component or source name must be an identifier, unique over both sections."""
    loc: Loc = (section, str(name))
    if not isinstance(name, str) or not IDENTIFIER.match(name):
        return [(loc, f"name {name!r} is not an identifier (ASCII letters, digits, _; "
                      "not starting with a digit)")]
    if name in seen:
        return [(loc, f"name {name!r} is already used in {seen[name]}")]
    seen[name] = section
    return []


def _period_problems(loc: Loc, spec: dict, tick: float | None,
                     tick_note: str = "") -> list[tuple[Loc, str]]:
    """A period must be a whole multiple (>= 1) of the tick."""
    period = _number(spec.get("period"))
    if period is None or tick is None:
        return []
    if whole_ticks(period, tick) is None:
        return [(loc + ("period",), f"period {period:g} s is not a whole multiple "
                                    f"of tick {tick:g} s{tick_note}")]
    return []


def _fmu_problems(loc: Loc, spec: dict, base_dir: Path | None) -> list[tuple[Loc, str]]:
    """An FMU is a built-in name or a path to an existing .fmu file."""
    fmu = spec.get("fmu")
    if not isinstance(fmu, str) or not fmu or fmu in BUILTIN_FMUS:
        return []
    if not fmu.lower().endswith(".fmu"):
        return [(loc + ("fmu",), f"{fmu!r} is neither a built-in FMU "
                                 f"({', '.join(BUILTIN_FMUS)}) nor a path ending in .fmu")]
    if base_dir is None:
        return []
    path = Path(fmu) if Path(fmu).is_absolute() else base_dir / fmu
    if path.is_file():
        return []
    kind = not_a_file(path)
    if kind is not None:
        return [(loc + ("fmu",), f"FMU {fmu!r} {kind}, not an .fmu file "
                                 f"(looked at {path})")]
    return [(loc + ("fmu",), f"FMU file {fmu!r} not found (looked at {path})")]
