"""Recording a run into its folder as it goes.

`signals.csv` has a `time` column, then one column per recorded scalar signal
`component.signal`, one row per master tick (0 = after initialization; with
`every`, ticks 0, N, 2N, ... and the last), in UTF-8, a column name in double quotes
when it holds a comma, quote, semicolon or line break (`read_signals` reads it back).
Array signals go to
`arrays/<component>.<signal>.csv`, one row per step of their component.
Floats are written with `repr`, the shortest text that reads back to the
identical float64, so a reload is bit-identical; integer and Boolean signals
(`Port.type`, `cosim.signal_types`) are written as integers. `write_json` writes the
manifest and metrics atomically.

Text formatting is too slow for the master's loop, so the loop only writes
each row's raw float64 values into a binary spool per table (`signals.f64`,
`arrays/<name>.f64`, each with a JSON header `*.f64.json` naming its columns,
see `cosim.results.csv_writer`) through an mmap window, then bumps the spool's
row count: every completed tick is in the kernel when the tick completes, even
if the master is then killed (SIGKILL, a segfault in FMU code). A writer
process tails the spools and appends the CSV text on the other core: started
at tick 0 for a run whose files will hold `WRITER_AT_ONCE_VALUES` values or more
when a CPU beside the loop's is free for it (`one_cpu.cpus_beside`), else after
`FLUSH_INTERVAL_S` (a short run is converted at close, without a process);
`close` (which the master's caller runs in `finally`) lets it finish, checks its row counts (rebuilding the CSV in this
process if the writer failed) and removes the spools unless `keep_spool`. So
a failing component loses nothing before its tick; if the master process
itself dies, the run's supervisor (`cosim.execution.supervisor`) or `recover`
(`cosim recover RUN_DIR`, `cosim.results.recover`) rebuilds every CSV from the spools.

With `every` > 1 the spools still hold every tick; the files keep ticks 0,
N, 2N, ... and the last (`cosim.results.csv_writer`). After `close`
`full_signals` maps the whole signals spool for the run's metrics, whatever
`every`: the values signals.csv holds (each float's repr reads back to it), without
parsing the CSV (about 0.2 s for the 27,500 rows of satory_nominal). With
"parquet" among the formats, `close` also writes `signals.parquet` and
`arrays/<name>.parquet` from the spools (`cosim.results.parquet`).

A run folder that cannot be written (disk full, read-only, removed mid-run)
raises one `RunFolderError` naming the folder, the reason and the tick; the
recorder then stops writing and keeps its spools for `cosim recover`.

From `begin` to the end of `close` the recorder holds an exclusive `flock` on
the signals spool (`hold_recording_lock`; its pid is in the spool headers):
`recover` refuses a folder whose spool is locked (`is_being_recorded`), since
rebuilding and removing a live spool would cut the run short. The kernel drops
the lock when the master dies, however it dies; the writer process never takes it.
"""

from __future__ import annotations

import contextlib
import fcntl
import fnmatch
import json
import math
import mmap
import operator
import os
import select
import struct
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cosim.engine import one_cpu
from cosim.errors import RunFolderError
from cosim.results.csv_writer import (DATA_OFFSET, SPOOL_SUFFIX, SpoolError, SpoolHeader,
                                      parse_header_line, read_header_record, rebuild_csv,
                                      write_header)
from cosim.results.jsonfile import write_json, write_json_in_place  # noqa: F401 - re-exported
from cosim.results.parquet import write_parquet
from cosim.signal_types import is_integer

