"""Result formats: decimation (`record: {every: N}`) and the Parquet files.

Exact expectations: a decimated table holds the undecimated run's rows at ticks
0, N, 2N, ... and the last tick, bit for bit; an array signal its rows at ticks
that are multiples of N (and its last row); a Parquet file holds the CSV's
parsed float64 values bit for bit (-0.0, subnormals, 1e308 included), with
units and descriptions in its field metadata; the salvage of a decimated,
Parquet-asking spool writes both files, with the same rows.
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

import cosim
from cosim.component import Component, Port
from cosim.engine.master import Master
from cosim.errors import UserError
from cosim.results.csv_writer import read_header
from cosim.results.recorder import Recorder, read_signals
from cosim.results.recover import recover
from cosim.results.salvage import complete_run_folder
from cosim.scenario.models import RecordSpec
from cosim.transport.inproc import InprocComponent, PythonComponentLaunch
from tests.results.test_recorder import Echo, Noisy, _edge

TICKS = 20
UNITS = {"noisy.u": {"unit": "m", "description": "a random walk"},
         "awkward.a": {"unit": "rad", "description": "awkward floats"},
         "echo.h": {"unit": "s", "description": "time and u, every 3 ticks"}}
AWKWARD = np.array([-0.0, 5e-324, -2.5e-310, 1.7976931348623157e308, -1e308, 0.1, 1 / 3])


class Awkward(Component):
    """Floats a text format gets wrong easily: -0.0, subnormals, the largest magnitudes."""

    outputs = (Port("a"), Port("b", size=len(AWKWARD)))

    def step(self, t, inputs):
        k = int(round(t * 100))
        return {"a": float(AWKWARD[k % len(AWKWARD)]), "b": np.roll(AWKWARD, k)}


def _comp(name, cls, period=1, **params):
    module = sys.modules[cls.__module__].__name__
    return InprocComponent(PythonComponentLaunch(name, f"{module}:{cls.__name__}", params, period))


def _record(folder, ticks=TICKS, **options):
    """Run noisy -> echo (period 3) and awkward for `ticks` ticks into `folder`."""
    comps = {"noisy": _comp("noisy", Noisy, seed=7), "echo": _comp("echo", Echo, 3),
             "awkward": _comp("awkward", Awkward)}
    recorder = Recorder(folder, column_info=UNITS, **options)
    master = Master(comps, [_edge("noisy", "u", "echo", "u")], tick=0.01, total_ticks=ticks,
                    observers=[recorder])
    try:
        master.run()
    finally:
        recorder.close()
    return master, recorder


def _kept_ticks(ticks, every, period=1):
    """Ticks 0..ticks whose rows a table of `period` keeps: multiples of lcm, and its last."""
    rows = list(range(0, ticks + 1, period))
    kept = [k for k in rows if k % math.lcm(every, period) == 0]
    return kept if kept[-1] == rows[-1] else kept + [rows[-1]]


@pytest.mark.parametrize("every", [2, 7, 25])
@pytest.mark.parametrize("flush_interval", [0.0, 1e9], ids=["writer-process", "at-close"])
def test_decimated_rows_are_the_full_runs_rows_at_0_N_2N_and_the_last(tmp_path, every,
                                                                       flush_interval):
    master, _ = _record(tmp_path / "full")
    _, recorder = _record(tmp_path / "dec", every=every, flush_interval=flush_interval)
    assert (recorder.writer_pid is not None) == (flush_interval == 0.0)
    assert recorder.writer_problem is None  # the writer's row counts are the decimated ones
    for table, period in (("signals.csv", 1), ("arrays/noisy.w.csv", 1),
                          ("arrays/echo.h.csv", 3), ("arrays/awkward.b.csv", 1)):
        names, full = read_signals(tmp_path / "full" / table)
        dec_names, dec = read_signals(tmp_path / "dec" / table)
        ticks = _kept_ticks(TICKS, every, period)
        assert dec_names == names
        assert [master.time_of(k) for k in ticks] == dec[:, 0].tolist(), table
        rows = [k // period for k in ticks]
        assert dec.tobytes() == full[rows].tobytes(), table
    assert _kept_ticks(TICKS, 7) == [0, 7, 14, 20]
    assert _kept_ticks(TICKS, 2, 3) == [0, 6, 12, 18]  # echo.h: every 3 ticks, kept at 6k
    assert _kept_ticks(TICKS, 25) == [0, 20]


def test_decimated_run_keeps_every_tick_for_the_metrics(tmp_path):
    master, recorder = _record(tmp_path, every=7)
    columns, every_tick = recorder.full_signals
    _, full = read_signals(_record(tmp_path / "full")[1].out_dir / "signals.csv")
    assert columns == ["time", "noisy.u", "noisy.v", "echo.e", "awkward.a"]
    assert every_tick.shape == (TICKS + 1, 5) and every_tick.tobytes() == full.tobytes()
    assert not list(tmp_path.glob("*.f64*"))  # mapped, yet the spool is gone from the folder


def test_a_plain_run_gives_the_metrics_the_rows_of_its_csv(tmp_path):
    columns, rows = _record(tmp_path)[1].full_signals
    names, csv = read_signals(tmp_path / "signals.csv")
    assert columns == names and rows.tobytes() == csv.tobytes()


@pytest.mark.parametrize("every", [1, 3])
def test_parquet_values_are_the_csv_values_bit_for_bit(tmp_path, every):
    _record(tmp_path, every=every, formats=("csv", "parquet"))
    names, csv = read_signals(tmp_path / "signals.csv")  # float() of each field
    table = pq.read_table(tmp_path / "signals.parquet")
    assert table.column_names == names
    parquet = np.column_stack([c.to_numpy() for c in table.columns])
    assert parquet.dtype == np.float64 and parquet.shape == csv.shape
    assert np.array_equal(parquet.view(np.uint64), csv.view(np.uint64))
    awkward = parquet[:, names.index("awkward.a")]
    assert set(awkward.view(np.uint64)) >= set(AWKWARD.view(np.uint64)) or every != 1
    assert np.signbit(awkward[0]) and awkward[0] == 0.0  # -0.0 survives
    for name in ("awkward.b", "echo.h", "noisy.z"):
        element_names, csv = read_signals(tmp_path / "arrays" / f"{name}.csv")
        array = pq.read_table(tmp_path / "arrays" / f"{name}.parquet")
        assert array.column_names == ["time", name]
        values = np.column_stack([array.column(0).to_numpy(),
                                  np.stack(array.column(1).to_numpy(zero_copy_only=False))])
        assert np.array_equal(values.view(np.uint64), csv.view(np.uint64)), name
    b = pq.read_table(tmp_path / "arrays" / "awkward.b.parquet").column(1).to_numpy(
        zero_copy_only=False)
    assert np.array_equal(b[0].view(np.uint64), AWKWARD.view(np.uint64))  # subnormals, 1.8e308


def test_parquet_fields_carry_unit_and_description(tmp_path):
    _record(tmp_path, every=4, formats=("csv", "parquet"))
    schema = pq.read_schema(tmp_path / "signals.parquet")
    assert schema.field("noisy.u").metadata == {b"unit": b"m", b"description": b"a random walk"}
    assert schema.field("time").metadata[b"unit"] == b"s"
    assert schema.field("echo.e").metadata == {b"unit": b"", b"description": b""}
    assert schema.metadata[b"cosim.every"] == b"4"
    array = pq.read_schema(tmp_path / "arrays" / "echo.h.parquet")
    assert array.field("echo.h").metadata[b"description"] == b"time and u, every 3 ticks"
    assert array.metadata[b"cosim.period_ticks"] == b"3"


def _manifest(folder, every=1, formats=("csv",)):
    info = {name: {**entry, "size": 1} for name, entry in UNITS.items()}
    manifest = {"status": "running", "scenario": {"tick": 0.01}, "start_time": 0.0,
                "step_order": ["noisy", "echo", "awkward"], "signals": info,
                "recording": {"every": every, "formats": list(formats)}}
    (folder / "manifest.json").write_text(json.dumps(manifest))


def test_load_run_reads_the_parquet_files_and_gives_the_identical_frames(tmp_path, monkeypatch):
    _record(tmp_path / "both", every=3, formats=("csv", "parquet"))
    _manifest(tmp_path / "both", 3, ("csv", "parquet"))
    shutil.copytree(tmp_path / "both", tmp_path / "csv")
    for path in (tmp_path / "csv").rglob("*.parquet"):
        path.unlink()
    from_csv = cosim.load_run(tmp_path / "csv")
    frames_csv, arrays_csv = from_csv.signals, from_csv.arrays
    import cosim.analysis.rundata as rundata

    def no_csv(path):
        raise AssertionError(f"{path} read although its Parquet file is there")

    monkeypatch.setattr(rundata, "read_csv_table", no_csv)
    from_parquet = cosim.load_run(tmp_path / "both")
    frame = from_parquet.signals
    pd.testing.assert_frame_equal(frame, frames_csv, check_exact=True)
    assert frame.values.tobytes() == frames_csv.values.tobytes()
    assert frame.index.values.tobytes() == frames_csv.index.values.tobytes()
    assert frame.attrs["units"] == {**frames_csv.attrs["units"]} and \
        frame.attrs["units"]["noisy.u"] == "m"
    arrays = from_parquet.arrays
    assert sorted(arrays) == sorted(arrays_csv)
    for name, array in arrays.items():
        pd.testing.assert_frame_equal(array, arrays_csv[name], check_exact=True)
        assert array.values.tobytes() == arrays_csv[name].values.tobytes()


def _spool_only(folder, every, formats):
    """A run folder as a killed master leaves it: spools, a running manifest, no outputs."""
    _record(folder, every=every, formats=formats, keep_spool=True)
    _manifest(folder, every, formats)
    for pattern in ("*.csv", "*.parquet"):
        for path in folder.rglob(pattern):
            path.unlink()


def test_salvage_of_a_decimated_spool_writes_the_csv_and_parquet_rows(tmp_path):
    master, _ = _record(tmp_path / "full")
    _spool_only(tmp_path / "run", 6, ("csv", "parquet"))
    message = complete_run_folder(tmp_path / "run", {"kind": "signal", "signal": "SIGKILL",
                                                     "call": None})
    assert f"after tick {TICKS} (t=0.2 s)" in message
    manifest = json.loads((tmp_path / "run" / "manifest.json").read_text())
    assert manifest["status"] == "failed" and manifest["ticks"] == TICKS
    assert manifest["recording"]["formats_written"] == ["csv", "parquet"]
    _, full = read_signals(tmp_path / "full" / "signals.csv")
    names, csv = read_signals(tmp_path / "run" / "signals.csv")
    assert csv.tobytes() == full[[0, 6, 12, 18, 20]].tobytes()
    table = pq.read_table(tmp_path / "run" / "signals.parquet")
    parquet = np.column_stack([c.to_numpy() for c in table.columns])
    assert parquet.tobytes() == csv.tobytes()
    _, h = read_signals(tmp_path / "run" / "arrays" / "echo.h.csv")
    assert h[:, 0].tolist() == [master.time_of(k) for k in (0, 6, 12, 18)]
    assert not list((tmp_path / "run").rglob("*.f64*"))


def test_recover_without_pyarrow_rebuilds_the_csv_and_says_parquet_was_not(tmp_path,
                                                                           monkeypatch):
    _spool_only(tmp_path, 5, ("csv", "parquet"))
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)
    done = {p.relative_to(tmp_path).as_posix(): n for p, n, _ in recover(tmp_path)}
    assert done["signals.csv"] == 5 and done["arrays/echo.h.csv"] == 3  # 0,5,..,20; 0,15,18
    assert not list(tmp_path.rglob("*.parquet"))
    recording = json.loads((tmp_path / "manifest.json").read_text())["recording"]
    assert recording["formats_written"] == ["csv"]
    assert "pyarrow is not installed" in recording["not_written"]


def test_recover_of_a_decimated_spool_counts_its_ticks(tmp_path):
    _spool_only(tmp_path, 7, ("csv",))
    header = read_header(tmp_path / "signals.f64.json")
    assert (header.every, header.stride, header.kept(TICKS + 1)) == (7, 7, 4)
    done = {p.name: n for p, n, _ in recover(tmp_path)}
    assert done["signals.csv"] == 4
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["ticks"] == TICKS and manifest["last_time_s"] == 0.2


def test_record_every_and_format_are_checked():
    assert RecordSpec().every == 1 and RecordSpec().format == ["csv"]
    assert RecordSpec(every=10, format=["csv", "parquet"]).every == 10
    for bad, field in ((dict(every=0), "every"), (dict(every=2.0), "every"),
                       (dict(every=True), "every"), (dict(format=["parquet"]), "include 'csv'"),
                       (dict(format=["csv", "hdf5"]), "format"),
                       (dict(format=["csv", "csv"]), "twice")):
        with pytest.raises(ValueError, match=field):
            RecordSpec(**bad)
    schema = RecordSpec.model_json_schema()["properties"]
    assert "last tick" in schema["every"]["description"]
    assert "pyarrow" in schema["format"]["description"]


BLOCKED_PYARROW = """
import sys
sys.modules["pyarrow"] = None
sys.modules["pyarrow.parquet"] = None
from cosim.cli.app import main
sys.argv = ["cosim", "validate", "lane_change", "--set", "record.format=[csv, parquet]"]
sys.exit(main())
"""


def test_parquet_without_pyarrow_is_one_line_and_exit_2(tmp_path):
    done = subprocess.run([sys.executable, "-c", BLOCKED_PYARROW], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "record.format" in lines[0], done.stderr
    assert "pyarrow is not installed" in lines[0] and "[parquet]" in lines[0]


def test_check_parquet_available_names_the_field(monkeypatch):
    from cosim.results.parquet import check_parquet_available

    check_parquet_available("x.yaml: record.format")  # pyarrow is here: no error
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    with pytest.raises(UserError, match=r"^x.yaml: record.format: parquet asked for, but "
                                        r"pyarrow is not installed"):
        check_parquet_available("x.yaml: record.format")


CRASH = ("name: crash\nduration: 0.4\ntick: 0.01\n"
         "record: {every: 3, format: [csv, parquet]}\ncomponents:\n"
         "  plant:\n    python: tests.helpers.components:Segfault\n"
         "    parameters: {at: 0.2}\n"
         "sources:\n  ref: {kind: constant, value: 1.0}\n"
         "connections:\n  - ref.value -> plant.u\n")


@pytest.mark.integration
@pytest.mark.timeout(120)
def test_a_master_crash_salvages_the_decimated_csv_and_parquet(tmp_path):
    from tests.execution.test_fmu_faults import run_cosim

    done, out, left = run_cosim(tmp_path, CRASH, "--transport", "inproc")
    assert done.returncode == 1 and "killed by SIGSEGV" in done.stderr, done.stderr
    names, csv = read_signals(out / "signals.csv")  # ticks 0..19 complete: 0, 3, ..., 18, 19
    assert np.round(csv[:, 0] / 0.01).astype(int).tolist() == [0, 3, 6, 9, 12, 15, 18, 19]
    table = pq.read_table(out / "signals.parquet")
    parquet = np.column_stack([c.to_numpy() for c in table.columns])
    assert table.column_names == names and parquet.tobytes() == csv.tobytes()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "failed" and manifest["ticks"] == 19
    assert manifest["recording"]["formats_written"] == ["csv", "parquet"]
    assert not list(out.glob("*.f64*")) and left == []


@pytest.mark.integration
def test_a_decimated_run_has_the_full_runs_metrics_and_rows(tmp_path):
    shared = {"duration": 3.0, "record.exclude": ["planner.alt_*"]}
    full = cosim.run("lane_change", set=shared, out=tmp_path / "full")
    dec = cosim.run("lane_change", set={**shared, "record.every": 10,
                                        "record.format": ["csv", "parquet"]},
                    out=tmp_path / "dec")
    assert full.status == dec.status == "ok"
    assert dec.metrics == full.metrics and "max_abs_yc" in dec.metrics  # from every tick
    assert dec.manifest["recording"]["every"] == 10
    assert dec.manifest["recording"]["formats"] == ["csv", "parquet"]
    ticks = list(range(0, 301, 10))
    assert dec.signals.index.tolist() == full.signals.index[ticks].tolist()
    assert dec.signals.values.tobytes() == full.signals.iloc[ticks].values.tobytes()
    assert (tmp_path / "dec" / "signals.parquet").is_file()
    assert (tmp_path / "dec" / "signals.csv").stat().st_size * 8 < \
        (tmp_path / "full" / "signals.csv").stat().st_size
    from cosim.analysis.metrics import analyse_run
    from cosim.analysis.rundata import load_run

    again = analyse_run(load_run(tmp_path / "dec"))  # a later analysis of the folder says so
    assert any("every 10-th tick" in note for note in again.notes)



class FractionalCounter(Component):
    """An Int32 output that a careless component fills with fractions and a -0.0."""

    outputs = (Port("n", type="Int32"),)
    values = (0.0, 2.7, -0.0, -2.7, 5.0)

    def step(self, t, inputs):
        return {"n": self.values[round(t * 100) % len(self.values)]}


def test_integer_columns_reach_the_metrics_as_the_csv_has_them(tmp_path):
    recorder = Recorder(tmp_path)
    master = Master({"c": _comp("c", FractionalCounter)}, [], tick=0.01, total_ticks=9,
                    observers=[recorder])
    try:
        master.run()
    finally:
        recorder.close()
    columns, rows = recorder.full_signals
    names, csv = read_signals(tmp_path / "signals.csv")  # "%d" of each: truncated, "0" for -0.0
    assert columns == names and rows.tobytes() == csv.tobytes()
    assert sorted(set(rows[:, 1].tolist())) == [-2.0, 0.0, 2.0, 5.0]
