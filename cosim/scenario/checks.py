"""Checks of a scenario that span several fields, and exact tick arithmetic.

The pydantic schema checks each field on its own; these checks relate fields:
names are identifiers and unique across components and sources, periods and
the duration are whole multiples of the tick, FMU files exist, and the
`parameters:` of a shipped class fit its parameter model (cosim.scenario.known_classes). They run on
the raw document and skip whatever the schema already rejects, so that one
load reports the schema's problems and these together.

Tick arithmetic is exact: a float is taken as the decimal its shortest repr
shows ("0.01" is 1/100), so 20.0 / 0.01 is exactly 2000 ticks.
"""

from __future__ import annotations

import math
import re
from fractions import Fraction
from pathlib import Path
from typing import Any

from cosim.resources import builtin_fmu_names
from cosim.scenario.known_classes import parameter_problems
from cosim.scenario.roles import role_problems

#: Built-in plant FMUs, built by the platform on demand: discovered from the folders of fmus/.
BUILTIN_FMUS: tuple[str, ...] = builtin_fmu_names()

IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")

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


def _number(value: Any) -> float | None:
    """A positive finite number from raw data, or None (the schema reports the rest)."""
    if isinstance(value, bool):
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) and number > 0 else None


def semantic_problems(data: Any, base_dir: Path | None) -> list[tuple[Loc, str]]:
    """Every cross-field problem of a raw scenario document.

    Args:
        data: the document as loaded from YAML (after overrides).
        base_dir: folder against which relative FMU paths resolve; None skips
            the file existence check.
    Returns:
        (document path, message) pairs.
    """
    if not isinstance(data, dict):
        return []
    problems: list[tuple[Loc, str]] = []
    tick = _number(data.get("tick"))
    duration = _number(data.get("duration"))
    if tick is not None and duration is not None and whole_ticks(duration, tick) is None:
        problems.append((("duration",), f"duration {duration:g} s is not a whole number "
                                        f"of ticks of {tick:g} s"))
    seen: dict[str, str] = {}
    for section in ("components", "sources"):
        entries = data.get(section)
        if not isinstance(entries, dict):
            continue
        for name, spec in entries.items():
            problems += _name_problems(section, name, seen)
            if isinstance(spec, dict):
                problems += _period_problems((section, str(name)), spec, tick)
                problems += _fmu_problems((section, str(name)), spec, base_dir)
                if section == "components":
                    problems += parameter_problems((section, str(name)), spec)
    return problems + role_problems(data)


def _name_problems(section: str, name: Any, seen: dict[str, str]) -> list[tuple[Loc, str]]:
    """A component or source name must be an identifier, unique over both sections."""
    loc: Loc = (section, str(name))
    if not isinstance(name, str) or not IDENTIFIER.match(name):
        return [(loc, f"name {name!r} is not an identifier (letters, digits, _; "
                      "not starting with a digit)")]
    if name in seen:
        return [(loc, f"name {name!r} is already used in {seen[name]}")]
    seen[name] = section
    return []


def _period_problems(loc: Loc, spec: dict, tick: float | None) -> list[tuple[Loc, str]]:
    """A period must be a whole multiple (>= 1) of the tick."""
    period = _number(spec.get("period"))
    if period is None or tick is None:
        return []
    if whole_ticks(period, tick) is None:
        return [(loc + ("period",), f"period {period:g} s is not a whole multiple "
                                    f"of tick {tick:g} s")]
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
    if not path.is_file():
        return [(loc + ("fmu",), f"FMU file {fmu!r} not found (looked at {path})")]
    return []
