"""What the run metrics share: the time-weighted RMS, and the finite checks that leave a metric out."""

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
        # v * v overflowed: divide by a power of two first (exact), multiply back after;
        # ldexp, since the power itself can be beyond a float (2.0 ** 1024 for |v| ~ 1.7e308)
        exponent = int(np.frexp(np.max(np.abs(v)))[1])
        with np.errstate(over="ignore"):
            return float(np.ldexp(_rms(t, np.ldexp(v, -exponent)), exponent))
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


def drop_non_finite(values: dict[str, float], notes: list[str]) -> None:
    """Remove the metrics whose value is not a finite number, each with a note naming it.

    Finite signals can still give an infinite metric: a difference or a rate of values
    near the largest float (1.8e308) overflows.

    Args:
        values: metric name -> value; changed in place.
        notes: where the notes go.
    """
    for name, value in list(values.items()):
        if not np.isfinite(value):
            del values[name]
            notes.append(f"{name}: {value!r}, not a finite number (the computation "
                         "overflowed: signal values near the largest float); left out")
