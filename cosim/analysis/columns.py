"""A recorder CSV held column by column on disk, so that analysis memory does not grow with a run.

A long run's signals.csv holds hundreds of thousands of rows; parsed whole, its
floats alone were the largest part of the analysis's peak memory, although a
metric or a figure reads a few columns at a time. `ColumnFile.parse` reads the
CSV in blocks of rows (numpy's C parser, the same conversion as `float()`, so
the values are bit-identical to a whole parse) and writes each block's columns
into an unnamed temporary file laid out column after column; `column(j)` then
reads one column into a fresh array (a `pread`, from the page cache: the
process holds only the columns its caller keeps). The file goes away with the
object. A table the block parser refuses (a blank line, a field numpy cannot
read) gives None: the caller parses it line by line for its error message.
"""

from __future__ import annotations

import itertools
import os
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np

BLOCK_ROWS = 8192  # rows parsed at a time: the parse's own memory, whatever the run's length


class ColumnFile:
    """The float columns of one table, column-major in a private temporary file.

    Args:
        handle: the temporary file (open, read-write), `rows * width` float64 written.
        rows: the table's rows.
        width: its columns.
    """

    def __init__(self, handle, rows: int, width: int) -> None:
        self._handle, self.rows, self.width = handle, rows, width

    @classmethod
    def parse(cls, source, width: int, rows: int, near: Path | None = None) -> "ColumnFile | None":
        """Parse `rows` CSV lines of `width` fields from the open text file `source`.

        Args:
            source: positioned after the header line.
            width: the fields of every line; rows: the complete data rows to read.
            near: a folder for the temporary file (the run folder, so it is on the
                disk the run is on, not in memory); the system's temporary folder if
                it cannot be written there.
        Returns:
            The columns, or None when some block is not `width` clean float fields.
        """
        handle = _temporary_file(near)
        fd, done = handle.fileno(), 0
        os.ftruncate(fd, rows * width * 8)
        while done < rows:
            count = min(BLOCK_ROWS, rows - done)
            try:
                block = np.loadtxt(itertools.islice(source, count), dtype=np.float64, delimiter=",",
                                   comments=None, ndmin=2)
            except ValueError:
                block = None
            if block is None or block.shape != (count, width):
                handle.close()
                return None
            for j in range(width):
                os.pwrite(fd, np.ascontiguousarray(block[:, j]), (j * rows + done) * 8)
            done += count
        return cls(handle, rows, width)

    def column(self, j: int) -> np.ndarray:
        """Column `j` as a new float64 array of `rows` values."""
        values = np.empty(self.rows)
        if self.rows:
            os.preadv(self._handle.fileno(), [values], j * self.rows * 8)
        return values

    def row(self, i: int) -> np.ndarray:
        """Row `i` (negative counts from the end) as a new float64 array of `width` values."""
        i = i + self.rows if i < 0 else i
        if not 0 <= i < self.rows:
            raise IndexError(f"row {i} of a table of {self.rows} rows")
        fd = self._handle.fileno()
        return np.array([np.frombuffer(os.pread(fd, 8, (j * self.rows + i) * 8), np.float64)[0]
                         for j in range(self.width)])

    def matrix(self, first: int = 0) -> np.ndarray:
        """Columns `first`.. as one (rows, width - first) array (the whole table in memory)."""
        out = np.empty((self.rows, self.width - first))
        for j in range(first, self.width):
            out[:, j - first] = self.column(j)
        return out


class LazyColumns(Mapping[str, np.ndarray]):
    """Named columns of a ColumnFile, each read when looked up (a fresh array each time).

    Args:
        names: the column names, in table order; skip: how many leading columns to leave out.
        table: where the values are.
    """

    def __init__(self, names: list[str], table: ColumnFile, skip: int = 0) -> None:
        self._index = {name: j for j, name in enumerate(names) if j >= skip}
        self._table = table

    def __getitem__(self, name: str) -> np.ndarray:
        return self._table.column(self._index[name])

    def __contains__(self, name: object) -> bool:
        return name in self._index

    def __iter__(self) -> Iterator[str]:
        return iter(self._index)

    def __len__(self) -> int:
        return len(self._index)


def _temporary_file(near: Path | None):
    """An unnamed read-write temporary file in `near` if possible, else in the temporary folder."""
    if near is not None:
        try:
            return tempfile.TemporaryFile(dir=near)
        except OSError:
            pass
    return tempfile.TemporaryFile()
