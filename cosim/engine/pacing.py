"""Real-time pacing of a run (`cosim run --realtime [FACTOR]`).

After tick k the pacer sleeps until the wall clock reaches
start + (t_k - t0) / factor. A tick whose work ends after its wall-clock
deadline counts as a deadline miss; how late the pacer actually resumes after
each deadline gives the jitter statistics reported in the manifest.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np


class RealtimePacer:
    """Master observer that paces the run to wall clock.

    Args:
        factor: simulated seconds per wall-clock second (1.0 = real time,
            2.0 = twice as fast as real time). Must be > 0.
        tick: base step in seconds.
    """

    def __init__(self, factor: float, tick: float) -> None:
        if not factor > 0:
            raise ValueError(f"real-time factor must be > 0, got {factor!r}")
        self.factor = float(factor)
        self.tick = float(tick)
        self._start = 0.0
        self._t0 = 0.0
        self.lateness: list[float] = []  # seconds between each deadline and the resume
        self.misses = 0

    def begin(self, master: Any) -> None:
        """Take the wall-clock origin (the initialization phase is not paced)."""
        self._t0 = master.t0

    def after_tick(self, tick: int, t: float, values: list[float], arrays: np.ndarray) -> None:
        """Sleep until this tick's wall-clock deadline; record how late it was."""
        now = time.perf_counter()
        if tick == 0:
            self._start = now
            return
        deadline = self._start + (t - self._t0) / self.factor
        if now > deadline:
            self.misses += 1
        else:
            time.sleep(deadline - now)
        self.lateness.append(time.perf_counter() - deadline)

    def stats(self) -> dict[str, float | int]:
        """Deadline misses and jitter (resume lateness in milliseconds)."""
        if not self.lateness:
            return {"factor": self.factor, "ticks": 0, "deadline_misses": 0}
        late = np.array(self.lateness)
        return {
            "factor": self.factor,
            "ticks": int(late.size),
            "deadline_misses": self.misses,
            "lateness_mean_ms": float(late.mean() * 1e3),
            "lateness_p99_ms": float(np.percentile(late, 99) * 1e3),
            "lateness_max_ms": float(late.max() * 1e3),
        }