SIGNALS_FILE = "signals.csv"
ARRAYS_DIR = "arrays"
WRITER_SCRIPT = Path(__file__).with_name("csv_writer.py")
WRITER_STALL_S = 10.0  # a writer that converts nothing for this long is given up
FLUSH_INTERVAL_S = 0.5  # a run still going after this long gets the writer process
# a run whose files will hold this many values starts the writer at tick 0: converting
# them at close would take the master about 90 ms (0.6 us a value, each float's repr;
# a 10 s Satory sample has 82,000), the writer's start a few ms, and from then on it
# converts beside the loop
WRITER_AT_ONCE_VALUES = 150_000
HOUSEKEEPING_ROWS = 15  # start the writer when due and check the folder every 16 rows
FOLDER_CHECK_ROWS = 255  # look for a removed run folder every 256 rows (one fstat)
WINDOW_BYTES = 1 << 20  # mmap window of a spool (about; whole rows and pages)
POPULATE_BYTES = 1 << 16  # faulted in writable ahead of the rows, in one call
# madvise(MADV_POPULATE_WRITE), Linux 5.14; Python names it from 3.12
MADV_POPULATE_WRITE = getattr(mmap, "MADV_POPULATE_WRITE", 23 if sys.platform == "linux" else None)


def selected(name: str, include: Sequence[str], exclude: Sequence[str]) -> bool:
    """Whether "component.signal" matches an include glob and no exclude glob.

    Args:
        name: the signal's full name.
        include / exclude: fnmatch patterns.
    """
    return (any(fnmatch.fnmatchcase(name, p) for p in include)
            and not any(fnmatch.fnmatchcase(name, p) for p in exclude))


