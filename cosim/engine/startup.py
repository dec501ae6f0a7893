"""Start-up clock of a run: how long `cosim run` takes to reach tick 0, and where.

`StartupClock` measures seconds from an origin (the start of this OS process
when known, else the moment the clock was made) and keeps named marks
("scenario_loaded", "spawned", "components_ready", "tick0"), with the CPU
time the process had used at each (a load-independent view of the work),
which the run writes into manifest.json. `cosim run` forks its master off a
supervisor after parsing its command line: the master's CPU time then counts the
work before the fork too (`after_fork`), so that it is the command's. It imports nothing heavy, so component processes
use `process_age_s` too.
"""

from __future__ import annotations

import os
import time

_STARTTIME_FIELD = 19  # /proc/<pid>/stat field 22 (starttime), counted after "comm)"
# /proc gives the fork time, not the exec time: `bash -c "pip install ... && cosim run X"`
# execs cosim in the shell's own process, forked before pip ran. A process that had been
# idle this long (age minus CPU time) when it imported cosim was not starting Python then.
IDLE_BEFORE_EXEC_S = 5.0


def process_age_s(pid: int | str = "self") -> float | None:
    """Seconds since a process started (Linux /proc, 10 ms resolution); None if unknown.

    Args:
        pid: the process id, or "self".
    """
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            data = stat.read()
        fields = data[data.rindex(b")") + 2:].split()
        started = int(fields[_STARTTIME_FIELD]) / os.sysconf("SC_CLK_TCK")
        return max(0.0, time.clock_gettime(time.CLOCK_BOOTTIME) - started)
    except (OSError, ValueError, IndexError, AttributeError):
        return None


class StartupClock:
    """Named marks in seconds since an origin on the perf_counter clock.

    Args:
        origin: perf_counter value of time zero.
        origin_kind: what time zero is ("process start" or "run_scenario call").
    """

    def __init__(self, origin: float, origin_kind: str) -> None:
        self.origin = origin
        self.origin_kind = origin_kind
        self.marks: dict[str, float] = {}
        self.cpu: dict[str, float] = {}  # CPU seconds this process had used at each mark
        self.cpu_before_fork = 0.0  # of the parent, when this process is a fork (after_fork)

    @classmethod
    def from_process_start(cls) -> "StartupClock":
        """A clock whose zero is the start of this process (or now, if unknown).

        When the process had been idle for over IDLE_BEFORE_EXEC_S by the time it
        imported cosim, it was forked long before it exec'd Python (a shell's last
        command): its zero is then that import, "cosim import (process forked before exec)".
        """
        from cosim import IMPORTED_AT

        now = time.perf_counter()
        age = process_age_s()
        if age is None:
            return cls(now, "clock creation")
        imported, cpu_then = IMPORTED_AT
        if age - (now - imported) - cpu_then > IDLE_BEFORE_EXEC_S:
            return cls(imported, "cosim import (process forked before exec)")
        return cls(now - age, "process start")

    @classmethod
    def from_now(cls, origin_kind: str = "run_scenario call") -> "StartupClock":
        """A clock whose zero is now.

        Args:
            origin_kind: what "now" is, for the manifest.
        """
        return cls(time.perf_counter(), origin_kind)

    def mark(self, name: str, at: float | None = None) -> float:
        """Record `name` at perf_counter time `at` (default now); return its seconds.

        Args:
            name: the mark's name, e.g. "tick0".
            at: a perf_counter value, or None for now.
        """
        seconds = (time.perf_counter() if at is None else at) - self.origin
        self.marks[name] = seconds
        self.cpu[name] = self.cpu_before_fork + time.process_time()
        return seconds

    def after_fork(self, parent_cpu_s: float) -> None:
        """In the child of a fork: add the parent's CPU time before it to every later mark
        (a forked process's own CPU time starts at zero).

        Args:
            parent_cpu_s: `time.process_time()` of the parent just before the fork.
        """
        self.cpu_before_fork = parent_cpu_s

    def as_dict(self) -> dict[str, object]:
        """The origin, the marks and the CPU time at each mark, for manifest.json."""
        return {"origin": self.origin_kind, **{f"{k}_s": v for k, v in self.marks.items()},
                "cpu_s": dict(self.cpu)}
