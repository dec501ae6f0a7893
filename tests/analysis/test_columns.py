"""Tests of `cosim.analysis.columns`: a run's tables read column by column from a temporary file.

`load_run` and `RunData.array` read the recorder's CSVs in blocks into a
column-major temporary file, so that the analysis holds only the columns it
uses. Every column, row and matrix read back must be the line-by-line parse's,
bit for bit, across block boundaries and with a last row cut short; a table the
block parser refuses must still get the line-numbered message.
"""

from __future__ import annotations

import numpy as np
import pytest

from cosim.analysis import columns, rundata
from cosim.analysis.rundata import AnalysisError, load_run

HEADER = "time,a.x,b.y,c.z"


def rows(n: int, seed: int = 2) -> list[str]:
    """Lines of random floats of every magnitude (and -0.0), written with repr as the recorder does."""
    values = np.random.default_rng(seed).standard_normal((n, 4)) * 10.0 ** np.arange(-12, 12, 6)
    values[n // 2, 1] = -0.0
    values[:, 0] = np.arange(n) * 0.01
    return [",".join(repr(float(v)) for v in row) for row in values]


def line_parse(lines: list[str]) -> np.ndarray:
    return rundata._parse_rows_slowly(None, lines, 4)


@pytest.mark.parametrize("ending", ["\n", "", "\n0.5,1"])  # last row kept, kept, cut short
def test_lazy_columns_are_the_line_parse_bit_for_bit(tmp_path, monkeypatch, ending):
    monkeypatch.setattr(columns, "BLOCK_ROWS", 7)  # many blocks, the last one short
    lines = rows(100)
    (tmp_path / "signals.csv").write_text(HEADER + "\n" + "\n".join(lines) + ending)
    run = load_run(tmp_path)
    expected = line_parse(lines)
    assert isinstance(run.columns, columns.LazyColumns)
    assert list(run.columns) == ["a.x", "b.y", "c.z"] and len(run.columns) == 3
    assert "time" not in run.columns and "b.y" in run.columns
    assert run.time.tobytes() == expected[:, 0].tobytes()
    for j, name in enumerate(["a.x", "b.y", "c.z"], start=1):
        assert run.signal(name).tobytes() == expected[:, j].tobytes()
    assert run.signal("nope") is None
    column = run.signal("a.x")
    column[0] = 99.0  # a fresh array for each look-up: the next one is unchanged
    assert run.signal("a.x").tobytes() == expected[:, 1].tobytes()


def test_array_windows_by_column_row_and_whole(tmp_path, monkeypatch):
    monkeypatch.setattr(columns, "BLOCK_ROWS", 5)
    (tmp_path / "arrays").mkdir()
    lines = rows(23)
    (tmp_path / "signals.csv").write_text("time,v.x\n0.0,1.0\n")
    (tmp_path / "arrays" / "planner.ref_x.csv").write_text("time,0,1,2\n" + "\n".join(lines) + "\n")
    window = load_run(tmp_path).array("planner.ref_x")
    expected = line_parse(lines)
    assert window.shape == (23, 3)
    assert window.times.tobytes() == expected[:, 0].tobytes()
    assert window.column(1).tobytes() == expected[:, 2].tobytes()
    assert window.row(-1).tobytes() == expected[-1, 1:].tobytes()
    assert window.row(4).tobytes() == expected[4, 1:].tobytes()
    with pytest.raises(IndexError):
        window.row(23)
    assert window.values.tobytes() == expected[:, 1:].tobytes()
    assert window.column(1).tobytes() == expected[:, 2].tobytes()  # from `values` now


def test_an_empty_table_and_a_refused_one(tmp_path):
    (tmp_path / "signals.csv").write_text(HEADER + "\n")
    run = load_run(tmp_path)
    assert run.time.shape == (0,) and run.signal("c.z").shape == (0,)
    lines = rows(5)
    lines[2] = "0.5,oops,1.0,2.0"
    (tmp_path / "signals.csv").write_text(HEADER + "\n" + "\n".join(lines) + "\n")
    with pytest.raises(AnalysisError, match=r"signals.csv:4: value 'oops' is not a number"):
        load_run(tmp_path)
