"""The supervisor of `cosim run`: a parent process that outlives the master.

Native FMU code runs inside the master's process: a segfault, `abort()` or
`exit()` there kills the master, a doStep that never returns hangs it. So
`cosim run` forks once, early (before any thread or component process exists,
about a millisecond): the child is the master and runs the command; the
parent, this module, only waits. They share anonymous memory
(`ControlPage`): the master writes there its run folder, the CSV writer's
pid, a phase, and before every component call the breadcrumb of
`cosim.engine.master` (component, call, tick; a memory write, nearly free);
around the constructor of a component in its own process it writes the
component's name and its start-up deadline too (there is no manifest table yet).

Every `POLL_S` and on every signal the supervisor reads the breadcrumb:

- the master dies (a signal, or an exit before its final manifest): the
  supervisor completes the run folder (`cosim.results.salvage`: every CSV from
  the spools, whose rows the kernel already holds, and the manifest with status
  failed and the cause), ends what the master left running, prints one line
  naming the component, tick, time and signal, and exits 1;
- a call of a local component (an FMU in the master, an in-process Python
  component, its constructor included) lasts longer than its deadline: the
  supervisor kills the master
  and reports the same way (components in other processes have their own
  deadline in the master; the supervisor gives them a margin more);
- Ctrl-C, SIGTERM and SIGHUP are forwarded to the master (which has its own
  process group, so it gets each one once); if it is inside a call that does
  not return within `INTERRUPT_GRACE_S` (native code ignores signals), it is
  killed and the run folder completed as interrupted.

Whichever way the master ends, the supervisor then removes the master's
temporary folder of the run (FMU extractions, Zenoh credentials) and ends what
it left running before exiting: the processes of the master's process group and any orphan
it adopted as the master's subreaper (a component process whose start a
Ctrl-C cut short has no handle in the master; the CSV writer has a session of
its own). Otherwise it exits with the master's status. Standard library only (cosim.startup_gc
is too), plus the salvage, loaded only when needed.
"""

from __future__ import annotations

import contextlib
import json
import mmap
import os
import signal
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from cosim import startup_gc

PAGE_BYTES = 8192
CRUMB, PHASE, FOLDER_LEN, WRITER_PID, BUILD_DEADLINE_MS, BUILD_NAME_LEN, SCRATCH_LEN = range(7)
FOLDER_AT = 64  # the run folder's path, UTF-8, from this byte up to BUILD_NAME_AT
BUILD_NAME_AT = 4096  # the name of the component under construction, UTF-8, up to SCRATCH_AT
SCRATCH_AT = 5120  # the master's temporary folder for the run, UTF-8
STARTING, RUNNING, DONE = 0, 1, 2  # phases: before the folder, folder announced, final manifest
POLL_S = 0.05
INTERRUPT_GRACE_S = 0.5
REMOTE_MARGIN_S = 2.0  # beyond a proxied component's own deadline
LEFTOVER_GRACE_S = 1.0
REAP_WAIT_S = 1.0  # after SIGKILL, for the kernel to end what was killed
PR_SET_CHILD_SUBREAPER = 36  # linux/prctl.h
SCRATCH_PREFIX = "cosim-run-"  # the only folders _remove_scratch removes
FORWARDED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class ControlPage:
    """The page the master shares with its supervisor (anonymous, MAP_SHARED, kept over fork)."""

    def __init__(self) -> None:
        self.map = mmap.mmap(-1, PAGE_BYTES)
        self.words = memoryview(self.map).cast("q")

    @property
    def crumb(self) -> memoryview:
        """The int64 words; item 0 is the master's breadcrumb."""
        return self.words

    def announce(self, folder: Path) -> None:
        """The run folder exists (phase running)."""
        data = str(Path(folder).resolve()).encode("utf-8")[:BUILD_NAME_AT - FOLDER_AT]
        self.map[FOLDER_AT:FOLDER_AT + len(data)] = data
        self.words[FOLDER_LEN] = len(data)
        self.words[PHASE] = RUNNING

    @contextlib.contextmanager
    def constructing(self, index: int, name: str, deadline_s: float) -> Iterator[None]:
        """Component `name` (`index`: its place among those built here) is being
        constructed in the master's process: a call that must end within `deadline_s`."""
        from cosim.engine.crumb import CALL_BUILD, crumb_code

        data = name.encode("utf-8")[:SCRATCH_AT - BUILD_NAME_AT]
        self.map[BUILD_NAME_AT:BUILD_NAME_AT + len(data)] = data
        self.words[BUILD_NAME_LEN] = len(data)
        self.words[BUILD_DEADLINE_MS] = max(1, round(deadline_s * 1000.0))
        self.words[CRUMB] = crumb_code(index, CALL_BUILD)
        try:
            yield
        finally:
            self.words[CRUMB] = 0

    def constructed_name(self) -> str:
        """The component whose constructor the master entered last."""
        size = self.words[BUILD_NAME_LEN]
        return self.map[BUILD_NAME_AT:BUILD_NAME_AT + size].decode("utf-8", "replace")

    def note_scratch(self, folder: Path) -> bool:
        """`folder` holds the master's temporary files of the run (FMU extractions, Zenoh
        credentials): the supervisor removes it once the master has ended, however it
        ended. False (nothing noted) for a path too long."""
        data = str(Path(folder).resolve()).encode("utf-8")
        if len(data) > PAGE_BYTES - SCRATCH_AT:
            return False
        self.map[SCRATCH_AT:SCRATCH_AT + len(data)] = data
        self.words[SCRATCH_LEN] = len(data)
        return True

    def scratch(self) -> Path | None:
        """The noted scratch folder, or None."""
        size = self.words[SCRATCH_LEN]
        return Path(self.map[SCRATCH_AT:SCRATCH_AT + size].decode("utf-8")) if size else None

    def note_writer(self, pid: int) -> None:
        """The CSV writer process started (ended by the supervisor if the master dies)."""
        self.words[WRITER_PID] = pid

    def done(self) -> None:
        """The final manifest is written: from here, the master's death loses nothing."""
        self.words[PHASE] = DONE

    def folder(self) -> Path | None:
        """The announced run folder, or None."""
        size = self.words[FOLDER_LEN]
        return Path(self.map[FOLDER_AT:FOLDER_AT + size].decode("utf-8")) if size else None


