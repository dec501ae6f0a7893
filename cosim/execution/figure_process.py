"""A run's figure drawn by a process started with the run: the parent side.

Drawing a run's figure after it costs matplotlib's import and its first-draw set-up
(fonts, caches) on top of the drawing itself. `cosim run` therefore starts
`python -m cosim.figures.drawing_process` (the child side, whose docstring has the
protocol) once tick 0 is done, on the CPUs the lockstep chain leaves free
(`cosim.engine.one_cpu.release`; not with a single CPU, nor in a process that has
matplotlib loaded already): the child
does that set-up while the run goes, then waits. After the run `take` writes the
recorder's rows into a memory file the child inherited (one copy, no pipe) and tells
it the run folder, before this process writes the metrics, which then overlap the
drawing; `notes` returns what `analyse_run_folder` prints: "figure: PATH" or
"figures not drawn: WHY", and passes on what the child wrote on stderr (matplotlib's
warnings, as when drawn here).

The caller draws in its own process instead when the child did not start, is gone
when the run ends, exits with an error before answering (it could not run at all),
or when the rows are larger than `ROWS_HANDED_OVER_BYTES` (a copy would cost more
than the child saves). A child ended by a signal, or one that breaks the protocol,
gets a note: the run and its files are not touched.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

if TYPE_CHECKING:  # numpy is loaded after the run's spawn (tests/execution/test_startup.py)
    import numpy as np

CHILD = [sys.executable, "-m", "cosim.figures.drawing_process"]
ROWS_HANDED_OVER_BYTES = 256 << 20  # larger rows: drawn here, from the recorder's mapped spool
CHILD_ERRORS_SHOWN = 4000  # characters of the child's stderr passed on


class FigureProcess:
    """One drawing process, started once with `start` and asked at most once (see the
    module docstring)."""

    def __init__(self) -> None:
        self._process: subprocess.Popen | None = None
        self._rows: IO[bytes] | None = None  # the memory file the rows are handed over in
        self._stderr: IO[bytes] | None = None  # a file: a full pipe would block the child
        self._handed = False

    @property
    def pid(self) -> int | None:
        """The process's id once started, else None."""
        return self._process.pid if self._process is not None else None

    def start(self) -> None:
        """Start the process now (once) on the CPUs beside the lockstep chain; nothing when
        there is none (on one CPU its import would slow the run by what it saves), when
        this process has matplotlib loaded already (drawing here then costs no import: a
        Python session, the test suite) or when it cannot start. Never raises: a figure
        must not fail the run."""
        from cosim.engine import one_cpu

        if self._process is not None or drawing_loaded_here() or not one_cpu.cpus_beside():
            return
        try:
            self._rows = _memory_file()
            self._stderr = tempfile.TemporaryFile()
            fd = self._rows.fileno()
            env = dict(os.environ)
            env.setdefault("OPENBLAS_NUM_THREADS", "1")  # a quicker numpy import; it draws only
            # its own session: a Ctrl-C at the terminal reaches the command, which ends it
            self._process = subprocess.Popen([*CHILD, "--rows-fd", str(fd)], stdin=subprocess.PIPE,
                                             stdout=subprocess.PIPE, stderr=self._stderr,
                                             pass_fds=(fd,), start_new_session=True, env=env)
        except (OSError, ValueError):
            self.close()
            return
        one_cpu.release(self._process.pid)  # off the chain's CPU (nothing when none is pinned)

    def take(self, out_dir: Path, full_signals: tuple[list[str], np.ndarray] | None) -> bool:
        """Hand the run folder `out_dir` and the recorder's rows (`RunResult.full_signals`;
        None: the child reads signals.csv) over; False when the caller should draw itself
        (see the module docstring)."""
        process, rows_file = self._process, self._rows
        if process is None or rows_file is None or self._handed or process.poll() is not None:
            return False
        header: dict[str, Any] = {"folder": str(out_dir), "columns_bytes": None, "rows": 0}
        try:
            if full_signals is not None:
                columns, rows = full_signals
                if rows.nbytes > ROWS_HANDED_OVER_BYTES:
                    return False
                header["columns_bytes"], header["rows"] = _write_rows(rows_file, columns, rows)
            assert process.stdin is not None
            process.stdin.write(json.dumps(header).encode() + b"\n")
            process.stdin.close()
        except OSError:  # no room for the rows, or the child ended just now: drawn here
            return False
        self._handed = True
        return True

    def notes(self) -> list[str] | None:
        """Wait for the figure; the notes to print, or None when the child exited with an
        error before any answer (the caller then draws in its own process)."""
        process = self._process
        assert process is not None and process.stdout is not None and self._handed, "take the run first"
        try:
            out = process.stdout.read()
            process.wait()
        except BaseException:  # Ctrl-C or SIGTERM while waiting: the child goes with the command
            self.close()
            raise
        errors = self._child_errors()
        if errors:
            print(errors, file=sys.stderr)
        notes = [_note(line) for line in out.decode(errors="replace").splitlines()]
        self.close()
        if notes:
            return notes
        if process.returncode > 0:
            return None
        last = errors.splitlines()[-1] if errors else ""
        return [f"figures not drawn: the drawing process ended with status {process.returncode}"
                + (f": {last}" if last else "")]

    def _child_errors(self) -> str:
        """The end of what the child wrote on stderr, stripped ('' for nothing)."""
        from cosim.transport.zenoh.processes import file_tail

        return file_tail(self._stderr, CHILD_ERRORS_SHOWN) if self._stderr is not None else ""

    def close(self) -> None:
        """End the process if it is still there (never asked, or interrupted) and release
        its files; idempotent."""
        process = self._process
        if process is not None and process.poll() is None:
            process.kill()
            process.wait()
        for stream in ((process.stdin, process.stdout) if process is not None else ()) + (self._rows, self._stderr):
            if stream is not None:
                try:
                    stream.close()
                except OSError:
                    pass


def drawing_loaded_here() -> bool:
    """Whether this process has imported matplotlib already."""
    return "matplotlib" in sys.modules


def _memory_file() -> IO[bytes]:
    """An anonymous file for the rows: in memory (memfd) on Linux, else an unlinked temporary file."""
    if hasattr(os, "memfd_create"):
        return os.fdopen(os.memfd_create("cosim-figure-rows"), "w+b")
    return tempfile.TemporaryFile()


def _write_rows(rows_file: IO[bytes], columns: list[str], rows: np.ndarray) -> tuple[int, int]:
    """The column names as JSON (padded to 8 bytes), then the rows as float64; returns the
    names' bytes and the row count (the child's `read_request` reads them back)."""
    import numpy as np

    names = json.dumps(list(columns)).encode()
    names += b" " * (-len(names) % 8)  # JSON ignores trailing spaces; the rows start aligned
    rows_file.write(names)
    rows_file.write(memoryview(np.ascontiguousarray(rows, dtype=np.float64)).cast("B"))
    rows_file.flush()
    return len(names), int(rows.shape[0])


def _note(line: str) -> str:
    """The note for one answer line of the child."""
    try:
        message: Any = json.loads(line)
        return (f"figure: {message['figure']}" if "figure" in message
                else f"figures not drawn: {message['error']}")
    except (ValueError, KeyError, TypeError):
        return f"figures not drawn: the drawing process wrote {line[:200]!r}"
