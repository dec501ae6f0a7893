"""Recorder files with rows wider than a conversion chunk, and with signal names that
need CSV quoting or are not ASCII (foreign FMUs name their variables freely)."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest

from cosim.component import Component, Port
from cosim.engine.master import Master
from cosim.errors import UserError
from cosim.results import csv_writer
from cosim.results.csv_writer import SpoolError, read_header, rebuild_csv
from cosim.results.recorder import Recorder, read_signals
from cosim.results.recover import recover
from cosim.transport.inproc import InprocComponent, PythonComponentLaunch

WIDE = 9000  # scalar outputs: a row of 72 KB, over the writer's 64 KB chunk


class Wide(Component):
    """`WIDE` scalar outputs o0..oN, each a distinct function of t."""

    outputs = tuple(Port(f"o{i}") for i in range(WIDE))

    def step(self, t, inputs):
        return {f"o{i}": t * 1000.0 + i for i in range(WIDE)}


ODD_NAMES = ("plain", "a b,c;d", 'say "hi"', "two\nlines", "geschwindigkeit_ü_速度")


class Odd(Component):
    """Outputs named as a foreign FMU may name its variables."""

    outputs = tuple(Port(name) for name in ODD_NAMES)

    def step(self, t, inputs):
        return {name: t + k for k, name in enumerate(ODD_NAMES)}


def _run(folder, cls, ticks, **options):
    comps = {"c": InprocComponent(PythonComponentLaunch("c", f"{__name__}:{cls.__name__}", {}, 1))}
    recorder = Recorder(folder, **options)
    master = Master(comps, [], tick=0.01, total_ticks=ticks, observers=[recorder])
    try:
        master.run()
    finally:
        recorder.close()
    return recorder


@pytest.mark.parametrize("flush_interval", [0.0, 1e9])  # the writer process; the rebuild at close
def test_rows_wider_than_a_chunk_are_all_written(tmp_path, flush_interval, capsys):
    _run(tmp_path, Wide, 20, flush_interval=flush_interval)
    assert "rebuilt" not in capsys.readouterr().err
    names, data = read_signals(tmp_path / "signals.csv")
    assert len(names) == WIDE + 1 and data.shape == (21, WIDE + 1)
    t = np.arange(21) * 0.01
    assert np.array_equal(data[:, 0], t)
    assert np.array_equal(data[:, 1 + 8500], t * 1000.0 + 8500)
    assert not list(tmp_path.glob("*.f64*"))


def test_recover_rebuilds_rows_wider_than_a_chunk(tmp_path):
    _run(tmp_path, Wide, 5, keep_spool=True)
    expected = (tmp_path / "signals.csv").read_bytes()
    (tmp_path / "signals.csv").write_text("time\n")
    assert [(p.name, n) for p, n, _ in recover(tmp_path)] == [("signals.csv", 6)]
    assert (tmp_path / "signals.csv").read_bytes() == expected


def test_a_rebuild_short_of_the_spooled_rows_fails_and_keeps_the_spool(tmp_path, monkeypatch):
    _run(tmp_path, Odd, 30, keep_spool=True)
    before = (tmp_path / "signals.csv").read_bytes()
    committed = csv_writer.SpoolHeader.committed_bytes
    # the spool shrinks after its row count was read: the reads come back short
    monkeypatch.setattr(csv_writer.SpoolHeader, "committed_bytes",
                        lambda self, fd: committed(self, fd) + 4 * self.row_bytes)
    header = read_header(tmp_path / "signals.f64.json")
    with pytest.raises(SpoolError, match=r"signals\.f64: .*31 of the 35 rows"):
        rebuild_csv(header)
    with pytest.raises(UserError, match=r"signals\.f64: .*31 of the 35 rows"):
        recover(tmp_path)
    assert (tmp_path / "signals.f64").exists() and (tmp_path / "signals.f64.json").exists()
    assert (tmp_path / "signals.csv").read_bytes() == before
    assert not list(tmp_path.glob("*.tmp"))


def test_close_keeps_the_spool_when_the_rebuild_is_short(tmp_path, monkeypatch):
    from cosim.results import recorder as recorder_module

    real = recorder_module.rebuild_csv
    monkeypatch.setattr(recorder_module, "rebuild_csv", lambda h: (real(h)[0] - 1, 0))
    with pytest.raises(UserError, match=r"signals\.csv: 10 rows written, 11 expected"):
        _run(tmp_path, Odd, 10, flush_interval=1e9)
    assert (tmp_path / "signals.f64").exists()


@pytest.mark.parametrize("flush_interval", [0.0, 1e9])
def test_odd_signal_names_are_quoted_utf8_and_read_back(tmp_path, flush_interval):
    _run(tmp_path, Odd, 10, flush_interval=flush_interval)
    raw = (tmp_path / "signals.csv").read_bytes()
    header = ('time,c.plain,"c.a b,c;d","c.say ""hi""","c.two\nlines",'
              "c.geschwindigkeit_ü_速度\n").encode()
    assert raw.startswith(header)
    rows = list(csv.reader(io.StringIO(raw.decode("utf-8"), newline="")))
    assert rows[0] == ["time"] + [f"c.{n}" for n in ODD_NAMES]
    assert len(rows) == 12 and all(len(r) == 6 for r in rows)  # the header, 11 ticks
    names, data = read_signals(tmp_path / "signals.csv")
    assert names == ["time"] + [f"c.{n}" for n in ODD_NAMES]
    assert data.shape == (11, 6) and data[3, 2] == data[3, 0] + 1.0


def test_recover_rebuilds_odd_names_byte_for_byte(tmp_path):
    _run(tmp_path, Odd, 10, keep_spool=True)
    expected = (tmp_path / "signals.csv").read_bytes()
    (tmp_path / "signals.csv").unlink()
    recover(tmp_path)
    assert (tmp_path / "signals.csv").read_bytes() == expected


def test_pandas_reads_odd_names(tmp_path):
    pd = pytest.importorskip("pandas")
    _run(tmp_path, Odd, 10)
    frame = pd.read_csv(tmp_path / "signals.csv", encoding="utf-8")
    assert list(frame.columns) == ["time"] + [f"c.{n}" for n in ODD_NAMES]
    assert frame.shape == (11, 6)