_page: ControlPage | None = None  # in the master: the page its supervisor reads


def current() -> ControlPage | None:
    """The control page when this process is a supervised master, else None."""
    return _page


def fork_supervisor() -> int | None:
    """Fork the master off; None in the master, its final exit status in the supervisor.

    Call it before any thread or child process exists.
    """
    global _page
    page = ControlPage()
    watched = {*FORWARDED, signal.SIGCHLD}
    old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, watched)
    subreaper = _become_subreaper()  # before the fork: the child does not inherit it
    pid = os.fork()
    if pid == 0:
        os.setpgid(0, 0)  # a terminal's Ctrl-C reaches the supervisor, which forwards it once
        signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)  # a forwarded one is delivered now
        _page = page
        return None
    startup_gc.resume()  # it lasts as long as the run: collect, whatever the command's start chose
    try:
        return Supervisor(pid, page, subreaper).run()
    finally:
        _end_leftovers(pid, subreaper)
        _remove_scratch(page)
        for signo in FORWARDED:  # the command only exits now: a late Ctrl-C changes nothing
            signal.signal(signo, signal.SIG_IGN)
        signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)


class Supervisor:
    """Waits for the master `pid`, watching its breadcrumb on `page` (see the module)."""

    def __init__(self, pid: int, page: ControlPage, subreaper: bool = False) -> None:
        self.pid, self.page, self.subreaper = pid, page, subreaper
        self.word, self.since = 0, time.monotonic()  # the breadcrumb and when it last changed
        self.interrupted: tuple[float, str] | None = None  # (when, by what)
        self._table: dict[str, Any] | None = None

    def run(self) -> int:
        """Supervise until the master ends; the exit status of `cosim run`."""
        watched = {*FORWARDED, signal.SIGCHLD}
        while True:
            info = signal.sigtimedwait(watched, POLL_S)
            if info is not None and info.si_signo != signal.SIGCHLD:
                self._forward(info.si_signo)
            status = _reap_children(self.pid)[1]  # adopted orphans too: no zombie piles up
            if status is not None:
                return self._ended(status)
            verdict = self._check(time.monotonic())
            if verdict is not None:
                os.kill(self.pid, signal.SIGKILL)
                os.waitpid(self.pid, 0)
                return self._complete(verdict)

    def _forward(self, signo: int) -> None:
        if self.interrupted is None:
            what = ("interrupted by the user (Ctrl-C)" if signo == signal.SIGINT
                    else f"terminated by {signal.Signals(signo).name}")
            self.interrupted = (time.monotonic(), what)
        try:
            os.kill(self.pid, signo)
        except ProcessLookupError:
            pass

    def _check(self, now: float) -> dict[str, Any] | None:
        """A reason to end the master now (a call past its deadline, a stuck interrupt), or None."""
        word = self.page.words[CRUMB]
        if word != self.word:
            self.word, self.since = word, now
            return None
        call = _decode(word)
        if call is None:
            return None
        if self.interrupted is not None:
            when, what = self.interrupted
            if self.since <= when and now - when >= INTERRUPT_GRACE_S:
                return {"kind": "interrupted", "what": what, "call": call}
        deadline = self._deadline(call[0], call[1])
        if deadline is not None and now - self.since > deadline:
            return {"kind": "deadline", "deadline_s": deadline, "call": call}
        return None

    def _deadline(self, index: int, call: int) -> float | None:
        """The deadline of a call; None for the stop of a component in another process
        (its host ends it with its own grace periods and kills)."""
        from cosim.engine.crumb import CALL_BUILD, CALL_STOP

        if call == CALL_BUILD:  # before the manifest's table: the page holds it
            return self.page.words[BUILD_DEADLINE_MS] / 1000.0
        table = self._load_table()
        deadlines, local = table.get("deadlines_s", []), table.get("local", [])
        if index >= len(deadlines) or (call == CALL_STOP and not local[index]):
            return None
        return deadlines[index]

    def _load_table(self) -> dict[str, Any]:
        """The manifest's "supervision" entry (step order, deadlines), read once it is there."""
        if self._table is None:
            folder = self.page.folder()
            try:
                manifest = json.loads((folder / "manifest.json").read_text()) if folder else {}
            except (OSError, ValueError):
                return {}
            if "supervision" not in manifest:
                return {}
            self._table = dict(manifest["supervision"])
        return self._table

    def _ended(self, status: int) -> int:
        """The master ended by itself: its status, or the folder completed after a death."""
        phase = self.page.words[PHASE]
        if os.WIFSIGNALED(status):
            verdict = {"kind": "signal", "signal": signal.Signals(os.WTERMSIG(status)).name}
        else:
            code = os.waitstatus_to_exitcode(status)
            if phase != RUNNING:
                return code
            verdict = {"kind": "exit", "exit_code": code}
        verdict["call"] = _decode(self.page.words[CRUMB])
        if phase == DONE:
            _say(f"cosim: the master process was killed by {verdict['signal']} after "
                 f"its run folder was complete")
            return 1
        if phase == STARTING:
            _say(f"run failed: the master process was killed by {verdict['signal']} "
                 f"before the run folder was made")
            return 1
        return self._complete(verdict)

    def _complete(self, verdict: dict[str, Any]) -> int:
        """Complete the run folder after the master's death; print one line; status 1."""
        from cosim.engine.crumb import CALL_BUILD
        from cosim.results.salvage import complete_run_folder

        call = verdict.get("call")
        if call is not None and call[1] == CALL_BUILD:
            verdict["component"] = self.page.constructed_name()
        writer = self.page.words[WRITER_PID]
        if writer > 0:
            _kill(writer)  # the folder is rebuilt here: its conversion would be wasted
        _end_leftovers(self.pid, self.subreaper)  # first: the salvage may take a while
        folder = self.page.folder()
        try:
            message = complete_run_folder(folder, verdict)
        except Exception as exc:  # noqa: BLE001 - the line must still be printed
            message = (f"the master process ended ({_what(verdict)}); the run folder "
                       f"{folder} could not be completed: {exc}")
        _say(f"run failed: {message}")
        return 1


