"""Failure detection on the master side, waking the blocked receive loop.

The master waits for replies with a blocking `recv()` in its main thread (the
fastest way, DESIGN.md). This thread watches what that loop cannot: liveliness
tokens that vanish (a killed process: within milliseconds), local processes
that exit, and the per-exchange deadline (a hung or SIGSTOPped process). A
death is recorded in `dead` (the master checks it before each exchange), then
a DIED or TIMEOUT message goes to the reply key of the component the master
is waiting for, so its blocked receive wakes up and raises the failure.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Mapping

import zenoh

from cosim.transport.zenoh import config
from cosim.transport.zenoh.wire import Kind, encode_json
from cosim.transport.zenoh.processes import ChildProcess

POLL_S = 0.02


class Watchdog:
    """Background watcher of one run's component processes.

    Args:
        session: the master's open session (puts the wake-up messages).
        run_id: the run's id.
        children: the component processes by name.
        deadline_s: longest time an exchange may take before it fails.
    """

    def __init__(self, session: zenoh.Session, run_id: str,
                 children: Mapping[str, ChildProcess], deadline_s: float) -> None:
        self._session = session
        self._run_id = run_id
        self._children = dict(children)
        self._deadline_s = deadline_s
        self._tokens = session.liveliness().declare_subscriber(config.alive_key(run_id, "*"))
        self._armed: tuple[int, float, str] | None = None
        self._fired_seq = -1
        self.dead: dict[str, str] = {}    # component -> cause, in order of death
        self.finished: set[str] = set()   # components that ended normally: not failures
        self._halt = threading.Event()
        self._thread = threading.Thread(target=self._loop, name=f"cosim-watchdog-{run_id}",
                                        daemon=True)

    def start(self) -> None:
        """Start watching."""
        self._thread.start()

    def arm(self, seq: int, name: str) -> None:
        """Exchange `seq` with component `name` starts now; its deadline runs from here."""
        self._armed = (seq, time.monotonic() + self._deadline_s, name)

    def disarm(self) -> None:
        """The current exchange is over."""
        self._armed = None

    def close(self) -> None:
        """Stop the thread and undeclare the liveliness subscriber."""
        self._halt.set()
        if self._thread.is_alive():
            self._thread.join()
        self._tokens.undeclare()

    def _loop(self) -> None:
        while not self._halt.wait(POLL_S):
            self._check_tokens()
            self._check_processes()
            self._check_deadline()

    def _check_tokens(self) -> None:
        while (sample := self._tokens.try_recv()) is not None:
            if sample.kind == zenoh.SampleKind.DELETE:
                name = str(sample.key_expr).rsplit("/", 1)[-1]
                if name in self._children and name not in self.finished and name not in self.dead:
                    self._wait_for_verdict(self._children[name])
                self._report_died(name)

    def _check_processes(self) -> None:
        for name, child in self._children.items():
            if child.exit_code() is not None:
                self._report_died(name)

    def _check_deadline(self) -> None:
        armed = self._armed
        if armed is None or armed[0] == self._fired_seq or time.monotonic() < armed[1]:
            return
        seq, _, name = armed
        self._fired_seq = seq
        cause = (f"no reply within the deadline of {self._deadline_s:g} s "
                 f"(process stopped or not responding)")
        self._wake(name, Kind.TIMEOUT, seq, name, cause)

    def _wait_for_verdict(self, child: ChildProcess) -> None:
        """After a token vanished: until how the process ended is known, at most the
        child's `verdict_wait_s` (then the message says it went silent)."""
        end = time.monotonic() + child.verdict_wait_s
        while not child.end_known() and time.monotonic() < end:
            time.sleep(0.005)

    def _report_died(self, name: str) -> None:
        if name in self.dead or name in self.finished:
            return
        child = self._children.get(name)
        cause = (child.describe_exit() if child
                 else "process stopped or not responding (liveliness token lost)")
        self.dead[name] = cause  # first: the master may check it before we read `_armed`
        armed = self._armed
        if armed is not None:
            self._wake(armed[2], Kind.DIED, armed[0], name, cause)

    def _wake(self, waiting: str, kind: int, seq: int, name: str, cause: str) -> None:
        """Put a message for exchange `seq` on the reply key of component `waiting`."""
        message = encode_json(kind, seq, -1, 0.0, {"component": name, "cause": cause})
        self._session.put(config.reply_key(self._run_id, waiting), message)
