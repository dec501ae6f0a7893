"""Reading a run folder for analysis: signals, arrays, manifest, scenario lookups.

The recorder writes `signals.csv` (a `time` column, then `<component>.<signal>`
columns, one row per master tick, or per N-th with `record.every`), `manifest.json` (the scenario as run and run
facts) and `arrays/<component>.<signal>.csv` (`time,0,...,N-1`, one row per
recorded window), and the same tables as `.parquet` files when the run asked
for them (read instead of the CSV when present: the same values, faster).
`RunData` loads these once and offers defensive lookups: a
missing signal is `None`, never an exception, so metrics and figures can leave
out what a run did not record. A file that exists but cannot be read is an
`AnalysisError` naming the file, the line and the value.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cosim.analysis.columns import ColumnFile, LazyColumns
from cosim.results.csv_writer import parse_header_line, read_header_record
from cosim.errors import UserError
from cosim.scenario.roles import resolve_roles


class AnalysisError(UserError):
    """A run folder (or sweep input) that cannot be analysed; the message says why."""


def _parse_rows(path: Path, lines: Sequence[str], width: int) -> np.ndarray:
    """Parse CSV data lines into a (rows, width) float array, naming bad lines.

    numpy's C reader converts each field with the same correctly rounded
    conversion as `float()` (CPython's PyOS_string_to_double), so its floats are
    bit-identical to the line-by-line parse, several times faster. But it skips
    blank lines and its errors do not name the value: a table it refuses, or
    returns with another shape, goes through the line-by-line parse, which
    names the first bad line (or, for text only `float()` reads, such as "1_0",
    returns the array).

    Args:
        path: the file, for messages.
        lines: the data lines (no header, no line ends).
        width: the number of fields every line must have.
    """
    if not lines:
        return np.empty((0, width))
    try:
        data = np.loadtxt(lines, dtype=np.float64, delimiter=",", comments=None, ndmin=2)
    except ValueError:
        data = None
    if data is not None and data.shape == (len(lines), width):
        return data
    return _parse_rows_slowly(path, lines, width)


def _parse_rows_slowly(path: Path, lines: Sequence[str], width: int) -> np.ndarray:
    """`_parse_rows` one line at a time with `float()`: the reference, and the error messages."""
    data = np.empty((len(lines), width))
    for i, line in enumerate(lines):
        fields = line.split(",")
        if len(fields) != width:
            raise AnalysisError(f"{path}:{i + 2}: expected {width} fields, found {len(fields)}")
        try:
            data[i] = [float(f) for f in fields]
        except ValueError:
            bad = next(f for f in fields if not _is_float(f))
            raise AnalysisError(f"{path}:{i + 2}: value {bad!r} is not a number") from None
    return data


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def read_csv_table(path: Path) -> tuple[list[str], np.ndarray]:
    """Read a recorder CSV (header line, then float rows).

    A last line without its newline and with a wrong field count is a row the
    recorder was writing when the run stopped: it is dropped, as the contract
    keeps only complete ticks.

    Args:
        path: the CSV file.

    Returns:
        (column names, float array of shape (rows, columns)).
    """
    try:
        streamed = _read_csv_streaming(path)
        if streamed is not None:
            return streamed
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise AnalysisError(f"{path}: cannot read: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise AnalysisError(f"{path}: not UTF-8 text: {exc.reason} at byte {exc.start}") from None
    lines = text.split("\n")
    record = lines[0]
    while record.count('"') % 2 and len(lines) > 1:  # a quoted name with a line break
        record += "\n" + lines.pop(1)
    header = _header(path, record)
    if not header or header[0] != "time":
        raise AnalysisError(f"{path}:1: header must start with 'time', found {lines[0][:40]!r}")
    body = lines[1:]
    if body and body[-1] == "":
        body = body[:-1]
    elif body and len(body[-1].split(",")) != len(header):
        body = body[:-1]  # partial last row of an interrupted run
    body = [b.rstrip("\r") for b in body]
    return header, _parse_rows(path, body, len(header))


def read_csv_columns(path: Path) -> tuple[list[str], ColumnFile | np.ndarray]:
    """Read a recorder CSV as `read_csv_table` does, into a `ColumnFile` (beside the file)
    when it parses in blocks, else into an array (the line-by-line path and its errors).

    Args:
        path: the CSV file.
    Returns:
        (column names, the columns).
    """
    try:
        with open(path, encoding="utf-8") as handle:
            record = read_header_record(handle)
            header = _header(path, record)
            rows = (_complete_rows(path, len(header), max(1, record.count("\n")))
                    if header[0] == "time" else None)
            table = None if rows is None else ColumnFile.parse(handle, len(header), rows,
                                                               near=path.parent)
    except OSError as exc:
        raise AnalysisError(f"{path}: cannot read: {exc.strerror}") from None
    if table is not None:
        return header, table
    return read_csv_table(path)


def _read_csv_streaming(path: Path) -> tuple[list[str], np.ndarray] | None:
    """`read_csv_table` without the whole text in memory (numpy reads the file itself), or None
    when the table needs the line-by-line path (a blank line, a field numpy refuses, a bad header).

    The text of a long run is several times the size of its floats: holding it (and its
    lines) made the analysis's peak memory grow with the run's duration.
    """
    with open(path, encoding="utf-8") as handle:
        record = read_header_record(handle)
        header = _header(path, record)
        if header[0] != "time":
            return None
        rows = _complete_rows(path, len(header), max(1, record.count("\n")))
        if rows is None:
            return None
        if rows == 0:
            return header, np.empty((0, len(header)))
        try:
            data = np.loadtxt(handle, dtype=np.float64, delimiter=",", comments=None, ndmin=2,
                              max_rows=rows)
        except ValueError:
            return None
    return (header, data) if data.shape == (rows, len(header)) else None


def _header(path: Path, record: str) -> list[str]:
    """The column names of a header record (names quoted where they hold a comma, quote,
    semicolon or line break, as the recorder writes them)."""
    try:
        return [h.strip() for h in parse_header_line(record)] or [""]
    except ValueError as exc:
        raise AnalysisError(f"{path}:1: {exc}") from None


def _complete_rows(path: Path, width: int, header_breaks: int = 1,
                   chunk: int = 1 << 20) -> int | None:
    """Data rows of a CSV whose last line may be partial (dropped unless it has `width` fields),
    counted in one pass over the bytes; None if some line is blank.
    `header_breaks`: the line breaks of the header record (more than 1 when a quoted name
    holds one)."""
    newlines, tail, previous = 0, b"", b""
    with open(path, "rb") as source:
        while block := source.read(chunk):
            if b"\n\n" in block or (previous == b"\n" and block[:1] == b"\n"):
                return None
            newlines += block.count(b"\n")
            cut = block.rfind(b"\n")
            tail = block[cut + 1:] if cut >= 0 else tail + block
            previous = block[-1:]
    if newlines < header_breaks:
        return 0   # the header alone
    complete = newlines - header_breaks
    if tail.strip(b"\r") and tail.count(b",") + 1 == width:
        complete += 1   # a last row written whole, without its newline
    return complete


class ArraySignal:
    """One recorded array signal: `times` (rows,) and `values` (rows, size).

    Read from a column file, `values` is built on first use; `column` and `row`
    read only what they return (a figure that draws each window's first point
    does not hold every window).
    """

    def __init__(self, times: np.ndarray, values: np.ndarray | None = None,
                 table: ColumnFile | None = None) -> None:
        self.times = times
        self._values, self._table = values, table

    @property
    def values(self) -> np.ndarray:
        """The windows, one row per recorded step."""
        if self._values is None:
            assert self._table is not None
            self._values = self._table.matrix(first=1)
        return self._values

    @property
    def shape(self) -> tuple[int, int]:
        """The shape of `values`, without reading them."""
        if self._values is None and self._table is not None:
            return (self._table.rows, self._table.width - 1)
        return self.values.shape

    def column(self, j: int) -> np.ndarray:
        """Point `j` of every window (a column of `values`)."""
        if self._values is None and self._table is not None:
            return self._table.column(j + 1)
        return self.values[:, j]

    def row(self, i: int) -> np.ndarray:
        """Window `i` (negative counts from the end; a row of `values`)."""
        if self._values is None and self._table is not None:
            return self._table.row(i)[1:]
        return self.values[i]


@dataclass
class RunData:
    """Everything an analysis needs from one run folder.

    Attributes:
        run_dir: the folder.
        time: the master tick times (rows,).
        columns: `<component>.<signal>` -> values (rows,).
        manifest: manifest.json as a dict ({} when absent).
        label_override: legend name to use instead of the folder's name.
        every: the data's tick stride: 1 when it holds every tick, N when read from
            the files of a run recorded with `record: {every: N}`.
    """

    run_dir: Path
    time: np.ndarray
    columns: Mapping[str, np.ndarray]
    manifest: dict[str, Any]
    label_override: str | None = None
    every: int = 1
    _arrays: dict[str, ArraySignal | None] = field(default_factory=dict)

    @property
    def scenario(self) -> dict[str, Any]:
        """The scenario as run ({} when the manifest does not have it)."""
        scenario = self.manifest.get("scenario")
        return scenario if isinstance(scenario, dict) else {}

    @property
    def label(self) -> str:
        """A short name for legends: `label_override` if set, else the folder's name."""
        return self.label_override or self.run_dir.resolve().name

    def signal(self, name: str) -> np.ndarray | None:
        """The column `name` ("component.signal"), or None when not recorded."""
        return self.columns.get(name)

    @functools.cached_property
    def roles(self) -> dict[str, str | None]:
        """role ("vehicle", "controller", "planner") -> the component playing it, or None
        (cosim.scenario.roles: the scenario's `metrics:` names, else the role's own name)."""
        arrays = self.run_dir / "arrays"
        recorded = [*self.columns, *(p.stem for p in arrays.glob("*.csv"))] if arrays.is_dir() \
            else list(self.columns)
        present = {name.split(".", 1)[0] for name in recorded}
        for pair in self.connections():
            present.update(end.split(".", 1)[0] for end in pair)
        return resolve_roles(self.scenario, present)

    @property
    def vehicle_run(self) -> bool:
        """True when some component plays a role; else the run gets the generic analysis."""
        return any(self.roles.values())

    def role_column(self, role: str, signal: str) -> str:
        """"component.signal" of a role's signal ("vehicle", "vx" -> "car.vx"); the role's
        own name stands for the component when no component plays it (for messages)."""
        return f"{self.roles[role] or role}.{signal}"

    def role_signal(self, role: str, signal: str) -> np.ndarray | None:
        """The column of a role's signal, or None when not recorded (or no component plays it)."""
        return self.columns.get(self.role_column(role, signal)) if self.roles[role] else None

    def role_path(self, role: str, field: str) -> str:
        """The scenario path of a field of a role's component ("controller", "parameters.ls")."""
        return f"components.{self.roles[role] or role}.{field}"

    def signal_info(self, name: str) -> dict[str, Any]:
        """A signal's entry in the manifest's "signals" (unit, description, size); {} when unknown."""
        info = self.manifest.get("signals")
        entry = info.get(name) if isinstance(info, dict) else None
        return entry if isinstance(entry, dict) else {}

    def unit(self, name: str) -> str:
        """The unit of a recorded signal from the manifest ("" when unknown)."""
        return str(self.signal_info(name).get("unit", "") or "")

    def array(self, name: str) -> ArraySignal | None:
        """The array signal `name` from arrays/<name>.csv (or .parquet), or None when absent."""
        if name not in self._arrays:
            path = self.run_dir / "arrays" / f"{name}.csv"
            if path.is_file():
                header, table = read_table(path)
                if isinstance(table, ColumnFile):
                    self._arrays[name] = ArraySignal(table.column(0), table=table)
                else:
                    self._arrays[name] = ArraySignal(table[:, 0], table[:, 1:])
            else:
                self._arrays[name] = None
        return self._arrays[name]

    def lookup(self, dotted: str, default: Any = None) -> Any:
        """A value from the scenario by dotted path ("components.vehicle.parameters.m")."""
        node: Any = self.scenario
        for key in dotted.split("."):
            if not isinstance(node, dict) or key not in node:
                return default
            node = node[key]
        return node

    def number(self, dotted: str, default: float) -> float:
        """A numeric scenario value by dotted path, `default` when absent.

        Raises:
            AnalysisError: the value is present but not a number.
        """
        value = self.lookup(dotted, None)
        if value is None:
            return default
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise AnalysisError(f"{self.run_dir / 'manifest.json'}: scenario.{dotted}: "
                                f"expected a number, found {value!r}")
        return float(value)

    def connections(self) -> list[tuple[str, str]]:
        """Connections as (source, destination) pairs, as written ([] when none known).

        From the manifest's "connections" ("a.x -> b.y" strings) when present,
        else from the scenario's connections ({"from", "to"} mappings or
        strings). Short forms ("a -> b": every output of a feeds b's input of
        the same name) are returned as written; see `source_of`.
        """
        items = self.manifest.get("connections") or self.scenario.get("connections") or []
        pairs = []
        for item in items:
            if isinstance(item, str) and "->" in item:
                src, dst = item.split("->", 1)
                pairs.append((src.strip(), dst.strip()))
            elif isinstance(item, dict) and "from" in item and "to" in item:
                pairs.append((str(item["from"]), str(item["to"])))
        return pairs

    def source_of(self, destination: str) -> str | None:
        """The recorded column feeding input `destination` ("vehicle.mu"), or None.

        An explicit "a.x -> vehicle.mu" wins over a short form "a -> vehicle"
        (which feeds vehicle.mu from a.mu), as in the platform's wiring rules.
        """
        component, _, port = destination.partition(".")
        short = None
        for src, dst in self.connections():
            if dst == destination and "." in src:
                return src if src in self.columns else None
            if dst == destination and "." not in src:
                outputs = [c for c in self.columns if c.startswith(src + ".")]
                short = outputs[0] if len(outputs) == 1 else short
            if dst == component and "." not in src and f"{src}.{port}" in self.columns:
                short = f"{src}.{port}"
        return short


def read_json_object(path: Path) -> dict[str, Any]:
    """Read a run folder's JSON file (manifest.json, metrics.json) holding one object.

    Args:
        path: the file; a missing file reads as {}.

    Raises:
        AnalysisError: the file is not valid JSON (naming the line) or not an object.
    """
    if not path.is_file():
        return {}
    try:
        document = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise AnalysisError(f"{path}:{exc.lineno}: not valid JSON: {exc.msg}") from None
    if not isinstance(document, dict):
        raise AnalysisError(f"{path}: expected a JSON object at the top level, "
                            f"found {type(document).__name__}")
    return document


def load_run(run_dir: str | Path) -> RunData:
    """Load a run folder.

    Args:
        run_dir: a folder holding at least `signals.csv`.

    Raises:
        AnalysisError: the folder or its signals.csv is missing or unreadable.
    """
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise AnalysisError(f"{run_dir}: no such run folder")
    path = run_dir / "signals.csv"
    if not path.is_file():
        raise AnalysisError(f"{run_dir}: not a run folder (signals.csv is missing)")
    header, table = read_table(path)
    manifest = read_json_object(run_dir / "manifest.json")
    recording = manifest.get("recording")
    every = recording.get("every", 1) if isinstance(recording, dict) else 1
    every = every if isinstance(every, int) and every >= 1 else 1
    if isinstance(table, ColumnFile):
        return RunData(run_dir, table.column(0), LazyColumns(header, table, skip=1), manifest,
                       every=every)
    columns = {name: table[:, i] for i, name in enumerate(header) if i > 0}
    return RunData(run_dir, table[:, 0], columns, manifest, every=every)


def read_table(csv_path: Path) -> tuple[list[str], ColumnFile | np.ndarray]:
    """A recorder table: from its Parquet twin when there is one and pyarrow reads it
    (several times faster, the same float64 values), else from the CSV (`read_csv_columns`)."""
    parquet = csv_path.with_suffix(".parquet")
    if parquet.is_file():
        try:
            from cosim.results.parquet import read_parquet_table

            return read_parquet_table(parquet)
        except ImportError:
            pass  # no pyarrow here: the CSV holds the same values
        except Exception as exc:  # a damaged file: say which, as for the CSV
            raise AnalysisError(f"{parquet}: cannot read: {exc}") from None
    return read_csv_columns(csv_path)


def recorded_run(run_dir: str | Path, full_signals: tuple[list[str], np.ndarray] | None) -> RunData:
    """The run folder just recorded, its scalar signals taken from the recorder
    (`Recorder.full_signals`: every tick, the float64 values signals.csv holds) instead
    of parsed from signals.csv; `load_run(run_dir)` when the recorder gave none.

    Args:
        run_dir: the run folder (its manifest and arrays are read from there).
        full_signals: (columns, rows) of every tick, or None.

    Raises:
        AnalysisError: the folder is missing (or, read by `load_run`, its signals.csv).
    """
    if full_signals is None:
        return load_run(run_dir)
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise AnalysisError(f"{run_dir}: no such run folder")
    header, data = full_signals
    columns = {name: data[:, i] for i, name in enumerate(header) if i > 0}
    return RunData(run_dir, data[:, 0], columns, read_json_object(run_dir / "manifest.json"))


def loaded_run(run_dir: str | Path, run: RunData | None) -> RunData:
    """`run` when given (`run_dir` loaded once by the caller), else `load_run(run_dir)`.

    Args:
        run_dir: the run folder the caller writes into.
        run: the folder already loaded, or None.

    Raises:
        AnalysisError: `run` was loaded from another folder (its results would
            be written beside the wrong run's files).
    """
    if run is None:
        return load_run(run_dir)
    if Path(run_dir).resolve() != run.run_dir.resolve():
        raise AnalysisError(f"{run_dir}: the run data given was loaded from another folder, "
                            f"{run.run_dir}")
    return run