def supervision_entry(order: list[str], local: set[str],
                      deadlines: dict[str, float]) -> dict[str, Any]:
    """The manifest's "supervision" entry: each component's call deadline, in step order.

    Args:
        order: the master's step order.
        local: the components whose calls run in the master's process; the
            others (Zenoh processes, isolated FMUs) have their own deadline in
            the master and get `REMOTE_MARGIN_S` more here, as a backstop.
        deadlines: name -> deadline in seconds.
    """
    return {"deadlines_s": [deadlines[n] + (0.0 if n in local else REMOTE_MARGIN_S)
                            for n in order],
            "local": [n in local for n in order]}


def _decode(word: int) -> tuple[int, int, int] | None:
    from cosim.engine.crumb import decode_crumb

    return decode_crumb(word)


def _what(verdict: dict[str, Any]) -> str:
    return verdict.get("signal") or f"exit status {verdict.get('exit_code')}"


def _become_subreaper() -> bool:
    """Make this process the subreaper of its descendants (Linux): an orphan of the master
    becomes its child, which it can end and reap. Whether that was done."""
    try:
        import ctypes

        return ctypes.CDLL(None, use_errno=True).prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) == 0
    except (OSError, AttributeError):  # not Linux: the master's process group is still ended
        return False


def _end_leftovers(group: int, adopted: bool) -> None:
    """End what the master (leader of process group `group`, already reaped) left running:
    that group and, when this process is a subreaper (`adopted`), the orphans it
    adopted, down any chain (a child adopted late is signalled on the next pass).
    SIGTERM (and SIGCONT, for a stopped one), SIGKILL after `LEFTOVER_GRACE_S`; adopted
    ones are reaped. Once the group is empty its id is never signalled again (it may be reused)."""
    leftovers = _Leftovers(group, adopted)
    if not leftovers.running():
        return  # the usual end: nothing
    for signos, wait_s in (((signal.SIGTERM, signal.SIGCONT), LEFTOVER_GRACE_S),
                           ((signal.SIGKILL,), REAP_WAIT_S)):
        end = time.monotonic() + wait_s
        while leftovers.running() and time.monotonic() < end:
            for signo in signos:
                leftovers.signal(signo)
            time.sleep(0.01)


