"""Parquet output of a run (`record: {format: [csv, parquet]}`), beside its CSV files.

Each recorder table becomes a Parquet file with the CSV's name and rows:
`signals.parquet` (time, then one float64 column per "component.signal") and
`arrays/<component>.<signal>.parquet` (time, and the signal as one column of
fixed-size lists of float64: one list per row, the window; a column per
element, as in the CSV, costs about ten times the bytes in per-column
metadata). It is written
from the recorder's binary spool (`cosim.results.csv_writer`), never from the
CSV text, with the same rows (the decimation's, `SpoolHeader.kept`), so every
value is the float64 the run computed, bit for bit (Parquet DOUBLE is IEEE
754 binary64: -0.0 and subnormals survive). Each field carries its unit and
description as field metadata ("unit", "description"); the file's metadata
says `cosim.every` (the decimation). pyarrow is an optional dependency (the
`parquet` extra), imported only here and only when Parquet is asked for.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from cosim.errors import UserError
from cosim.results.csv_writer import SpoolError, SpoolHeader

PARQUET_SUFFIX = ".parquet"
INSTALL_HINT = "pip install 'cosim-vehicle[parquet]'"


def pyarrow_missing() -> str | None:
    """Why Parquet cannot be written here (pyarrow not importable), or None."""
    try:
        import pyarrow.parquet  # noqa: F401
    except ImportError as exc:
        return f"pyarrow is not installed ({exc}): {INSTALL_HINT}"
    return None


def check_parquet_available(where: str) -> None:
    """A UserError (exit 2) naming the scenario field when Parquet is asked for without pyarrow.

    Args:
        where: the field that asks for it ("scenario.yaml: record.format").
    """
    missing = pyarrow_missing()
    if missing is not None:
        raise UserError(f"{where}: parquet asked for, but {missing}")


def parquet_path(header: SpoolHeader) -> Path:
    """The Parquet file a spool becomes (the CSV's name with .parquet)."""
    return header.csv_path.with_suffix(PARQUET_SUFFIX)


def spool_rows(header: SpoolHeader) -> np.ndarray:
    """The rows of a spool that the outputs keep (every `stride`-th and the last), (rows, columns).

    Raises:
        SpoolError when the spool cannot be read.
    """
    width = len(header.columns)
    try:
        with open(header.spool_path, "rb") as spool:
            rows = header.committed_bytes(spool.fileno()) // header.row_bytes
            data = np.fromfile(spool, dtype=np.dtype("<f8" if header.byteorder == "little"
                                                      else ">f8"),
                               count=rows * width, offset=header.data_offset)
    except OSError as exc:
        raise SpoolError(f"{header.spool_path}: cannot read the spool: {exc.strerror}") from None
    table = data.reshape(rows, width)
    keep = np.arange(0, rows, header.stride)
    if rows and keep[-1] != rows - 1:
        keep = np.append(keep, rows - 1)
    return table[keep].astype(np.float64)  # native byte order, as the CSV parse gives


def write_parquet(header: SpoolHeader) -> Path:
    """Write a table's Parquet file from its spool (temporary file, then rename).

    Args:
        header: the spool's header (columns, decimation, per-column unit and description).
    Returns:
        the Parquet file.
    Raises:
        SpoolError when the spool cannot be read; OSError when the file cannot be written.
    """
    import pyarrow as pa

    rows = spool_rows(header)
    array = array_name(header)
    if array is None:
        fields = [pa.field(name, pa.float64(), nullable=False,
                           metadata=_field_metadata(header, i))
                  for i, name in enumerate(header.columns)]
        values = [pa.array(rows[:, i]) for i in range(rows.shape[1])]
    else:
        size = rows.shape[1] - 1
        fields = [pa.field("time", pa.float64(), nullable=False,
                           metadata=_field_metadata(header, 0)),
                  pa.field(array, pa.list_(pa.float64(), size), nullable=False,
                           metadata=_field_metadata(header, 1))]
        values = [pa.array(rows[:, 0]),
                  pa.FixedSizeListArray.from_arrays(pa.array(rows[:, 1:].ravel()), size)]
    schema = pa.schema(fields, metadata={"cosim.every": str(header.every),
                                         "cosim.period_ticks": str(header.period)})
    table = pa.Table.from_arrays(values, schema=schema)
    path = parquet_path(header)
    tmp = path.with_name(path.name + ".tmp")
    try:
        import pyarrow.parquet as pq

        pq.write_table(table, tmp, compression="zstd")
        os.replace(tmp, path)
    except OSError:
        tmp.unlink(missing_ok=True)
        raise
    return path


def _field_metadata(header: SpoolHeader, index: int) -> dict[str, str]:
    meta: dict[str, Any] = header.meta[index] if index < len(header.meta) else {}
    return {"unit": str(meta.get("unit", "")), "description": str(meta.get("description", ""))}


def array_name(header: SpoolHeader) -> str | None:
    """The array signal a table holds ("planner.ref_x": columns time, name[0], ...), or None."""
    stem = header.csv[:-len(".csv")]
    elements = [f"{stem}[{i}]" for i in range(len(header.columns) - 1)]
    return stem if elements and list(header.columns[1:]) == elements else None


def read_parquet_table(path: Path) -> tuple[list[str], np.ndarray]:
    """Read a recorder Parquet file as the CSV reads: (column names, float64 (rows, columns)).

    An array signal's list column becomes its columns "name[0]", "name[1]", ...

    Args:
        path: signals.parquet or an arrays/ file.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    names: list[str] = []
    blocks: list[np.ndarray] = []
    for name, column in zip(table.column_names, table.columns):
        if pa.types.is_fixed_size_list(column.type):
            size = column.type.list_size
            flat = column.combine_chunks().flatten().to_numpy()
            blocks.append(flat.reshape(len(column), size))
            names += [f"{name}[{i}]" for i in range(size)]
        else:
            blocks.append(column.to_numpy().reshape(-1, 1))
            names.append(name)
    data = np.hstack(blocks) if blocks else np.empty((0, 0))
    return names, data.astype(np.float64, copy=False)
