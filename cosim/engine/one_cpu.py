"""The lockstep chain of a run on one CPU: the master and its local component processes.

In lockstep one process of a run computes at a time: the master steps the
FMU, then waits while the controller's process computes, which then waits for
the master's next request. Every message wakes a thread that waited. When the
waker and the woken run on different CPUs, the wake-up goes through the other
CPU's idle state; on a virtual machine whose idle CPUs halt (no halt polling)
that costs tens of microseconds per wake-up, several per message. Measured on
the development VM (2 vCPUs, `cosim run satory_nominal` over Zenoh, 6000 ticks):
295-315 us/tick with the processes where the OS puts them, 150-160 us/tick on
one CPU; a raw put/subscribe round trip 143-152 vs 36-56 us.

`PinnedChain.pin` is called once the run has started everything (start-up,
imports in every process at once, uses every CPU: pinned from the spawn, tick
0 came 0.15 s later), just before tick 0: it puts the calling thread, Zenoh's
runtime threads and every thread of the chain's other processes (components,
isolated FMU hosts, by pid) on one CPU; threads they start later inherit it.
Other threads of the master's process (a notebook's, the Foxglove server's)
keep their CPUs, and a chain process's threads that work beside the lockstep (an
OS name starting with `cosim.beside.BESIDE_THREAD_PREFIX`: a controller's
compiled code loading while it steps) get the other CPUs. When the context ends it restores the CPUs of every thread
of this process it pinned, and widens those born pinned meanwhile. `release`
gives a helper process started during the run that is not in the chain (the
recorder's writer) the other CPUs, so it does not compete with the chain.

The setting is "auto" (the CPU the master's thread runs on at tick 0: the OS
put it where it found room, so two runs started side by side land on
different CPUs), "off" (the OS places everything), or a CPU number
(`check_setting` refuses one this process may not use). Linux only: elsewhere
"auto" pins nothing and a CPU number is refused.
"""

from __future__ import annotations

import os
import re
import threading
from collections.abc import Iterable

from cosim.beside import BESIDE_THREAD_PREFIX
from cosim.errors import UserError

AUTO, OFF = "auto", "off"
Setting = str | int

_active: "PinnedChain | None" = None  # the chain pinned now in this process, if any


def parse_setting(value: object, source: str = "--lockstep-cpu") -> Setting:
    """"auto", "off" or a CPU number from a command line or API value.

    Args:
        value: the value given.
        source: the option's name, for the error message.
    Raises:
        UserError naming the option and the value when it is none of those.
    """
    if isinstance(value, bool):
        raise UserError(f"{source}: expected auto, off or a CPU number, got {value!r}")
    if isinstance(value, int):
        cpu = value
    else:
        text = str(value).strip().lower()
        if text in (AUTO, OFF):
            return text
        try:
            cpu = int(text, 10)
        except ValueError:
            raise UserError(f"{source}: expected auto, off or a CPU number, got {value!r}") from None
    if cpu < 0:
        raise UserError(f"{source}: a CPU number is 0 or more, got {cpu}")
    return cpu


def check_setting(setting: Setting, source: str = "--lockstep-cpu") -> Setting:
    """`parse_setting`, and a CPU number checked against the CPUs this process may use
    (before a run starts anything).

    Raises:
        UserError naming the option: not a setting, a CPU not allowed here, or a CPU
        number on a platform where a process cannot choose its CPUs.
    """
    setting = parse_setting(setting, source)
    if isinstance(setting, int):
        if not supported():
            raise UserError(f"{source} {setting}: this platform does not let a process choose "
                            f"its CPUs (Linux does); use auto or off")
        _refuse_unless_allowed(setting, set(os.sched_getaffinity(0)), source)
    return setting


def _refuse_unless_allowed(cpu: int, allowed: set[int], label: str) -> None:
    if cpu not in allowed:
        names = ", ".join(str(c) for c in sorted(allowed))
        raise UserError(f"{label} {cpu}: this process may run only on CPU {names}")


def supported() -> bool:
    """Whether this platform lets a process choose its threads' CPUs (Linux)."""
    return hasattr(os, "sched_setaffinity") and os.path.isdir("/proc/self/task")


def current_cpu() -> int | None:
    """The CPU the calling thread ran on last (field 39 of /proc/thread-self/stat), or None."""
    try:
        with open("/proc/thread-self/stat") as stat:
            text = stat.read()
    except OSError:
        return None
    fields = text.rsplit(")", 1)[1].split()
    return int(fields[36])  # field 39 of the whole line; fields here start at field 3


ZENOH_THREAD = re.compile(r"^(tx|rx|net|acc|app)-\d+$")  # the names of Zenoh's runtime threads


def _threads() -> list[int]:
    try:
        return [int(tid) for tid in os.listdir("/proc/self/task")]
    except OSError:
        return []


