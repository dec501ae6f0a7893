"""The process that draws a run's figure while the run is still going: the child side.

`cosim run` starts it once tick 0 is done (`cosim.execution.figure_process`): it
imports matplotlib and the layouts and draws a small figure once (fonts, caches)
while the run goes, then waits for one request on stdin, a JSON line:

    {"folder": RUN_FOLDER, "columns_bytes": C, "rows": N}

The recorder's rows are in the memory file inherited as `--rows-fd FD`: the column
names as a JSON list in its first C bytes (C a multiple of 8), then N rows of
float64, one value per column. `columns_bytes` null: the run's signals.csv is read
instead. It answers one JSON line per figure on stdout, `{"figure": PATH}`, or one
`{"error": TEXT}` when the figure cannot be drawn, then exits. End of input before
a request (the command ended without asking) ends it quietly.

    python -m cosim.figures.drawing_process --rows-fd FD
"""

from __future__ import annotations

import argparse
import io
import json
import mmap
import sys
from typing import Any

import numpy as np


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


def read_request(line: bytes, rows_fd: int) -> tuple[str, tuple[list[str], np.ndarray] | None]:
    """The run folder and its rows (columns, values, read-only; None: read signals.csv).

    Raises:
        ValueError, KeyError, TypeError: a malformed request, or a memory file that
            holds less than it announces.
    """
    header = json.loads(line)
    folder, names_bytes = str(header["folder"]), header["columns_bytes"]
    if names_bytes is None:
        return folder, None
    held = mmap.mmap(rows_fd, 0, access=mmap.ACCESS_READ)
    columns = json.loads(held[:int(names_bytes)])
    count = int(header["rows"]) * len(columns)
    if len(held) < names_bytes + 8 * count:
        raise ValueError(f"the rows file holds {len(held)} bytes, not {names_bytes + 8 * count}")
    values = np.frombuffer(held, dtype=np.float64, count=count, offset=names_bytes)
    return folder, (list(columns), values.reshape(int(header["rows"]), len(columns)))


def answer(message: dict[str, Any]) -> None:
    """One JSON line on stdout."""
    sys.stdout.write(json.dumps(message) + "\n")
    sys.stdout.flush()


def main(argv: list[str] | None = None) -> int:
    """Warm up, wait for the request, draw, answer; the exit status is 0 unless the
    request was malformed."""
    parser = argparse.ArgumentParser(prog="python -m cosim.figures.drawing_process")
    parser.add_argument("--rows-fd", type=int, required=True)
    args = parser.parse_args(argv)
    try:
        warm_up()
    except Exception:  # noqa: BLE001  the figure itself, drawn below, says what is wrong
        pass
    line = sys.stdin.buffer.readline()
    if not line:
        return 0
    try:
        folder, full_signals = read_request(line, args.rows_fd)
    except (ValueError, KeyError, TypeError, OSError) as exc:
        answer({"error": f"bad request from the run: {exc}"})
        return 1
    try:
        from cosim.analysis.rundata import recorded_run
        from cosim.figures.layouts import draw_figures

        for path in draw_figures(folder, run=recorded_run(folder, full_signals)):
            answer({"figure": str(path)})
    except Exception as exc:  # a figure is best effort after a run that succeeded
        answer({"error": str(exc)})
    return 0


if __name__ == "__main__":
    from cosim import quick_exit

    quick_exit.skip_teardown()  # the PNG is written and the answer flushed: 0.4 s saved
    sys.exit(quick_exit.exit_status(main()))