class _Leftovers:
    """The master's process group and this process's adopted children, as `_end_leftovers` ends them."""

    def __init__(self, group: int, adopted: bool) -> None:
        self.group: int | None = group  # None once it is empty
        self.adopted = adopted
        self.sent: set[tuple[int, int]] = set()  # (signal, pid or -group): each sent once

    def running(self) -> bool:
        """Whether a process of the group, or an adopted child, still runs (ended children reaped)."""
        child_running = self.adopted and _reap_children()[0]
        if self.group is not None:
            try:
                os.killpg(self.group, 0)
                return True
            except (ProcessLookupError, PermissionError):
                self.group = None
        return child_running

    def signal(self, signo: int) -> None:
        """Send `signo` once to the group (while it has members) and to each adopted child
        that has not had it (one adopted since the last call has not)."""
        if self.group is not None and (signo, -self.group) not in self.sent:
            self.sent.add((signo, -self.group))
            try:
                os.killpg(self.group, signo)
            except (ProcessLookupError, PermissionError):
                self.group = None
        for pid in _children() if self.adopted else ():
            if (signo, pid) not in self.sent:
                self.sent.add((signo, pid))
                _signal(pid, signo)


def _reap_children(master: int = -1) -> tuple[bool, int | None]:
    """Reap every child that has ended (orphans adopted as subreaper among them):
    (whether a child still runs, the wait status of `master` if it was one of them)."""
    status = None
    while True:
        try:
            pid, code = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return False, status
        if pid == 0:
            return True, status
        if pid == master:
            status = code


def _remove_scratch(page: ControlPage) -> None:
    """Remove the master's temporary folder of the run (what a crashed or killed master left)."""
    folder = page.scratch()
    if folder is not None and folder.name.startswith(SCRATCH_PREFIX):
        import shutil

        shutil.rmtree(folder, ignore_errors=True)


def _children() -> list[int]:
    """This process's children, from /proc (every thread's list)."""
    pids: list[int] = []
    for task in Path("/proc/self/task").glob("*"):
        try:
            pids += [int(p) for p in (task / "children").read_text().split()]
        except (OSError, ValueError):
            continue
    return pids


def _signal(pid: int, signo: int) -> None:
    try:
        os.kill(pid, signo)
    except (ProcessLookupError, PermissionError):
        pass


def _kill(pid: int) -> None:
    _signal(pid, signal.SIGKILL)


def _say(line: str) -> None:
    sys.stderr.write(line + "\n")
    sys.stderr.flush()
