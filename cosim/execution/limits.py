"""Bounds on the size of a run, checked before tick 0.

A typo such as `tick: 1e-9` or `duration: 1e9` gives a run that never ends
and fills the disk. A run is refused when it has more ticks than a limit
(`DEFAULT_MAX_TICKS`, changed with `cosim run --max-ticks N`), or when the CSV
it would write, estimated from its ticks and recorded signals, is larger
than `MAX_CSV_BYTES`; `--allow-large` lifts both limits.

`check_ticks` needs only the scenario (it runs before the run folder is
made); `check_recorded_size` needs the signal layout (once the components'
ports are known: in `cosim validate`, and in `cosim run` before tick 0).
"""

from __future__ import annotations

import math

from dataclasses import dataclass
from typing import Any

from cosim.errors import UserError

DEFAULT_MAX_TICKS = 10**8
MAX_CSV_BYTES = 10 * 10**9
BYTES_PER_VALUE = 20  # the repr of a float64 and its comma, about

ADVICE = "raise the limit with --max-ticks N, or pass --allow-large"


@dataclass(frozen=True)
class RunLimits:
    """How large a run may be.

    Attributes:
        max_ticks: most master ticks of one run.
        allow_large: no limit at all (ticks nor CSV size).
    """

    max_ticks: int = DEFAULT_MAX_TICKS
    allow_large: bool = False

    def __post_init__(self) -> None:
        if isinstance(self.max_ticks, bool) or not isinstance(self.max_ticks, int) \
                or self.max_ticks < 1:
            raise UserError(f"--max-ticks must be an integer >= 1, got {self.max_ticks!r}")


def check_ticks(scenario: Any, limits: RunLimits) -> int:
    """The run's tick count; a UserError when it is above the limit.

    Args:
        scenario: a validated `cosim.scenario.loader.Scenario`.
        limits: the bounds of this run.
    """
    ticks = scenario.total_ticks
    if not limits.allow_large and ticks > limits.max_ticks:
        raise UserError(f"{scenario.where(('duration',), ('tick',))}: the run would have {ticks:.3g} "
                        f"ticks (duration {scenario.duration:g} s / tick {scenario.tick:g} s), "
                        f"more than the limit of {limits.max_ticks:.3g}: {ADVICE}")
    return ticks


def estimated_csv_bytes(scenario: Any, layout: Any, periods: dict[str, int]) -> int:
    """About how many bytes of CSV the run writes (signals.csv and arrays/).

    Args:
        scenario: the scenario (its tick count and `record` selection).
        layout: the master's `cosim.engine.signals.Layout`.
        periods: component -> period in ticks (array tables have a row per step).
    """
    every = scenario.record.every
    ticks = scenario.total_ticks // every + 2  # ticks 0, N, 2N, ... and the last
    scalars = sum(1 for name, _ in layout.scalar_columns() if scenario.record.selects(name))
    total = ticks * (1 + scalars)
    for component, signal, _, size in layout.array_signals():
        if scenario.record.selects(f"{component}.{signal}"):
            period = max(periods.get(component, 1), 1)
            kept_ticks = math.lcm(period, every)  # an array keeps its rows at multiples of both
            total += (scenario.total_ticks // kept_ticks + 2) * (1 + size)
    return total * BYTES_PER_VALUE


def check_formats(scenario: Any) -> None:
    """A UserError (before the run folder) when `record.format` asks for Parquet without pyarrow.

    Args:
        scenario: a validated scenario.
    """
    if "parquet" in scenario.record.format:
        from cosim.results.parquet import check_parquet_available

        check_parquet_available(scenario.where(("record", "format")))


def check_recorded_size(scenario: Any, layout: Any, periods: dict[str, int],
                        limits: RunLimits) -> None:
    """A UserError when the run would write more than MAX_CSV_BYTES of CSV.

    Args:
        scenario, layout, periods: as for `estimated_csv_bytes`.
        limits: the bounds of this run.
    """
    if limits.allow_large:
        return
    size = estimated_csv_bytes(scenario, layout, periods)
    if size > MAX_CSV_BYTES:
        raise UserError(f"{scenario.where(('record',))}: the run would write about "
                        f"{size / 1e9:.3g} GB of CSV ({scenario.total_ticks:.3g} ticks), more "
                        f"than {MAX_CSV_BYTES / 1e9:g} GB: record fewer signals "
                        "(record: exclude), or pass --allow-large")
