"""Zenoh's runtime on one thread in the processes of a run.

By default Zenoh runs each process's I/O on five pools of threads (app, acc, tx,
rx, net): a message put by one thread is written to the socket by another and
read on the far side by a third, which hands it to the receiving thread; every
hand-over is a wake-up. In a lockstep run one message is in flight at a time, so
nothing runs in parallel there: with every pool handed over to a single app
thread (Zenoh's `ZENOH_RUNTIME` setting), a message wakes fewer threads.

Measured on the 2-vCPU machine of DESIGN.md (`benchmarks/bench_zenoh.py`, which
also runs the default pools in the same run): a raw round trip between two Python
processes 178 -> 100 us where the OS puts them, 43-58 -> 31 us on one CPU; a
trivial component's lockstep tick 190-195 -> 112 us and 79-81 -> 43-50 us; the
Satory loop under two or four busy processes no slower (benchmarks/issue14_plan.md,
"Session 8").

Zenoh reads the setting once per process, when its first session opens. The
master's session is opened inside `first_session` and every component process
inherits `child_environment`; a `ZENOH_RUNTIME` the user set is left alone
(`ZENOH_RUNTIME='()'` gives Zenoh's default pools).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, MutableMapping

ENV = "ZENOH_RUNTIME"
ONE_THREAD = ("(app: (worker_threads: 1), acc: (handover: app), tx: (handover: app), "
              "rx: (handover: app), net: (handover: app))")
DEFAULT_POOLS = "()"  # Zenoh's own defaults, for a comparison


def child_environment(env: MutableMapping[str, str]) -> MutableMapping[str, str]:
    """`env` (a child process's environment) with one runtime thread unless it says otherwise."""
    env.setdefault(ENV, ONE_THREAD)
    return env


@contextlib.contextmanager
def first_session() -> Iterator[None]:
    """Around the `zenoh.open` of this process's first session: one runtime thread.

    A `ZENOH_RUNTIME` already in the environment is used as it is. Once Zenoh's runtime
    has started in this process (an earlier session), the setting no longer changes it.
    The environment is restored afterwards, so later child processes see the user's.
    """
    if ENV in os.environ:
        yield
        return
    os.environ[ENV] = ONE_THREAD
    try:
        yield
    finally:
        os.environ.pop(ENV, None)
