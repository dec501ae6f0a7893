"""Ending a process that is done without the interpreter's teardown.

When a Python process ends, after the atexit callbacks, the interpreter frees
every module and every object it still holds. With numpy, fmpy, Zenoh or
matplotlib loaded that takes a while: about 0.2 s in `cosim run`'s master and
0.4 s in the process that draws a run's figure, on a 2-vCPU VM, time the user
waits for the prompt and that frees nothing the kernel would not free at
exit anyway.

`skip_teardown()` registers an atexit callback; atexit runs callbacks last
registered first, so one registered before any other runs after all of them,
and the interpreter has joined every non-daemon thread before it runs any. The
callback flushes Python's and C's standard streams (an FMU may have written
with printf) and ends the process with `os._exit` and the status given to
`exit_status` (1 until then: a process that dies of an uncaught exception
exits with 1, as Python's own exit does; an uncaught KeyboardInterrupt too, where
Python would end by SIGINT). What the teardown would still do is
calling `__del__` of objects alive at exit; a process that arms this closes
its files and sessions itself before it returns.
"""

from __future__ import annotations

import atexit
import ctypes
import os
import sys

_status = 1
_armed = False


def skip_teardown() -> None:
    """End this process without the teardown, after every atexit callback (once).

    Nothing when a callback is registered already (a sitecustomize, a coverage hook, a
    host script): registered before this one, it would run after it, that is never.
    """
    global _armed
    count = getattr(atexit, "_ncallbacks", None)  # CPython's; without it, assume none
    if not _armed and not (count is not None and count() > 0):
        atexit.register(_end)
        _armed = True


def exit_status(code: int) -> int:
    """Record `code` as the status this process exits with and return it (`sys.exit(exit_status(c))`)."""
    global _status
    _status = code
    return code


def _end() -> None:
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None:
                stream.flush()
        except (OSError, ValueError):  # a closed pipe or stream: nothing more can reach it
            pass
    try:
        ctypes.CDLL(None).fflush(None)  # every C stdio stream
    except Exception:  # noqa: BLE001  no C library to flush (not POSIX): os._exit anyway
        pass
    os._exit(_status)