class _Table:
    """One recorded table: its CSV header line and its spool, written through an mmap window.

    Each row goes straight into the kernel's page cache (an mmap of the spool
    file, `MAP_SHARED`), then the row count at the spool's start: a completed
    tick is on disk for every other process, and survives the master's death,
    without a system call per row. The file grows by windows of about
    `WINDOW_BYTES`, allocated first (`posix_fallocate`, so a full disk is an
    OSError there, never a SIGBUS on a later write); only the current window
    is mapped, so memory stays flat with the run's length. A window is no
    larger than the rows still expected (`expected_rows`, known from the
    run's ticks and the table's period) need, rounded up to whole rows and
    pages: a short run reserves about what it writes, not a whole window per
    table, which the file system would allocate, then free at close. The window's pages
    are faulted in writable `POPULATE_BYTES` at a time ahead of the rows
    (`make_room`), not one trap per page in the middle of a tick.

    Args:
        folder: where the CSV, the spool and its header go.
        stem: file name without extension.
        columns: column names, "time" first.
        output: `every`, `formats` and `meta` of the spool header (`SpoolHeader`).
        offset / size / period: for an array signal, its slice of the master's
            array buffer and its component's period in ticks.
        integers: the columns written as integers.
        expected_rows: the rows the run will write at most, if known (None: windows of
            `WINDOW_BYTES`; rows beyond it still go in, in windows of that size).
    """

    def __init__(self, folder: Path, stem: str, columns: list[str], output: dict[str, Any],
                 offset: int = 0, size: int = 0, period: int = 1,
                 integers: Sequence[str] = (), expected_rows: int | None = None) -> None:
        self.offset, self.stop, self.period = offset, offset + size, period
        spool = folder / f"{stem}{SPOOL_SUFFIX}"
        self.header: SpoolHeader = write_header(spool, f"{stem}.csv", columns, period=period,
                                                integer_columns=tuple(integers), **output)
        with open(self.header.csv_path, "w", encoding="utf-8", newline="\n") as csv:
            csv.write(self.header.csv_header_line())
        self.row_bytes = self.header.row_bytes
        self.fd = os.open(spool, os.O_RDWR | os.O_CREAT | os.O_TRUNC, 0o644)
        os.posix_fallocate(self.fd, 0, DATA_OFFSET)
        self._count_map = mmap.mmap(self.fd, DATA_OFFSET)
        self.count = memoryview(self._count_map).cast("q")
        self.step = math.lcm(self.row_bytes, mmap.ALLOCATIONGRANULARITY)  # whole rows, whole pages
        self.largest_window = self.step * max(1, WINDOW_BYTES // self.step)
        self.expected_bytes = None if expected_rows is None else expected_rows * self.row_bytes
        self.window_bytes = 0  # the current window's size
        self.window: mmap.mmap | None = None
        # data bytes: where the window starts and how far into it rows are written
        self.base = self.at = 0
        self.ready = 0  # bytes of the window faulted in writable (the spool's first rows: none)
        self.room = -1  # the last offset in the window where a row fits in the ready bytes
        self.populate = MADV_POPULATE_WRITE is not None
        self.rows = 0
        self.source: memoryview | None = None  # an array table's slice of the master's buffer

    def make_room(self) -> int:
        """Make the next row's bytes ready: map the next window when this one is full, and
        fault in the next pages writable in one call. Returns the row's offset in the window.

        A page faulted in by the row's own write costs a trap into ext4 each time (3 us
        in process, ~13 us after a Zenoh wait, measured): in one call, per 16 pages, much less.
        """
        if self.window is None or self.at + self.row_bytes > self.window_bytes:
            self._next_window()
        ready = self.ready
        while ready < self.at + self.row_bytes:
            ready = min(self.window_bytes, ready + POPULATE_BYTES)
        if self.populate:
            try:
                self.window.madvise(MADV_POPULATE_WRITE, self.ready, ready - self.ready)
            except OSError:  # an older kernel: the rows' writes fault the pages in
                self.populate = False
        self.ready, self.room = ready, ready - self.row_bytes
        return self.at

    def _next_window(self) -> None:
        """Allocate and map the next window of the spool."""
        base = self.base if self.window is None else self.base + self.window_bytes
        if self.window is not None:
            self.window.close()
        size = self._window_size(base)
        os.posix_fallocate(self.fd, DATA_OFFSET + base, size)
        self.window = mmap.mmap(self.fd, size, offset=DATA_OFFSET + base)
        self.base, self.at, self.ready, self.window_bytes = base, 0, 0, size

    def _window_size(self, base: int) -> int:
        """The size of a window starting `base` data bytes into the spool: `largest_window`,
        or less when the rows still expected need less (whole steps of rows and pages)."""
        if self.expected_bytes is None or self.expected_bytes <= base:
            return self.largest_window
        steps = -(-(self.expected_bytes - base) // self.step)
        return self.step * min(steps, self.largest_window // self.step)

    def close(self) -> None:
        """Unmap and cut the spool to its complete rows (safe to call twice)."""
        if self.fd >= 0:
            if self.window is not None:
                self.window.close()
                self.window = None
            self.count.release()
            self._count_map.close()
            os.ftruncate(self.fd, DATA_OFFSET + self.base + self.at)
            os.close(self.fd)
            self.fd = -1

    def remove_spool(self) -> None:
        """Delete the spool and its header."""
        self.header.spool_path.unlink(missing_ok=True)
        self.header.path.unlink(missing_ok=True)


class Recorder:
    """Observer of the master that appends every tick to the run folder.

    Args:
        out_dir: the run folder (created when missing).
        include / exclude: fnmatch globs over "component.signal".
        flush_interval: wall time in seconds before the CSV writer process
            starts (a short run is converted at close, without a process); None:
            at tick 0 for a run whose files will hold `WRITER_AT_ONCE_VALUES` values
            or more, with a CPU beside the loop's, else `FLUSH_INTERVAL_S`.
        keep_spool: keep the binary spools after the CSV files are complete.
        on_writer: called with the CSV writer process's pid once it starts.
        every: keep every `every`-th tick in the output files (ticks 0, N, 2N, ...
            and the last); the spools hold every tick, and after `close`
            `full_signals` gives them to the analysis.
        formats: the output files: ("csv",) or ("csv", "parquet").
        column_info: "component.signal" -> {"unit", "description"} (the manifest's
            "signals" entry), written into the spool headers and the Parquet fields.
    """

    def __init__(self, out_dir: str | Path, include: Sequence[str] = ("*",),
                 exclude: Sequence[str] = (), flush_interval: float | None = None,
                 keep_spool: bool = False, on_writer: Any = None, every: int = 1,
                 formats: Sequence[str] = ("csv",),
                 column_info: dict[str, dict[str, Any]] | None = None) -> None:
        self.out_dir = Path(out_dir)
        self.include, self.exclude = list(include), list(exclude)
        self.every, self.formats = every, tuple(formats)
        self.column_info = column_info or {}
        self.full_signals: tuple[list[str], np.ndarray] | None = None  # after close
        self.flush_interval = flush_interval
        self.keep_spool = keep_spool
        self.on_writer = on_writer
        self.columns: list[str] = []
        self.rows = 0
        self.writer_pid: int | None = None  # the CSV writer process, once started
        self.writer_problem: str | None = None  # why the CSV was rebuilt here, if it was
        self._tables: list[_Table] = []
        self._array_groups: list[tuple[int, list[_Table]]] = []
        self._writer: subprocess.Popen[bytes] | None = None
        self._writer_tried = False
        self._closed = False
        self.failed: RunFolderError | None = None  # the folder could not be written
        self._started = time.monotonic()
        self._lock_fd: int | None = None  # `hold_recording_lock` on the signals spool

    def records(self, name: str) -> bool:
        """Whether this recorder keeps signal "component.signal"."""
        return selected(name, self.include, self.exclude)

    def begin(self, master: Any) -> None:
        """Choose the columns from the master's layout; write the CSV and spool headers."""
        try:
            self._begin(master)
        except OSError as exc:
            raise self._failure(exc, 0) from None

    def _begin(self, master: Any) -> None:
        self.out_dir.mkdir(parents=True, exist_ok=True)
        layout = master.layout
        chosen = [(n, i) for n, i in layout.scalar_columns()
                  if selected(n, self.include, self.exclude)]
        self.columns = [n for n, _ in chosen]
        index = [i for _, i in chosen]
        self._pick: Any = None if index == list(range(len(master.values))) else \
            operator.itemgetter(*index) if len(index) > 1 else (lambda values: [values[i] for i in index])
        self._pack_into = struct.Struct(f"={1 + len(index)}d").pack_into
        self._pack_time_into = struct.Struct("=d").pack_into
        integer = {f"{c}.{p}" for (c, p), port in layout.ports.items() if is_integer(port.type)}
        ticks = getattr(master, "total_ticks", None)  # the rows: ticks 0..N (of the period)
        self._signals = _Table(self.out_dir, SIGNALS_FILE[:-len(".csv")], ["time"] + self.columns,
                               self._output(["time"] + self.columns),
                               integers=[n for n in self.columns if n in integer],
                               expected_rows=None if ticks is None else ticks + 1)
        self._lock_fd = hold_recording_lock(self._signals.header.spool_path)
        self._tables = [self._signals]
        groups: dict[int, list[_Table]] = {}
        for comp, signal, offset, size in layout.array_signals():
            name = f"{comp}.{signal}"
            if selected(name, self.include, self.exclude):
                (self.out_dir / ARRAYS_DIR).mkdir(exist_ok=True)
                period = master.components[comp].period_ticks
                cells = [f"{name}[{i}]" for i in range(size)]
                columns = ["time"] + cells
                table = _Table(self.out_dir / ARRAYS_DIR, name, columns,
                               self._output(columns, name), offset, size, period,
                               cells if name in integer else (),
                               None if ticks is None else ticks // period + 1)
                self._tables.append(table)
                groups.setdefault(period, []).append(table)
        self._array_groups = sorted(groups.items())
        self._arrays_seen: Any = None
        self._started = time.monotonic()
        if self.flush_interval is None:  # at once only where it can convert beside the loop
            at_once = (ticks is not None and self._values_to_write(ticks) >= WRITER_AT_ONCE_VALUES
                       and one_cpu.cpus_beside())
            self.flush_interval = 0.0 if at_once else FLUSH_INTERVAL_S
        if self.flush_interval <= 0.0:
            self._start_writer()

    def _values_to_write(self, ticks: int) -> int:
        """The values the files of a run of `ticks` ticks will hold (rows kept by `every`)."""
        return sum(t.header.kept(ticks // t.period + 1) * len(t.header.columns) for t in self._tables)

    def _output(self, columns: list[str], array: str | None = None) -> dict[str, Any]:
        """The spool header's `every`, `formats` and per-column `meta` (an array's
        elements share its signal's unit and description)."""
        meta = [{"unit": "s", "description": "simulation time"}]
        for column in columns[1:]:
            info = self.column_info.get(array or column, {})
            meta.append({"unit": str(info.get("unit", "")),
                         "description": str(info.get("description", ""))})
        return {"every": self.every, "formats": self.formats, "meta": tuple(meta),
                "pid": os.getpid()}

    def after_tick(self, tick: int, t: float, values: list[float], arrays: np.ndarray) -> None:
        """Write this tick's raw rows into the spools (in the kernel from here on)."""
        table = self._signals
        at = table.at
        if at > table.room:
            at = self._make_room(table, tick)
        pick = self._pick  # None: every value of the store, in its order
        self._pack_into(table.window, at, t, *(values if pick is None else pick(values)))
        table.at = at + table.row_bytes
        self.rows = table.rows = rows = table.rows + 1
        table.count[0] = rows  # after the row: a reader never counts a row not written
        for period, tables in self._array_groups:
            if not tick % period:
                self._write_array_rows(tables, tick, t, arrays)
        if not rows & HOUSEKEEPING_ROWS:
            self._housekeeping(tick)

    def _housekeeping(self, tick: int) -> None:
        """Every 16 rows, not per tick: start the writer when due, look for a removed folder."""
        if not self._writer_tried and time.monotonic() - self._started >= self.flush_interval:
            self._start_writer()
        if not self.rows & FOLDER_CHECK_ROWS:
            self._check_folder(tick)

    def _make_room(self, table: _Table, tick: int) -> int:
        """`_Table.make_room`; a full disk is a RunFolderError at this tick."""
        try:
            return table.make_room()
        except OSError as exc:
            raise self._failure(exc, tick) from None

    def _check_folder(self, tick: int) -> None:
        """Rows written through the mmap go on into a removed file: look for its link now and then."""
        try:
            removed = os.fstat(self._signals.fd).st_nlink == 0
        except OSError as exc:
            raise self._failure(exc, tick) from None
        if removed:
            raise self._failure(RunFolderError(self.out_dir, "the spool was removed", tick), tick)

    def _write_array_rows(self, tables: list[_Table], tick: int, t: float,
                          arrays: np.ndarray) -> None:
        """One row (the time, then the array's values) into each table of a due group."""
        if arrays is not self._arrays_seen:  # memoryviews made once, not per row
            self._see_arrays(arrays)
        pack_time_into = self._pack_time_into
        for table in tables:
            at = table.at
            if at > table.room:
                at = self._make_room(table, tick)
            window, end = table.window, at + table.row_bytes
            pack_time_into(window, at, t)
            window[at + 8:end] = table.source
            table.at = end
            table.rows = rows = table.rows + 1
            table.count[0] = rows

    def _see_arrays(self, arrays: np.ndarray) -> None:
        """Point each array table at its slice of the master's array buffer."""
        view = memoryview(arrays).cast("B")
        for _, tables in self._array_groups:
            for table in tables:
                table.source = view[table.offset * 8:table.stop * 8]
        self._arrays_seen = arrays

    def _failure(self, exc: Exception, tick: int) -> RunFolderError:
        """Remember the first folder failure (the recorder writes nothing more) and return it."""
        if self.failed is None:
            if not self.out_dir.is_dir():
                self.failed = RunFolderError(self.out_dir, "the folder was removed", tick)
            elif isinstance(exc, RunFolderError):
                self.failed = exc
            else:
                self.failed = RunFolderError(self.out_dir, exc if isinstance(exc, OSError)
                                             else str(exc), tick)
        return self.failed

    def close(self) -> None:
        """Complete every CSV, then remove the spools unless kept (safe to call twice).

        The writer process converts what it has not yet converted; if it fails
        or its row counts differ from the rows spooled, the CSV files are
        rebuilt from the spools in this process.
        """
        if self._closed:
            return
        self._closed = True
        try:
            if self.failed is None:
                try:
                    self._complete()
                    return
                except (OSError, SpoolError) as exc:  # SpoolError: the spool went with its folder
                    self._failure(exc, self.rows - 1)
            self._abandon()
            raise self.failed  # type: ignore[misc]
        finally:
            if self._lock_fd is not None:
                os.close(self._lock_fd)  # the spools are complete or gone: recover may have them
                self._lock_fd = None

    def _complete(self) -> None:
        """close() of a folder that can be written: complete the CSV, remove the spools."""
        for table in self._tables:
            table.close()
        if self._writer is not None:
            self.writer_problem = self._finish_writer()
        if self._writer is None or self.writer_problem is not None:
            for table in self._tables:
                written, _ = rebuild_csv(table.header)
                expected = table.header.kept(table.rows)
                if written != expected:  # the spool is kept (close raises)
                    raise SpoolError(f"{table.header.csv_path}: {written} rows written, "
                                     f"{expected} expected, from {table.header.spool_path}")
            if self.writer_problem is not None:
                print(f"recorder: {self.writer_problem}; CSV files rebuilt from the spools",
                      file=sys.stderr)
        if "parquet" in self.formats:
            for table in self._tables:
                write_parquet(table.header)
        if self._tables:  # begun
            self.full_signals = _map_rows(self._signals.header, self._signals.rows)
        if not self.keep_spool:
            for table in self._tables:
                table.remove_spool()

    def _abandon(self) -> None:
        """After a folder failure: close the spools as they are (kept for `cosim recover`)
        and stop the writer process."""
        for table in self._tables:
            with contextlib.suppress(OSError, ValueError, BufferError):
                table.close()
            if table.fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(table.fd)
                table.fd = -1
        if self._writer is not None and self._writer.poll() is None:
            self._writer.kill()
        if self._writer is not None:
            self._writer.communicate()

    def _start_writer(self) -> None:
        """Start the CSV writer process on the spools (the CSV is built at close if it fails)."""
        self._writer_tried = True
        args = [sys.executable, "-S", str(WRITER_SCRIPT)] + [str(t.header.path) for t in self._tables]
        try:
            self._writer = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                            stderr=subprocess.PIPE, start_new_session=True)
        except OSError as exc:
            self.writer_problem = f"CSV writer process not started: {exc}"
            return
        self.writer_pid = self._writer.pid
        one_cpu.release(self.writer_pid)  # the writer works beside the lockstep chain, not on its CPU
        if self.on_writer is not None:
            self.on_writer(self.writer_pid)

    def _finish_writer(self) -> str | None:
        """Tell the writer the spools are complete and wait; why its CSV is not trusted, or None."""
        writer = self._writer
        assert writer is not None and writer.stdin is not None
        for action in (lambda: writer.stdin.write(b"close\n"), writer.stdin.close):
            try:
                action()
            except OSError:
                pass  # it died: its exit status says so below
        writer.stdin = None  # closed: communicate() must not flush it
        out = _read_while_progressing(writer, [t.header.csv_path for t in self._tables])
        if out is None:
            return f"CSV writer process made no progress for {WRITER_STALL_S:g} s"
        rest, err = writer.communicate()
        out += rest
        if writer.returncode != 0:
            last = err.decode(errors="replace").strip().splitlines()[-1:] or ["no message"]
            return f"CSV writer process exited with status {writer.returncode}: {last[0]}"
        try:
            counted = json.loads(out)["rows"]
        except (ValueError, KeyError, TypeError):
            return f"CSV writer process gave an unreadable report: {out[:200]!r}"
        for table in self._tables:
            expected = table.header.kept(table.rows)
            if counted.get(str(table.header.path)) != expected:
                return (f"CSV writer process wrote {counted.get(str(table.header.path))} rows "
                        f"to {table.header.csv_path}, expected {expected}")
        return None


def hold_recording_lock(spool: Path) -> int | None:
    """Take the recording lock of `spool`: an exclusive `flock` on a descriptor of its
    own (not inherited by child processes), held until it is closed or the process ends.

    Returns:
        the descriptor, or None when the file system has no locks (the run goes on;
        `recover` then cannot tell it is live).
    """
    try:
        fd = os.open(spool, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def is_being_recorded(spool: Path) -> bool:
    """Whether a live recorder holds the recording lock of `spool` (False: no spool,
    a dead recorder's spool, or a file system without locks)."""
    try:
        fd = os.open(spool, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:
        return False
    finally:
        os.close(fd)  # also drops the shared lock, if taken
    return False


def _read_while_progressing(process: subprocess.Popen[bytes], outputs: list[Path]) -> bytes | None:
    """The process's stdout, read to its end (the writer exits after its report), while it
    keeps growing `outputs`; after a stall it is killed (None).

    Woken by the pipe, not by polling: `Popen.wait(timeout)` sleeps 0.5, 1, 2, ... 50 ms
    between looks, which kept a run's close waiting up to twice as long as the writer.
    """
    assert process.stdout is not None
    fd, chunks = process.stdout.fileno(), []
    last_size, last_change = -1, time.monotonic()
    while True:
        if select.select([fd], [], [], 0.5)[0]:
            chunk = os.read(fd, 1 << 16)
            if not chunk:
                return b"".join(chunks)
            chunks.append(chunk)
            continue
        size = sum(p.stat().st_size for p in outputs if p.exists())
        if size != last_size:
            last_size, last_change = size, time.monotonic()
        elif time.monotonic() - last_change > WRITER_STALL_S:
            process.kill()
            process.communicate()
            return None


def _map_rows(header: SpoolHeader, rows: int) -> tuple[list[str], np.ndarray]:
    """Every row of a complete spool, mapped read-only (file-backed: it stays valid,
    and costs no memory of its own, after the spool is removed), as the CSV has them:
    integer columns as their text reads back (`%d`: truncated, no -0.0), in a copy."""
    if rows == 0:
        return list(header.columns), np.empty((0, len(header.columns)))
    data = np.memmap(header.spool_path, dtype=np.float64, mode="r", offset=header.data_offset,
                     shape=(rows, len(header.columns)))
    integers = [i for i, name in enumerate(header.columns) if name in header.integer_columns]
    if integers:
        data = np.array(data)
        data[:, integers] = np.trunc(data[:, integers]) + 0.0  # + 0.0: -0.0 becomes 0.0
    return list(header.columns), data


def read_signals(path: str | Path) -> tuple[list[str], np.ndarray]:
    """Read a signals.csv (or an arrays/ file) written by the recorder.

    Args:
        path: the CSV file.
    Returns:
        (column names, 2-D float64 array with one row per recorded tick).
    """
    with open(path, encoding="utf-8") as handle:
        try:
            names = parse_header_line(read_header_record(handle))
        except ValueError as exc:
            raise ValueError(f"{path}:1: {exc}") from None
        rows = [[float(v) for v in line.rstrip("\n").split(",")] for line in handle if line.strip()]
    return names, np.array(rows, dtype=np.float64).reshape(len(rows), len(names))
