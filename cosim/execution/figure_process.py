"""A run's figure drawn by a process started with the run: the parent side.

Drawing a run's figure after it costs matplotlib's import and its first-draw set-up
(fonts, caches) on top of the drawing itself. `cosim run` therefore starts
`python -m cosim.figures.drawing_process` (the child side, whose docstring has the
protocol) with the run: the child does that set-up while the run goes, on a CPU the
lockstep chain leaves free (with a single CPU it is not started), then waits for the
run's rows. After the run `send` hands
it the run folder and the recorder's rows (before this process writes the metrics,
which then overlap the drawing) and `notes` returns what `analyse_run_folder` prints:
"figure: PATH" or "figures not drawn: WHY".

When the process cannot start, or exits with an error before answering, the caller
draws in its own process; when a signal ends it or it breaks its protocol, the note
says so (the run and its files are not touched).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # numpy is loaded after the run's spawn (tests/execution/test_startup.py)
    import numpy as np

CHILD = [sys.executable, "-m", "cosim.figures.drawing_process"]


class FigureProcess:
    """One drawing process, started once with `start` and asked at most once (see the
    module docstring)."""

    def __init__(self) -> None:
        self._process: subprocess.Popen | None = None
        self._stderr: Any = None  # a file: a pipe the child filled while this one reads stdout would block both
        self._sent = False
        self._send_problem: str | None = None

    @property
    def pid(self) -> int | None:
        """The process's id once started, else None."""
        return self._process.pid if self._process is not None else None

    @property
    def started(self) -> bool:
        """Whether the process runs (else the caller draws in its own process)."""
        return self._process is not None

    def start(self) -> None:
        """Start the process now (once), if this thread has a CPU beside the one the
        lockstep chain will take (on one CPU its import would slow the run by as much as
        it saves after); if it cannot start, `started` stays False."""
        from cosim.engine import one_cpu

        if self._process is not None or not one_cpu.cpus_beside():
            return
        try:
            self._stderr = tempfile.TemporaryFile()
            # its own session: a Ctrl-C at the terminal reaches the command, which ends it
            self._process = subprocess.Popen(CHILD, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                             stderr=self._stderr, start_new_session=True)
        except OSError:
            if self._stderr is not None:
                self._stderr.close()
                self._stderr = None

    def send(self, out_dir: Path, full_signals: tuple[list[str], np.ndarray] | None) -> None:
        """Ask for the figure of run folder `out_dir`, drawn from the recorder's rows
        (`RunResult.full_signals`; None: the child reads signals.csv)."""
        assert self._process is not None and not self._sent, "start it; it draws one run"
        self._sent = True
        stdin = self._process.stdin
        assert stdin is not None
        columns, rows = (None, None) if full_signals is None else full_signals
        header = {"folder": str(out_dir), "columns": columns,
                  "rows": 0 if rows is None else int(rows.shape[0])}
        try:
            stdin.write(json.dumps(header).encode() + b"\n")
            if rows is not None and rows.size:
                import numpy as np

                stdin.write(memoryview(np.ascontiguousarray(rows, dtype=np.float64)).cast("B"))
            stdin.close()
        except OSError as exc:  # it ended early (BrokenPipeError): `notes` says how
            self._send_problem = exc.strerror or str(exc)

    def notes(self) -> list[str] | None:
        """Wait for the figure; the notes to print (see the module docstring), or None when
        the process exited by itself with an error before any answer (it could not run at
        all, e.g. an import failed): the caller then draws in its own process. A process
        killed by a signal (a crash, the OOM killer) gets a note: drawing the same figure
        here could take the command down with it."""
        process = self._process
        assert process is not None and process.stdout is not None and self._sent, "send the run first"
        try:
            out = process.stdout.read()
            process.wait()
        except BaseException:  # Ctrl-C while waiting: the child goes with the command
            self.close()
            raise
        notes = []
        for line in out.decode(errors="replace").splitlines():
            try:
                message: Any = json.loads(line)
                notes.append(f"figure: {message['figure']}" if "figure" in message
                             else f"figures not drawn: {message['error']}")
            except (ValueError, KeyError, TypeError):
                notes.append(f"figures not drawn: the drawing process wrote {line[:200]!r}")
        if not notes and process.returncode > 0:
            self.close()
            return None
        if not notes:
            why = f"the drawing process ended with status {process.returncode}"
            if self._send_problem is not None:
                why += f" before it had the run ({self._send_problem})"
            last = self._last_error_line()
            notes.append(f"figures not drawn: {why}" + (f": {last}" if last else ""))
        self.close()
        return notes

    def _last_error_line(self) -> str:
        """The last line the child wrote on stderr (why it died), or ''."""
        try:
            self._stderr.seek(0)
            lines = self._stderr.read().decode(errors="replace").strip().splitlines()
        except (OSError, ValueError):
            return ""
        return lines[-1][:300] if lines else ""

    def close(self) -> None:
        """End the process if it is still there (not asked, or interrupted); idempotent."""
        process = self._process
        if process is None:
            return
        if process.poll() is None and not self._sent and process.stdin is not None:
            try:  # end of input before a request: it exits at once, quietly
                process.stdin.close()
                process.wait(timeout=2.0)
            except (OSError, subprocess.TimeoutExpired):
                pass
        if process.poll() is None:
            process.kill()
            process.wait()
        for stream in (process.stdin, process.stdout, self._stderr):
            if stream is not None:
                try:
                    stream.close()
                except OSError:
                    pass