def _thread_name(tid: int, pid: int | str = "self") -> str:
    try:
        with open(f"/proc/{pid}/task/{tid}/comm") as comm:
            return comm.read().strip()
    except OSError:
        return ""


def _chain_threads() -> list[int]:
    """This thread and Zenoh's runtime threads (they carry every message of the chain)."""
    here = threading.get_native_id()
    return [here] + [tid for tid in _threads() if tid != here and ZENOH_THREAD.match(_thread_name(tid))]


def _set(tids: Iterable[int], cpus: set[int]) -> None:
    for tid in tids:
        try:
            os.sched_setaffinity(tid, cpus)
        except OSError:  # the thread ended meanwhile, or its cpuset refuses (EINVAL): left as it is
            pass


class PinnedChain:
    """The lockstep chain on one CPU from `pin` until the context ends.

    Args:
        setting: "auto", "off" or a CPU number (see the module docstring).

    Attributes:
        cpu: the CPU chosen by `pin`, or None while nothing is pinned (before `pin`,
            off, a single CPU, an unsupported platform).
    """

    def __init__(self, setting: Setting = AUTO) -> None:
        self.setting = parse_setting(setting)
        self.cpu: int | None = None
        self._allowed: set[int] = set()
        self._saved: dict[int, set[int]] = {}  # the chain threads pinned: their CPUs before
        self._before: set[int] = set()  # every thread of this process when `pin` began

    def __enter__(self) -> "PinnedChain":
        return self

    def pin(self, processes: Iterable[int] = ()) -> int | None:
        """Put this thread, Zenoh's runtime threads and every thread of `processes` (the
        chain's other processes, on this machine) on one CPU; return it, or None. The
        threads of `processes` that work beside the lockstep get the other CPUs.

        Called once everything has started (start-up uses every CPU), just before tick 0.
        """
        global _active
        if self.cpu is not None or self.setting == OFF or not supported():
            return self.cpu
        if _active is not None:  # a chain of this process (an outer run) holds one: this
            return _active.cpu   # thread, and what it started, are on it already
        self._allowed = set(os.sched_getaffinity(0))
        cpu = self._choose()
        if cpu is None:
            return None
        self._before = set(_threads())
        self._saved = {tid: cpus for tid in _chain_threads() if (cpus := _affinity(tid))}
        self.cpu, _active = cpu, self  # before any change: an interruption below is undone at exit
        _set(self._saved, {cpu})
        for pid in processes:
            threads = _threads_of(pid)
            beside = [tid for tid in threads if _thread_name(tid, pid).startswith(BESIDE_THREAD_PREFIX)]
            _set([tid for tid in threads if tid not in beside], {cpu})
            _set(beside, self.others())
        return cpu

    def _choose(self) -> int | None:
        if isinstance(self.setting, int):
            _refuse_unless_allowed(self.setting, self._allowed, "lockstep CPU")
            return self.setting
        if len(self._allowed) < 2:
            return None  # one CPU: the chain is on it already
        here = current_cpu()
        return here if here in self._allowed else min(self._allowed)

    def others(self) -> set[int]:
        """The CPUs this process had that are not the chain's (all of them if that leaves none)."""
        rest = self._allowed - {self.cpu} if self.cpu is not None else self._allowed
        return rest or set(self._allowed)

    def __exit__(self, *exc_info: object) -> None:
        global _active
        if self.cpu is None:
            return
        for tid in _threads():
            if tid in self._saved:
                _set([tid], self._saved[tid])
            elif tid not in self._before and _affinity(tid) == {self.cpu}:  # born pinned
                _set([tid], self._allowed)
        self.cpu = None
        _active = None


def _threads_of(pid: int) -> list[int]:
    try:
        return [int(tid) for tid in os.listdir(f"/proc/{pid}/task")]
    except OSError:
        return []  # it has ended already


def _affinity(tid: int) -> set[int]:
    try:
        return set(os.sched_getaffinity(tid))
    except OSError:
        return set()


def cpus_beside() -> set[int]:
    """The CPUs a process started now from this thread would work on beside the lockstep
    chain: the pinned chain's others (`release`), else this thread's CPUs when it has
    several; empty when it would share this thread's one CPU (a sweep worker's own CPU)."""
    if _active is not None:
        return _active.others() - {_active.cpu}
    try:
        allowed = set(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # no affinity on this platform: the OS places it
        return set(range(os.cpu_count() or 1)) if (os.cpu_count() or 1) > 1 else set()
    return allowed if len(allowed) > 1 else set()


def pinned_cpu() -> int | None:
    """The chain's CPU while a `PinnedChain` is open in this process, else None."""
    return _active.cpu if _active is not None else None


def release(pid: int) -> None:
    """Give process `pid` (just started from a pinned thread, not part of the chain) the
    CPUs other than the chain's; nothing when no chain is pinned.

    Its later threads inherit them; call it right after the process starts.
    """
    if _active is not None:  # set only while a chain is pinned
        _set(_threads_of(pid), _active.others())
