"""Progress display of a run: a rich progress bar on a terminal, nothing otherwise.

`ProgressBar` is a master observer; it redraws at most every 0.1 s of wall
time so the bar costs nothing per tick worth measuring.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn


class ProgressBar:
    """Master observer drawing simulated time against the scenario duration.

    Args:
        total_ticks: ticks of the run (after initialization).
        tick: base step in seconds, to show simulated time.
        console: where to draw (a terminal); stderr's console by default.
    """

    def __init__(self, total_ticks: int, tick: float, console: Console | None = None) -> None:
        self.total_ticks = max(int(total_ticks), 1)
        self.tick = tick
        self.console = console or Console(stderr=True)
        self._progress: Progress | None = None
        self._task: Any = None
        self._last = 0.0

    def begin(self, master: Any) -> None:
        """Show the bar."""
        self._progress = Progress(
            TextColumn("[bold]sim t={task.fields[t]:.2f} s"), BarColumn(),
            TextColumn("{task.completed}/{task.total} ticks"), TimeElapsedColumn(),
            TimeRemainingColumn(), console=self.console, transient=True)
        self._progress.start()
        self._task = self._progress.add_task("run", total=self.total_ticks, t=master.t0)

    def after_tick(self, tick: int, t: float, values: list[float], arrays: np.ndarray) -> None:
        """Redraw when 0.1 s of wall time has passed or the run is complete."""
        now = time.monotonic()
        if self._progress is not None and (now - self._last >= 0.1 or tick == self.total_ticks):
            self._last = now
            self._progress.update(self._task, completed=tick, t=t)

    def close(self) -> None:
        """Remove the bar (safe to call twice)."""
        if self._progress is not None:
            self._progress.stop()
            self._progress = None
