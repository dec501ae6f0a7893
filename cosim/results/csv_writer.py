"""CSV text from the recorder's binary spool: the writer process and the shared conversion.

The recorder (`cosim.results.recorder`) appends every row of a table (signals.csv, or
one array signal's CSV) as raw float64 values to a spool file `<stem>.f64`,
described by a small JSON header `<stem>.f64.json` (column names, the CSV's
file name, byte order). This module turns spool rows into the CSV text of the
recorder's contract, in UTF-8: a header line of column names (a name holding a comma,
quote, semicolon or line break in double quotes, RFC 4180: `csv_header_field`; read back by
`read_header_record` and `parse_header_line`), then one line per row with
every float written by `repr` (the shortest text that reads back to the same
float64), except in the header's `integer_columns` (integer and Boolean
signals), written as integers ("3", not "3.0"; exact, since the store holds
only integers that float64 represents exactly). It does so either while the run goes on, in a separate process that
tails the spool (`main`, so the text formatting runs on the other core), or in
one pass (`rebuild_csv`, for the recorder's fallback and `cosim recover`).
A spool starts with a page whose first 8 bytes count the complete rows
(`DATA_OFFSET`; the recorder writes each row into an mmap window of the file,
then the count, so a row is in the kernel's page cache the moment the tick
completes and survives the master's death); a spool without that page (an
older run) holds whole rows only, a partial last row being ignored. A row
whose values are bit-identical to the previous row's (a held planner window)
reuses that row's text: formatting floats is the whole cost of this module.

Decimation (`record: {every: N}`): the spool holds every row; a table keeps
the rows at ticks that are multiples of N, plus its last row (`SpoolHeader.kept`).
Spool row j is at tick j * period (period: ticks per row, 1 for signals.csv,
the component's period for an array), so the kept rows are every
`stride`-th row. The last row is known only when the spool is complete, so
the writer appends it after "close" (or after the master went away); a
salvage from the spool does the same. The header also carries each column's
metadata (unit, description), which the other writers (Parquet) use.

Only the standard library is imported, so the process starts fast; it is run
as a script (`python -S csv_writer.py HEADER...`). Protocol: the CSV files
already hold their header line; the writer appends the complete rows it finds,
polling, in chunks of whole rows (at least one, however wide). A line "close"
on stdin means the spool is complete: it converts the rest, prints {"rows": {HEADER: rows}} as JSON on stdout and exits 0. End of
stdin without "close" (the master died) converts what is on disk, prints the
same and exits 3, leaving the spool for `cosim recover`.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import select
import signal
import sys
from array import array
from dataclasses import dataclass
from pathlib import Path
from typing import IO

SPOOL_SUFFIX = ".f64"
HEADER_SUFFIX = ".f64.json"
SPOOL_FORMAT = "cosim-spool-f64"
DATA_OFFSET = 4096  # rows start here; the first 8 bytes count the complete rows
POLL_S = 0.2
CHUNK_BYTES = 1 << 16  # converted per read: bounds the writer's memory (flat with duration)
# a header field in these is quoted (RFC 4180); ";" too, for tools that guess the delimiter
QUOTED_CHARACTERS = frozenset(',";\r\n')
EXIT_MASTER_GONE = 3


class SpoolError(ValueError):
    """A spool or its header cannot be read; the message names the file and field."""


@dataclass(frozen=True)
class SpoolHeader:
    """What a spool holds.

    Args:
        path: the header file `<stem>.f64.json`.
        columns: CSV column names, "time" first; one float64 per column per row.
        csv: the CSV's file name, in the header's folder.
        byteorder: "little" or "big", as the floats were written.
        data_offset: where the rows start in the spool: `DATA_OFFSET` (a row
            count first), or 0 (whole rows only, as older runs wrote them).
        integer_columns: the columns written as integers (absent in older runs).
        every: keep the rows at ticks that are multiples of `every` (and the last).
        period: ticks per spool row.
        formats: the files this spool becomes: "csv", and "parquet" if asked.
        meta: per column, {"unit", "description"} ({} when not known).
        pid: the recording process (absent in older runs); it holds the recording lock
            on the signals spool while it records (`cosim.results.recorder.hold_recording_lock`).
    """

    path: Path
    columns: tuple[str, ...]
    csv: str
    byteorder: str
    data_offset: int = 0
    integer_columns: tuple[str, ...] = ()
    every: int = 1
    period: int = 1
    formats: tuple[str, ...] = ("csv",)
    meta: tuple[dict, ...] = ()
    pid: int | None = None

    @property
    def stride(self) -> int:
        """Spool rows per kept row: row j is kept when j % stride == 0 (or it is the last)."""
        return self.every // math.gcd(self.every, self.period)

    def kept(self, rows: int) -> int:
        """How many of `rows` spool rows the outputs keep (every `stride`-th, and the last)."""
        if rows <= 0:
            return 0
        return (rows - 1) // self.stride + 1 + (1 if (rows - 1) % self.stride else 0)

    def formatter(self) -> RowFormatter:
        """A RowFormatter for this spool's rows."""
        integers = {i for i, name in enumerate(self.columns) if name in self.integer_columns}
        return RowFormatter(len(self.columns), self.byteorder, integers)

    @property
    def spool_path(self) -> Path:
        """The binary spool file beside the header."""
        return self.path.with_name(self.path.name[:-len(".json")])

    @property
    def csv_path(self) -> Path:
        """The CSV file this spool becomes."""
        return self.path.with_name(self.csv)

    @property
    def row_bytes(self) -> int:
        """Bytes per spool row."""
        return 8 * len(self.columns)

    def csv_header_line(self) -> str:
        """The CSV's first line (`csv_header_field` of each column)."""
        return ",".join(map(csv_header_field, self.columns)) + "\n"

    @property
    def chunk_bytes(self) -> int:
        """Bytes converted per read: whole rows, at least one however wide a row is."""
        return max(1, CHUNK_BYTES // self.row_bytes) * self.row_bytes

    def committed_bytes(self, fd: int) -> int:
        """Bytes of complete rows in the open spool `fd` (from its row count, if it has one)."""
        available = max(0, os.fstat(fd).st_size - self.data_offset)
        if not self.data_offset:
            return available // self.row_bytes * self.row_bytes
        count = int.from_bytes(os.pread(fd, 8, 0), self.byteorder, signed=True)
        return max(0, min(count * self.row_bytes, available // self.row_bytes * self.row_bytes))


def csv_header_field(name: str) -> str:
    """A column name as the CSV header writes it: as is, or quoted (RFC 4180: in double
    quotes, a quote doubled) when it holds a comma, quote, semicolon or line break."""
    if QUOTED_CHARACTERS.isdisjoint(name):
        return name
    return '"' + name.replace('"', '""') + '"'


def parse_header_line(text: str) -> list[str]:
    """The column names of a CSV header record written by `SpoolHeader.csv_header_line`
    (quoted names included; `text` holds the whole record, line breaks in quotes too).

    Raises:
        ValueError when the record is not one well-formed CSV record.
    """
    try:
        records = list(csv.reader(io.StringIO(text, newline=""), strict=True))
    except csv.Error as exc:
        raise ValueError(f"header: {exc}") from None
    if len(records) != 1:
        raise ValueError(f"header: expected one line of column names, found {len(records)}")
    return records[0]


def read_header_record(handle: IO[str]) -> str:
    """The header record of a recorder CSV from its start: the first line, and the
    further lines while a quoted name holds line breaks (an odd count of quotes so far)."""
    record = handle.readline()
    while record.count('"') % 2 and (more := handle.readline()):
        record += more
    return record


def write_header(spool_path: Path, csv_name: str, columns: list[str],
                 data_offset: int = DATA_OFFSET, integer_columns: tuple[str, ...] = (),
                 every: int = 1, period: int = 1, formats: tuple[str, ...] = ("csv",),
                 meta: tuple[dict, ...] = (), pid: int | None = None) -> SpoolHeader:
    """Write the JSON header of a spool (atomically) and return it.

    Args:
        spool_path: the spool file `<stem>.f64` the header describes.
        csv_name: the CSV file name, in the same folder.
        columns: column names, "time" first.
        data_offset: where the rows start in the spool (see `SpoolHeader`).
        integer_columns: columns written as integers.
        every / period / formats / meta / pid: see `SpoolHeader`.
    """
    path = spool_path.with_name(spool_path.name + ".json")
    data = {"format": SPOOL_FORMAT, "csv": csv_name, "columns": list(columns),
            "byteorder": sys.byteorder, "data_offset": data_offset,
            "integer_columns": list(integer_columns), "every": every,
            "period": period, "formats": list(formats), "meta": list(meta)}
    if pid is not None:
        data["pid"] = pid
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(json.dumps(data) + "\n", encoding="utf-8")
        os.replace(tmp, path)
    except OSError:  # a full disk: no half-written .tmp stays behind
        _discard(tmp)
        raise
    return SpoolHeader(path, tuple(columns), csv_name, sys.byteorder, data_offset,
                       tuple(integer_columns), every, period, tuple(formats), tuple(meta), pid)


def _discard(path: Path) -> None:
    """Remove a temporary file if it is there and can be removed."""
    try:
        path.unlink()
    except OSError:
        pass


def read_header(path: Path) -> SpoolHeader:
    """Read and check a spool header.

    Args:
        path: a `<stem>.f64.json` file.
    Raises:
        SpoolError naming the file and the field that is wrong.
    """
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise SpoolError(f"{path}: unreadable spool header: {exc}") from None
    if not isinstance(data, dict):
        raise SpoolError(f"{path}: spool header is not a JSON object")
    if data.get("format") != SPOOL_FORMAT:
        raise SpoolError(f"{path}: format: expected {SPOOL_FORMAT!r}, got {data.get('format')!r}")
    columns = data.get("columns")
    if (not isinstance(columns, list) or not columns
            or not all(isinstance(c, str) and c for c in columns)):
        raise SpoolError(f"{path}: columns: expected a non-empty list of non-empty names, "
                         f"got {columns!r}")
    csv = data.get("csv")
    if not isinstance(csv, str) or not csv.endswith(".csv") or "/" in csv or "\\" in csv:
        raise SpoolError(f"{path}: csv: expected a file name ending in .csv, got {csv!r}")
    byteorder = data.get("byteorder")
    if byteorder not in ("little", "big"):
        raise SpoolError(f"{path}: byteorder: expected 'little' or 'big', got {byteorder!r}")
    offset = data.get("data_offset", 0)
    if offset not in (0, DATA_OFFSET):
        raise SpoolError(f"{path}: data_offset: expected 0 or {DATA_OFFSET}, got {offset!r}")
    integers = data.get("integer_columns", [])
    if not isinstance(integers, list) or not set(integers) <= set(columns[1:]):
        raise SpoolError(f"{path}: integer_columns: expected a list of columns after the "
                         f"time, got {integers!r}")
    every, period = data.get("every", 1), data.get("period", 1)
    for field, value in (("every", every), ("period", period)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise SpoolError(f"{path}: {field}: expected an integer >= 1, got {value!r}")
    formats = data.get("formats", ["csv"])
    if not isinstance(formats, list) or not set(formats) <= {"csv", "parquet"}:
        raise SpoolError(f"{path}: formats: expected a list of 'csv', 'parquet', got {formats!r}")
    meta = data.get("meta", [])
    if not isinstance(meta, list) or not all(isinstance(m, dict) for m in meta):
        raise SpoolError(f"{path}: meta: expected a list of objects, got {meta!r}")
    pid = data.get("pid")
    if pid is not None and (isinstance(pid, bool) or not isinstance(pid, int) or pid < 1):
        raise SpoolError(f"{path}: pid: expected a process id, got {pid!r}")
    return SpoolHeader(Path(path), tuple(columns), csv, byteorder, offset, tuple(integers),
                       every, period, tuple(formats), tuple(meta), pid)


def kept_rows(data: bytes, first: int, header: SpoolHeader) -> tuple[bytes, int]:
    """The rows of `data` (whole spool rows from row `first`) that the outputs keep.

    The last row of the spool is not among them unless the stride keeps it:
    `last_row` adds it once the spool is complete.

    Returns:
        (the kept rows' bytes, their number).
    """
    stride, size = header.stride, header.row_bytes
    rows = len(data) // size
    if stride == 1:
        return data, rows
    start = -first % stride  # the first row index >= first that is a multiple of stride
    view = memoryview(data)
    picked = [view[j * size:(j + 1) * size] for j in range(start, rows, stride)]
    return b"".join(picked), len(picked)


def last_row(fd: int, header: SpoolHeader, rows: int) -> bytes:
    """The spool's last row when the stride skipped it (b"" when it was kept, or no rows)."""
    if rows == 0 or (rows - 1) % header.stride == 0:
        return b""
    size = header.row_bytes
    return os.pread(fd, size, header.data_offset + (rows - 1) * size)


class RowFormatter:
    """Formats whole float64 rows as CSV lines, every float as its repr
    (the columns in `integers` as integers).

    A row whose values after the time are bit for bit those of the previous
    row (a held array signal, e.g. a planner window that did not change)
    reuses that row's text instead of formatting it again. The previous row
    is remembered across calls, so a table can be formatted chunk by chunk.

    Args:
        ncols: floats per row (the time first).
        byteorder: byte order of the data given to `format`.
        integers: indices of the columns (after the time, 0) written as integers.
    """

    def __init__(self, ncols: int, byteorder: str = sys.byteorder,
                 integers: set[int] | frozenset[int] = frozenset()) -> None:
        self.ncols = ncols
        self.swap = byteorder != sys.byteorder
        # "%r" of a float is exactly repr(float); "%d" of an integer-valued float its integer
        self._template = "".join(",%d" if i in integers else ",%r"
                                 for i in range(1, ncols)) + "\n"
        self._previous: bytes | None = None  # the previous row's values after the time, as bytes
        self._previous_text = ""

    def format(self, data: bytes) -> str:
        """CSV lines of `data`, a whole number of rows.

        Args:
            data: raw float64 values.
        """
        values = array("d")
        values.frombytes(data)
        if self.swap:
            values.byteswap()
        n, size = self.ncols, 8 * self.ncols
        template, previous, text = self._template, self._previous, self._previous_text
        parts: list[str] = []
        for row in range(len(values) // n):
            start = row * n
            payload = data[row * size + 8:(row + 1) * size]
            if payload != previous:
                previous, text = payload, template % tuple(values[start + 1:start + n])
            parts.append(repr(values[start]))
            parts.append(text)
        self._previous, self._previous_text = previous, text
        return "".join(parts)


def format_rows(data: bytes, ncols: int, byteorder: str = sys.byteorder) -> str:
    """CSV lines of whole float64 rows, every float as its repr.

    Args:
        data: raw float64 values, a whole number of rows of `ncols`.
        ncols: floats per row.
        byteorder: byte order of `data`.
    """
    return RowFormatter(ncols, byteorder).format(data)


class SpoolTail:
    """Follows one spool and appends its new complete rows to the CSV.

    Args:
        header: the spool's header; its CSV already holds the header line.
    """

    def __init__(self, header: SpoolHeader) -> None:
        self.header = header
        self.offset = 0
        self.rows = 0
        self._formatter = header.formatter()
        self._fd = os.open(header.spool_path, os.O_RDONLY)
        self._csv: IO[str] = open(header.csv_path, "a", encoding="utf-8", newline="\n")

    def pump(self) -> int:
        """Convert the complete rows written since the last call (at most one chunk).

        Returns:
            the number of spool rows read (those the stride keeps are appended to the CSV).
        """
        size = self.header.row_bytes
        end = self.header.committed_bytes(self._fd)
        data = os.pread(self._fd, min(self.header.chunk_bytes, end - self.offset),
                        self.header.data_offset + self.offset)
        rows = len(data) // size
        if rows:
            kept, count = kept_rows(data[:rows * size], self.offset // size, self.header)
            self._write(kept, count)
            self.offset += rows * size
        return rows

    def _write(self, data: bytes, rows: int) -> None:
        if rows:
            self._csv.write(self._formatter.format(data))
            self._csv.flush()
            self.rows += rows

    def drain(self) -> None:
        """Convert every complete row on disk, the last one included (the spool is complete)."""
        while self.pump():
            pass
        last = last_row(self._fd, self.header, self.offset // self.header.row_bytes)
        self._write(last, 1 if last else 0)

    def close(self) -> None:
        """Close the spool and the CSV."""
        os.close(self._fd)
        self._csv.close()


def rebuild_csv(header: SpoolHeader) -> tuple[int, int]:
    """Write a table's whole CSV from its spool (temporary file, then rename).

    Args:
        header: the spool's header.
    Returns:
        (CSV rows written, bytes of a partial last spool row that were ignored).
    Raises:
        SpoolError when the spool file is missing or unreadable, or when fewer rows
        could be read than its row count says (the CSV is then left as it was).
    """
    spool = header.spool_path
    try:
        source = open(spool, "rb")
    except OSError as exc:
        raise SpoolError(f"{spool}: cannot read the spool: {exc.strerror}") from None
    size, formatter = header.row_bytes, header.formatter()
    tmp = header.csv_path.with_name(header.csv + ".tmp")
    try:
        with source, open(tmp, "w", encoding="utf-8", newline="\n") as out:
            out.write(header.csv_header_line())
            end = header.committed_bytes(source.fileno())
            partial = 0 if header.data_offset else os.fstat(source.fileno()).st_size - end
            done = written = 0
            while done < end:
                chunk = os.pread(source.fileno(), min(header.chunk_bytes, end - done),
                                 header.data_offset + done)
                chunk = chunk[:len(chunk) // size * size]  # a short read: its whole rows
                if not chunk:
                    break
                kept, count = kept_rows(chunk, done // size, header)
                out.write(formatter.format(kept))
                done, written = done + len(chunk), written + count
            last = last_row(source.fileno(), header, done // size)
            out.write(formatter.format(last))
            written += 1 if last else 0
        expected = header.kept(end // size)
        if written != expected:
            raise SpoolError(f"{spool}: only {written} of the {expected} rows its count "
                             f"holds could be read; {header.csv} left as it was")
        os.replace(tmp, header.csv_path)
    except (OSError, SpoolError):  # a full disk: no half-written .tmp stays behind
        _discard(tmp)
        raise
    return written, partial


def _follow(tails: list[SpoolTail], control: IO[bytes]) -> bool:
    """Convert as rows arrive until the master says close (True) or goes away (False)."""
    busy = False
    while True:
        ready, _, _ = select.select([control], [], [], 0.0 if busy else POLL_S)
        busy = sum([tail.pump() for tail in tails]) > 0  # a backlog: no sleeping
        if ready:
            line = control.readline()
            if not line:
                return False
            if line.strip() == b"close":
                return True


def main(argv: list[str]) -> int:
    """The writer process: tail the spools named by their header files.

    Args:
        argv: header file paths.
    Returns:
        0 after "close", 3 when the master went away, 2 on a bad header.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the master's to handle
    try:
        os.nice(10)  # the lockstep processes come first; the backlog waits on disk
    except OSError:
        pass
    try:
        tails = [SpoolTail(read_header(Path(arg))) for arg in argv]
    except (SpoolError, OSError) as exc:
        print(f"csv writer: {exc}", file=sys.stderr)
        return 2
    closing = _follow(tails, sys.stdin.buffer)
    for tail in tails:
        tail.drain()
        tail.close()
    print(json.dumps({"rows": {str(t.header.path): t.rows for t in tails}}), flush=True)
    return 0 if closing else EXIT_MASTER_GONE


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
