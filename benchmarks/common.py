"""Timing helpers shared by the benchmarks in this folder.

The machine is shared with other jobs, so a benchmark that compares two ways
of doing the same work runs them in alternating repetitions (the same load
weighs on both) and reports the minimum (the run least disturbed) next to
the median. Each case is a callable that does its own set-up, times only the
part that matters, and returns seconds per unit of work.
"""

from __future__ import annotations

import statistics
from collections.abc import Callable, Mapping


def interleaved(cases: Mapping[str, Callable[[], float]], repeats: int) -> dict[str, list[float]]:
    """Run every case once per repetition, in turn, `repeats` times.

    Args:
        cases: label -> callable returning one sample (e.g. seconds per step).
        repeats: number of rounds (>= 1).
    Returns:
        label -> the samples in the order taken.
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    samples: dict[str, list[float]] = {label: [] for label in cases}
    for _ in range(repeats):
        for label, case in cases.items():
            samples[label].append(case())
    return samples


def min_and_median(samples: list[float]) -> tuple[float, float]:
    """(minimum, median) of a non-empty list of samples."""
    if not samples:
        raise ValueError("no samples")
    return min(samples), statistics.median(samples)
