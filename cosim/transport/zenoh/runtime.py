"""Zenoh's runtime on one thread in the processes of a run.

By default Zenoh runs each process's I/O on five pools of threads (app, acc, tx,
rx, net): a message put by one thread is written to the socket by another and
read on the far side by a third, which hands it to the receiving thread; every
hand-over is a wake-up. In a lockstep run one message is in flight at a time, so
nothing runs in parallel there: with every pool handed over to a single app
thread (Zenoh's `ZENOH_RUNTIME` setting), a message wakes fewer threads.

Measured on the 2-vCPU machine of DESIGN.md (benchmarks/issue14_plan.md, "Session 8";
`benchmarks/bench_zenoh.py` measures both runtimes in alternating child processes):
a trivial component's lockstep tick about 1.5x faster in both placements (OS-placed
p99 worse); `cosim run satory_nominal` 7-12 % faster on a quiet machine, up to 20 %
slower with a busy process on each CPU and up to 40 % with two; with
`--lockstep-cpu off` faster, quiet and under load.

Zenoh reads the setting once per process, when its first session opens: the
choice holds for every later session of the process that hosts the master (a
user's own included). That process opens its first session inside
`first_session`; every local component process inherits `child_environment`.
A `ZENOH_RUNTIME` the user set is left alone (`ZENOH_RUNTIME='()'` gives Zenoh's
default pools).

Runs with workers or deployment settings (`cosim.distributed`) keep the default
pools in the master, its local components and every worker's children, unless the
master's process chose one thread for an earlier run (a Python session: it is
warned). With one runtime thread, a link cut mid-run left the master waiting past
every deadline instead of naming the lost worker (tests/distributed/test_netns.py,
the link-cut test); why is not known.
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Iterator, MutableMapping

ENV = "ZENOH_RUNTIME"
ONE_THREAD = ("(app: (worker_threads: 1), acc: (handover: app), tx: (handover: app), "
              "rx: (handover: app), net: (handover: app))")
DEFAULT_POOLS = "()"  # Zenoh's own defaults, for a comparison
_chosen = False  # first_session has run in this process: later sessions share its runtime
_one_thread_chosen = False  # ... and chose one runtime thread
POOLS_TOO_LATE = ("this process runs Zenoh on one runtime thread (chosen by its first run); a run "
                  "with workers then may not notice a cut link before its deadline: run it in a "
                  "fresh process (cosim run does), or set ZENOH_RUNTIME='()' before the first run")


def child_environment(env: MutableMapping[str, str]) -> MutableMapping[str, str]:
    """`env` (a child process's environment) with one runtime thread unless it says otherwise."""
    env.setdefault(ENV, ONE_THREAD)
    return env


@contextlib.contextmanager
def first_session(one_thread: bool = True) -> Iterator[None]:
    """Around the `zenoh.open` of this process's first session: one runtime thread,
    or Zenoh's default pools when `one_thread` is False.

    A `ZENOH_RUNTIME` already in the environment is used as it is. The environment is
    set only on the first call of the process and restored right after, so later child
    processes see the user's; later calls change nothing (Zenoh's runtime is chosen by
    then, and other threads may be reading the environment).
    """
    global _chosen, _one_thread_chosen
    if not one_thread and _one_thread_chosen:
        warnings.warn(POOLS_TOO_LATE, RuntimeWarning, stacklevel=3)
    if _chosen or not one_thread or ENV in os.environ:
        _chosen = True
        yield
        return
    _chosen = _one_thread_chosen = True  # whatever happens below: touched once per process
    os.environ[ENV] = ONE_THREAD
    try:
        yield
    finally:
        os.environ.pop(ENV, None)
