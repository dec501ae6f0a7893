"""Small helpers on signal values shared by the master and the Zenoh codec.

`picker` builds the C-speed getter both use to read several signals at once;
`value_problem` says why a value is not a finite scalar or float array of a
given size (the text of a component-failure message); `lane_result_problem`
why a `step_values` result is not a sequence of the outputs' count. No heavy import at
module level: numpy loads only when a value is actually diagnosed.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from operator import itemgetter
from typing import Any


def picker(keys: Sequence[Any]) -> Callable[[Any], tuple]:
    """A C-speed getter of several keys as a tuple (itemgetter, also for 0 and 1 keys).

    Args:
        keys: the keys (signal names, or list indices) to read, in the order wanted.

    Returns:
        A function of a container returning the tuple of its values at `keys`.
    """
    if not keys:
        return lambda _: ()
    if len(keys) == 1:
        only = keys[0]
        return lambda container: (container[only],)
    return itemgetter(*keys)


def value_problem(value: Any, size: int) -> str:
    """Why `value` is not a finite float (size 1) or a finite float array of `size`.

    Args:
        value: what a component gave for one signal.
        size: the signal's declared size (1: a scalar).

    Returns:
        The reason, worded to follow "output 'name' ...", or "" if the value is fine.
    """
    import numpy as np  # only failure paths diagnose values; keep this module light

    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return f"is not a number: {value!r}"
    if size == 1 and array.ndim != 0:
        return f"has shape {array.shape}, expected a scalar"
    if size > 1 and array.shape != (size,):
        return f"has shape {array.shape}, expected ({size},)"
    flat = array.reshape(-1)
    bad = np.flatnonzero(~np.isfinite(flat))
    if bad.size:
        where = "" if size == 1 else f" at [{bad[0]}]"
        return f"is non-finite{where}: {float(flat[bad[0]])!r}"
    return ""


def lane_result_problem(result: Any, count: int) -> str:
    """Why `result`, returned by a component's `step_values`, is not a sequence of `count`
    values, or "" (the same words in-process and in a component process)."""
    try:
        got = len(result)
    except TypeError:
        return f"step_values returned {type(result).__name__}, expected a sequence of {count} floats"
    if got != count:
        return f"step_values returned {got} values for {count} outputs"
    return ""
