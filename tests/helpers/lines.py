"""Lines of a child process's output, waited for with a deadline.

Read from the pipe's descriptor with `select` and `os.read`, never with the
stream's buffered `readline`: that one can take two lines out of the pipe and
return the first, and `select` then sees an empty pipe and never reports the
second (a worker's "listen ..." and "ready" lines, written together on a busy
machine, hid "ready" until the start's timeout).
"""

from __future__ import annotations

import os
import select
import subprocess
import time


class LineReader:
    """The lines a process writes on one pipe, each returned once."""

    def __init__(self, stream) -> None:
        self.fd = stream.fileno()
        self.pending = b""
        self.ended = False  # the pipe's writers have all closed it

    def next_line(self, deadline: float) -> str | None:
        """The next whole line (with its newline; the last one may lack it), or None when
        none came before `deadline` (time.monotonic) or the pipe ended."""
        while b"\n" not in self.pending and not self.ended:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            if select.select([self.fd], [], [], min(left, 0.2))[0]:
                chunk = os.read(self.fd, 1 << 16)
                self.ended = not chunk
                self.pending += chunk
        if b"\n" in self.pending:
            line, _, self.pending = self.pending.partition(b"\n")
            return line.decode(errors="replace") + "\n"
        line, self.pending = self.pending, b""
        return line.decode(errors="replace") or None


def line_reader(proc: subprocess.Popen) -> LineReader:
    """The one reader of `proc`'s stdout (made at the first call, kept on the object)."""
    reader = getattr(proc, "_test_line_reader", None)
    if reader is None:
        reader = proc._test_line_reader = LineReader(proc.stdout)
    return reader


def wait_for_line(proc: subprocess.Popen, text: str, timeout_s: float) -> None:
    """Read `proc`'s stdout until a line contains `text`; fail on timeout or end of output."""
    reader, seen = line_reader(proc), []
    end = time.monotonic() + timeout_s
    while (line := reader.next_line(end)) is not None:
        seen.append(line)
        if text in line:
            return
    raise AssertionError(f"no line {text!r} within {timeout_s} s; output: {''.join(seen)}")
