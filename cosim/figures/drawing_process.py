"""The process that draws a run's figure while the run is still going: the child side.

`cosim run` starts it with the run (`cosim.execution.figure_process`): it imports
matplotlib and the layouts and draws a small figure once (fonts, caches) while the
run goes, then waits. When the run has ended, one request comes on stdin (read by a
thread, so the run's side never waits on the warm-up): a JSON line, then the
recorder's rows as raw float64 bytes (`columns` null: signals.csv is read instead):

    {"folder": RUN_FOLDER, "columns": [NAME, ...], "rows": N}\\n<N x len(columns) float64>

It answers one JSON line per figure on stdout, `{"figure": PATH}`, or one
`{"error": TEXT}` when the figure cannot be drawn, then exits. End of input
before a request (the run failed, the master died) ends it quietly.

    python -m cosim.figures.drawing_process
"""

from __future__ import annotations

import io
import json
import os
import sys
import threading
from typing import Any, BinaryIO

import numpy as np

FLOAT_BYTES = 8


def warm_up() -> None:
    """Import what drawing needs and draw a small figure once, to memory."""
    from matplotlib.figure import Figure
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    import cosim.figures.layouts  # noqa: F401  (the layouts and what they import)

    fig = Figure(figsize=(2, 1.5), layout="constrained")
    ax = fig.subplots()
    ax.plot([0.0, 1.0], [0.0, 1.0], label="warm-up")
    ax.set_xlabel("time [s]")
    ax.legend()
    FigureCanvasAgg(fig).print_png(io.BytesIO())


def read_request(stream: BinaryIO) -> tuple[str, tuple[list[str], np.ndarray] | None] | None:
    """The run folder and its rows (columns, values; None: read signals.csv), or None
    at end of input.

    Raises:
        ValueError: a malformed header or fewer bytes than it announced.
    """
    line = stream.readline()
    if not line:
        return None
    header = json.loads(line)
    if header["columns"] is None:
        return str(header["folder"]), None
    columns, rows = list(header["columns"]), int(header["rows"])
    values = np.empty((rows, len(columns)), dtype=np.float64)
    view = memoryview(values.reshape(-1).view(np.uint8))
    got = 0
    while got < len(view):
        n = stream.readinto(view[got:])
        if not n:
            raise ValueError(f"the rows ended after {got} of {len(view)} bytes")
        got += n
    return str(header["folder"]), (columns, values)


def answer(message: dict[str, Any]) -> None:
    """One JSON line on stdout."""
    sys.stdout.write(json.dumps(message) + "\n")
    sys.stdout.flush()


class _Reader(threading.Thread):
    """Reads the request while the main thread warms up, so the run's side never waits
    on a full pipe; at end of input before a request it ends the process."""

    def __init__(self) -> None:
        super().__init__(name="request", daemon=True)
        self.request: Any = None
        self.problem: str | None = None

    def run(self) -> None:
        try:
            self.request = read_request(sys.stdin.buffer)
        except (ValueError, KeyError, TypeError) as exc:
            self.problem = f"bad request from the run: {exc}"
            return
        if self.request is None:  # the run ended without asking: leave, mid-import or not
            os._exit(0)


def main() -> int:
    """Warm up while the request comes in, then draw and answer; the exit status is 0
    unless the request was malformed."""
    reader = _Reader()
    reader.start()
    try:
        warm_up()
    except Exception:  # noqa: BLE001  the figure itself, drawn below, says what is wrong
        pass
    reader.join()
    if reader.problem is not None:
        answer({"error": reader.problem})
        return 1
    folder, full_signals = reader.request
    try:
        from cosim.analysis.rundata import recorded_run
        from cosim.figures.layouts import draw_figures

        for path in draw_figures(folder, run=recorded_run(folder, full_signals)):
            answer({"figure": str(path)})
    except Exception as exc:  # a figure is best effort after a run that succeeded
        answer({"error": str(exc)})
    return 0


if __name__ == "__main__":
    sys.exit(main())
