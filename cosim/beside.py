"""Threads that work beside a run's lockstep chain, not in it.

A component may start a thread for work the lockstep does not wait for (a
controller loading its compiled code while it steps: controllers.jit). Its name,
in Python and in the OS, starts with BESIDE_THREAD_PREFIX, so that a host that
pins the chain's threads to one CPU (cosim.engine.one_cpu) gives it the other
CPUs instead. Standard library only: the run path reads the prefix before it
loads numpy. Components reach this through cosim.component.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from cosim import startup_gc

BESIDE_THREAD_PREFIX = "beside-"


def start_beside(target: Callable[[], None], name: str, loads: bool = False) -> threading.Thread:
    """Start a daemon thread that runs `target()`, named BESIDE_THREAD_PREFIX + `name` in
    Python and, on Linux, in the OS (its first 15 bytes: what /proc shows). The OS name
    is set when this returns.

    Args:
        loads: `target` makes objects that live as long as the process (compiled code):
            Python's collector is held back until it returns, then those are frozen
            (cosim.startup_gc.hold), so that collections neither go over them while they
            are made, holding the interpreter the stepping thread needs, nor after.
    """
    named = threading.Event()
    held = loads and startup_gc.hold()   # here, not in the thread: before the host's resume

    def run() -> None:
        try:
            with open("/proc/thread-self/comm", "w") as comm:
                comm.write(threading.current_thread().name[:15])
        except OSError:  # not Linux
            pass
        named.set()
        try:
            target()
        finally:
            if held:
                startup_gc.let_go()

    thread = threading.Thread(target=run, name=BESIDE_THREAD_PREFIX + name, daemon=True)
    try:
        thread.start()
    except BaseException:  # no thread to be had (RuntimeError): nothing is held for it
        if held:
            startup_gc.let_go()
        raise
    named.wait()
    return thread
