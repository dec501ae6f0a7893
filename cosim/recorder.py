"""Recording a run into its folder as it goes.

`signals.csv` has a `time` column, then one column per recorded scalar signal
`component.signal`, one row per master tick (0 = after initialization). Array
signals go to `arrays/<component>.<signal>.csv`, one row per step of their
component. Floats are written with `repr`, the shortest text that reads back to
the identical float64, so a reload is bit-identical. Rows are written whole and
flushed at least every `flush_interval` seconds of wall time and on close, so
a crash loses nothing before the last flushed tick and the partial file is a
valid CSV. `write_json` writes the manifest and metrics atomically.
"""

from __future__ import annotations

import fnmatch
import json
import math
import operator
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

SIGNALS_FILE = "signals.csv"
ARRAYS_DIR = "arrays"


def selected(name: str, include: Sequence[str], exclude: Sequence[str]) -> bool:
    """Whether "component.signal" matches an include glob and no exclude glob.

    Args:
        name: the signal's full name.
        include / exclude: fnmatch patterns.
    """
    return (any(fnmatch.fnmatchcase(name, p) for p in include)
            and not any(fnmatch.fnmatchcase(name, p) for p in exclude))


class _ArrayFile:
    """One array signal's CSV: rows at the ticks its component steps."""

    def __init__(self, path: Path, name: str, offset: int, size: int, period: int) -> None:
        self.offset, self.size, self.period = offset, size, period
        self.file: IO[str] = open(path, "w", encoding="ascii", newline="\n")
        self.file.write(",".join(["time"] + [f"{name}[{i}]" for i in range(size)]) + "\n")
        self.file.flush()
        self.pending: list[str] = []


class Recorder:
    """Observer of the master that appends every tick to the run folder.

    Args:
        out_dir: the run folder (created when missing).
        include / exclude: fnmatch globs over "component.signal".
        flush_interval: maximum wall time in seconds between two flushes.
    """

    def __init__(self, out_dir: str | Path, include: Sequence[str] = ("*",),
                 exclude: Sequence[str] = (), flush_interval: float = 0.5) -> None:
        self.out_dir = Path(out_dir)
        self.include, self.exclude = list(include), list(exclude)
        self.flush_interval = flush_interval
        self.columns: list[str] = []
        self._pick: Any = lambda values: ()
        self._signals: IO[str] | None = None
        self._pending: list[str] = []
        self._arrays: list[_ArrayFile] = []
        self._last_flush = time.monotonic()
        self.rows = 0

    @property
    def signals_path(self) -> Path:
        """Path of signals.csv."""
        return self.out_dir / SIGNALS_FILE

    def begin(self, master: Any) -> None:
        """Choose the columns from the master's layout and write the headers."""
        self.out_dir.mkdir(parents=True, exist_ok=True)
        layout = master.layout
        chosen = [(n, i) for n, i in layout.scalar_columns()
                  if selected(n, self.include, self.exclude)]
        self.columns = [n for n, _ in chosen]
        index = [i for _, i in chosen]
        self._pick = (lambda values: [values[i] for i in index]) if len(index) < 2 \
            else operator.itemgetter(*index)
        self._signals = open(self.signals_path, "w", encoding="ascii", newline="\n")
        self._signals.write(",".join(["time"] + self.columns) + "\n")
        self._signals.flush()
        for comp, signal, offset, size in layout.array_signals():
            name = f"{comp}.{signal}"
            if selected(name, self.include, self.exclude):
                (self.out_dir / ARRAYS_DIR).mkdir(exist_ok=True)
                period = master.components[comp].period_ticks
                self._arrays.append(_ArrayFile(self.out_dir / ARRAYS_DIR / f"{name}.csv",
                                               name, offset, size, period))

    def after_tick(self, tick: int, t: float, values: list[float], arrays: np.ndarray) -> None:
        """Queue the row of this tick; flush when the interval has passed."""
        stamp = repr(t)
        self._pending.append(",".join([stamp, *map(repr, self._pick(values))]) + "\n")
        for array in self._arrays:
            if tick % array.period == 0:
                row = arrays[array.offset:array.offset + array.size].tolist()
                array.pending.append(",".join([stamp, *map(repr, row)]) + "\n")
        self.rows += 1
        if time.monotonic() - self._last_flush >= self.flush_interval:
            self.flush()

    def flush(self) -> None:
        """Write the queued complete rows and push them to the OS."""
        if self._signals is not None and self._pending:
            self._signals.write("".join(self._pending))
            self._signals.flush()
            self._pending.clear()
        for array in self._arrays:
            if array.pending:
                array.file.write("".join(array.pending))
                array.file.flush()
                array.pending.clear()
        self._last_flush = time.monotonic()

    def close(self) -> None:
        """Flush and close every file (safe to call twice)."""
        self.flush()
        for handle in [self._signals, *(a.file for a in self._arrays)]:
            if handle is not None and not handle.closed:
                handle.close()


def read_signals(path: str | Path) -> tuple[list[str], np.ndarray]:
    """Read a signals.csv (or an arrays/ file) written by the recorder.

    Args:
        path: the CSV file.
    Returns:
        (column names, 2-D float64 array with one row per recorded tick).
    """
    with open(path, encoding="ascii") as handle:
        names = handle.readline().rstrip("\n").split(",")
        rows = [[float(v) for v in line.rstrip("\n").split(",")] for line in handle if line.strip()]
    return names, np.array(rows, dtype=np.float64).reshape(len(rows), len(names))


def write_json(path: str | Path, data: Any) -> None:
    """Write JSON atomically (temporary file, then rename); non-finite floats become null.

    Args:
        path: destination file.
        data: JSON-serializable data (dicts, lists, str, numbers, bools, None).
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", encoding="utf-8") as handle:
        json.dump(_finite(data), handle, indent=2, sort_keys=False)
        handle.write("\n")
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(tmp, path)


def _finite(data: Any) -> Any:
    """Replace NaN/inf floats by None so the JSON stays standard."""
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {str(k): _finite(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [_finite(v) for v in data]
    return data
