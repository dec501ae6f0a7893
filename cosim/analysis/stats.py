"""What the run metrics share: the time-weighted RMS, and the finite check that leaves a metric out."""

from __future__ import annotations

import numpy as np


def rms(t: np.ndarray, v: np.ndarray) -> float:
    """Time-weighted RMS of v(t) by the trapezoid rule (plain RMS when t spans no time).

    Args:
        t: strictly increasing times.
        v: values at those times.
    """
    with np.errstate(over="ignore"):
        value = _rms(t, v)
    if np.isinf(value) and np.isfinite(v).all():
        # v * v overflowed: divide by a power of two first (exact), multiply back after
        scale = 2.0 ** int(np.frexp(np.max(np.abs(v)))[1])
        return scale * _rms(t, v / scale)
    return value


def _rms(t: np.ndarray, v: np.ndarray) -> float:
    if len(v) == 1 or t[-1] == t[0]:
        return float(np.sqrt(np.mean(v * v)))
    return float(np.sqrt(np.trapezoid(v * v, t) / (t[-1] - t[0])))


def finite_or_note(name: str, t: np.ndarray, v: np.ndarray, notes: list[str]) -> bool:
    """True when v is all finite; else add a note naming the first bad tick.

    Args:
        name: the metric (or metrics) the values are for, as the note names them.
        t, v: times and values.
        notes: where the note goes.
    """
    bad = np.flatnonzero(~np.isfinite(v))
    if len(bad) == 0:
        return True
    notes.append(f"{name}: non-finite value {v[bad[0]]!r} at t={t[bad[0]]:.10g} s; left out")
    return False
