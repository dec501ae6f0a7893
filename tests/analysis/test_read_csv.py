"""Tests of `cosim.analysis.rundata.read_csv_table`'s streaming path against the line-by-line one.

A long run's signals.csv is read without holding its text (numpy reads the
file; the peak memory of the analysis then follows the floats, not the text).
The streamed table must be the one the line-by-line parse gives, bit for bit,
with the same rule for a last row cut short, and any table the streaming path
cannot take (a blank line, a bad value) must still get the line-by-line
path's message.
"""

from __future__ import annotations

import numpy as np
import pytest

from cosim.analysis import rundata
from cosim.analysis.rundata import AnalysisError, read_csv_table

HEADER = "time,a.x,b.y"


def rows(n: int, seed: int = 1) -> list[str]:
    """Lines of random floats of every magnitude, written with repr as the recorder does."""
    values = np.random.default_rng(seed).standard_normal((n, 3)) * 10.0 ** np.arange(-12, 12, 8)
    return [",".join(repr(float(v)) for v in row) for row in values]


def slow(lines: list[str]) -> np.ndarray:
    return rundata._parse_rows_slowly(None, lines, 3)


@pytest.fixture
def no_text_path(monkeypatch):
    """Fail the test if the whole-text path is taken."""
    def refuse(*args, **kwargs):
        raise AssertionError("the line-by-line path was used")
    monkeypatch.setattr(rundata, "_parse_rows", refuse)


@pytest.mark.parametrize("ending", ["\n", ""])
def test_streamed_table_is_bit_identical_to_the_line_parse(tmp_path, no_text_path, ending):
    lines = rows(3000)
    path = tmp_path / "signals.csv"
    path.write_text(HEADER + "\n" + "\n".join(lines) + ending)
    header, data = read_csv_table(path)
    assert header == HEADER.split(",")
    assert data.tobytes() == slow(lines).tobytes()   # a last row without its newline is kept


def test_a_partial_last_row_is_dropped(tmp_path, no_text_path):
    lines = rows(50)
    path = tmp_path / "signals.csv"
    path.write_text(HEADER + "\n" + "\n".join(lines) + "\n" + lines[0][:7])
    _, data = read_csv_table(path)
    assert data.tobytes() == slow(lines).tobytes()


def test_rows_spanning_many_read_blocks_are_counted(tmp_path):
    lines = rows(500)
    path = tmp_path / "signals.csv"
    path.write_text(HEADER + "\n" + "\n".join(lines) + "\n" + lines[1][:5])
    assert rundata._complete_rows(path, 3, chunk=7) == 500


def test_header_only(tmp_path, no_text_path):
    path = tmp_path / "signals.csv"
    for text in (HEADER + "\n", HEADER):
        path.write_text(text)
        assert read_csv_table(path)[1].shape == (0, 3)


def test_a_blank_line_still_gets_the_line_numbered_message(tmp_path):
    lines = rows(5)
    path = tmp_path / "signals.csv"
    path.write_text(HEADER + "\n" + "\n".join(lines[:2]) + "\n\n" + "\n".join(lines[2:]) + "\n")
    assert rundata._read_csv_streaming(path) is None
    with pytest.raises(AnalysisError, match=r"signals.csv:4: expected 3 fields, found 1"):
        read_csv_table(path)


def test_a_bad_value_still_gets_the_line_numbered_message(tmp_path):
    lines = rows(5)
    lines[3] = "0.5,oops,1.0"
    path = tmp_path / "signals.csv"
    path.write_text(HEADER + "\n" + "\n".join(lines) + "\n")
    with pytest.raises(AnalysisError, match=r"signals.csv:5: value 'oops' is not a number"):
        read_csv_table(path)
