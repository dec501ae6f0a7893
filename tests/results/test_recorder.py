"""Recorder: bit-identical round trip, array files, partial files after a failure,
the spool and its writer process (CSV bytes equal to the direct repr formatting),
recovery after the master process is killed."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from fmpy.util import read_csv

from cosim.component import Component, Port
from cosim.errors import ComponentFailure
from cosim.transport.inproc import InprocComponent, PythonComponentLaunch
from cosim.engine.master import Master
from cosim.results.csv_writer import RowFormatter, format_rows, read_header
from cosim.errors import UserError
from cosim.engine import one_cpu
from cosim.results import recorder as recorder_module
from cosim.results.recorder import Recorder, read_signals, selected, write_json
from cosim.results.recover import recover
from tests.helpers.paths import REPO_ROOT


class Noisy(Component):
    """Awkward floats (full-precision random, tiny, huge, negative zero) and arrays,
    one of them held for 4 ticks at a time with zeros of alternating sign."""

    outputs = (Port("u"), Port("v"), Port("w", size=3), Port("z", size=2))

    def __init__(self, seed: int = 1, fail_at: float = -1.0):
        self.rng = np.random.default_rng(seed)
        self.fail_at = fail_at

    def step(self, t, inputs):
        if t == self.fail_at:
            raise RuntimeError("sensor unplugged")
        a, b = self.rng.standard_normal(2)
        return {"u": a / 3.0, "v": b * 1e-300 if a > 0 else -0.0,
                "w": self.rng.standard_normal(3) * 1e200,
                "z": np.array([int(t * 25), -0.0 if int(t * 25) % 2 else 0.0])}


class Echo(Component):
    """Reads u at a slower period (array outputs recorded per step)."""

    inputs = (Port("u"),)
    outputs = (Port("e"), Port("h", size=2))

    def step(self, t, inputs):
        return {"e": inputs["u"], "h": np.array([t, inputs["u"]])}


class Snapshots:
    """Observer keeping a copy of the signal store after every tick."""

    def __init__(self):
        self.rows = []

    def begin(self, master):
        self.master = master

    def after_tick(self, tick, t, values, arrays):
        self.rows.append((t, list(values), arrays.copy()))


def _comp(name, cls, period=1, **params):
    return InprocComponent(PythonComponentLaunch(name, f"{__name__}:{cls.__name__}", params, period))


def _edge(src, sp, dst, dp):
    from types import SimpleNamespace
    return SimpleNamespace(src=src, src_port=sp, dst=dst, dst_port=dp, delay=0)


def _run(tmp_path, ticks=20, fail_at=-1.0, include=("*",), exclude=(), extra=(), **options):
    comps = {"noisy": _comp("noisy", Noisy, seed=7, fail_at=fail_at), "echo": _comp("echo", Echo, 3)}
    recorder = Recorder(tmp_path, include, exclude, **options)
    snaps = Snapshots()
    snaps.recorder = recorder
    master = Master(comps, [_edge("noisy", "u", "echo", "u")], tick=0.01, total_ticks=ticks,
                    observers=[recorder, snaps, *extra])
    try:
        master.run()
    finally:
        recorder.close()
    return master, snaps


def legacy_csv(columns, rows):
    """The CSV as the first recorder formatted it in the master's loop (the reference).

    Args:
        columns: column names, "time" first.
        rows: (t, list of Python floats) per row.
    """
    lines = [",".join(columns) + "\n"]
    lines += [",".join([repr(t), *map(repr, row)]) + "\n" for t, row in rows]
    return "".join(lines).encode("ascii")


def expected_files(master, snaps, ticks=None):
    """Reference bytes of signals.csv and of each arrays/ file for the snapshots."""
    out = master.layout.outputs
    rows = snaps.rows if ticks is None else snaps.rows[:ticks]
    scalars = [("noisy", "u"), ("noisy", "v"), ("echo", "e")]
    files = {"signals.csv": legacy_csv(
        ["time"] + [f"{c}.{s}" for c, s in scalars],
        [(t, [v[out[key][0]] for key in scalars]) for t, v, _ in rows])}
    for comp, sig, period in (("noisy", "w", 1), ("noisy", "z", 1), ("echo", "h", 3)):
        off, size = out[(comp, sig)]
        files[f"arrays/{comp}.{sig}.csv"] = legacy_csv(
            ["time"] + [f"{comp}.{sig}[{i}]" for i in range(size)],
            [(t, a[off:off + size].tolist()) for k, (t, _, a) in enumerate(rows) if k % period == 0])
    return files


def test_round_trip_is_bit_identical(tmp_path):
    master, snaps = _run(tmp_path)
    names, data = read_signals(tmp_path / "signals.csv")
    assert names == ["time", "noisy.u", "noisy.v", "echo.e"]
    assert data.shape == (21, 4)
    out = master.layout.outputs
    expected = np.array([[t, v[out[("noisy", "u")][0]], v[out[("noisy", "v")][0]],
                          v[out[("echo", "e")][0]]] for t, v, _ in snaps.rows])
    assert data.tobytes() == expected.tobytes()  # bit-identical, -0.0 and 1e-300 included
    v = data[:, 2]
    assert np.any(np.signbit(v) & (v == 0.0)) and np.any((v != 0.0) & (np.abs(v) < 1e-299))
    assert data[5, 0] == 0.05 and data[5, 0] == master.time_of(5)


def test_readable_by_numpy_and_fmpy(tmp_path):
    _run(tmp_path, ticks=5)
    traj = read_csv(tmp_path / "signals.csv")
    _, data = read_signals(tmp_path / "signals.csv")
    assert np.array_equal(traj["noisy.u"], data[:, 1])
    loaded = np.loadtxt(tmp_path / "signals.csv", delimiter=",", skiprows=1)
    assert loaded.tobytes() == data.tobytes()


def test_array_files_one_row_per_step(tmp_path):
    master, snaps = _run(tmp_path, ticks=10)
    names, echo_h = read_signals(tmp_path / "arrays" / "echo.h.csv")
    assert names == ["time", "echo.h[0]", "echo.h[1]"]
    # echo has a period of 3 ticks: rows at ticks 0, 3, 6, 9; h = [t, u(t)]
    assert echo_h[:, 0].tolist() == [master.time_of(k) for k in (0, 3, 6, 9)]
    assert np.array_equal(echo_h[:, 0], echo_h[:, 1])
    _, noisy_w = read_signals(tmp_path / "arrays" / "noisy.w.csv")
    off = master.layout.outputs[("noisy", "w")][0]
    assert noisy_w[:, 1:].tobytes() == np.array([a[off:off + 3] for _, _, a in snaps.rows]).tobytes()


def test_include_exclude_globs(tmp_path):
    _run(tmp_path, ticks=2, include=["noisy.*", "echo.h"], exclude=["*.v"])
    names, _ = read_signals(tmp_path / "signals.csv")
    assert names == ["time", "noisy.u"]
    assert sorted(p.name for p in (tmp_path / "arrays").iterdir()) == [
        "echo.h.csv", "noisy.w.csv", "noisy.z.csv"]
    assert selected("a.b", ["a.*"], []) and not selected("a.b", ["a.*"], ["*.b"])


def test_partial_csv_after_failure_is_valid(tmp_path):
    with pytest.raises(ComponentFailure, match="'noisy' failed at tick 8 .*RuntimeError: sensor unplugged"):
        _run(tmp_path, ticks=20, fail_at=0.08)
    names, data = read_signals(tmp_path / "signals.csv")
    assert data.shape == (8, 4)  # ticks 0..7, every row complete
    assert data[-1, 0] == 0.07
    assert read_csv(tmp_path / "signals.csv").shape == (8,)


def _spooled_rows(folder, stem="signals"):
    """The complete rows of a spool as another process sees them (count, then data)."""
    header = read_header(folder / f"{stem}.f64.json")
    fd = os.open(header.spool_path, os.O_RDONLY)
    try:
        data = os.pread(fd, header.committed_bytes(fd), header.data_offset)
    finally:
        os.close(fd)
    return np.frombuffer(data, dtype=np.float64).reshape(-1, len(header.columns))


def test_rows_reach_the_spool_as_they_go(tmp_path):
    """Every tick's raw row is in the kernel (row count included) before the next tick runs."""
    seen = []

    class Peek:
        def begin(self, master):
            pass

        def after_tick(self, tick, t, values, arrays):
            rows = _spooled_rows(tmp_path)
            seen.append((len(rows), rows[-1].tolist() == [t, *values[:2]]))

    comps = {"noisy": _comp("noisy", Noisy)}
    recorder = Recorder(tmp_path, flush_interval=1e9)
    Master(comps, [], tick=0.1, total_ticks=4, observers=[recorder, Peek()]).run()
    recorder.close()
    assert seen == [(k, True) for k in range(1, 6)]  # rows of time, noisy.u, noisy.v
    assert not list(tmp_path.rglob("*.f64*"))  # spools removed once the CSV is complete
    assert read_signals(tmp_path / "signals.csv")[1].shape == (5, 3)


def test_write_json_replaces_non_finite(tmp_path):
    write_json(tmp_path / "m.json", {"a": float("nan"), "b": [1.5, float("inf")], "c": "x"})
    import json
    assert json.loads((tmp_path / "m.json").read_text()) == {"a": None, "b": [1.5, None], "c": "x"}


class WriterAtTick1:
    """Observer after the recorder: its writer process at tick 1, before the first
    housekeeping (row 16) could start it, so only tick 0 did."""

    seen = False
    pid: int | None = None

    def begin(self, master):
        self.recorder = master.observers[0]

    def after_tick(self, tick, t, values, arrays):
        if tick == 1:
            self.seen, self.pid = True, self.recorder.writer_pid


@pytest.mark.parametrize("threshold, at_tick0", [(1, True), (10**9, False)])
def test_a_long_run_starts_its_writer_at_tick_0_a_short_one_converts_at_close(
        tmp_path, threshold, at_tick0, monkeypatch):
    monkeypatch.setattr(one_cpu, "cpus_beside", lambda: {1})  # a CPU free beside the loop's
    monkeypatch.setattr(recorder_module, "WRITER_AT_ONCE_VALUES", threshold)
    writer = WriterAtTick1()
    master, snaps = _run(tmp_path, ticks=60, extra=[writer])
    assert (writer.pid is not None) == at_tick0
    assert (tmp_path / "signals.csv").read_bytes() == expected_files(master, snaps)["signals.csv"]


def test_a_long_run_on_one_cpu_of_its_own_keeps_its_writer_for_later(tmp_path, monkeypatch):
    monkeypatch.setattr(one_cpu, "cpus_beside", set)  # a sweep worker on its own CPU
    monkeypatch.setattr(recorder_module, "WRITER_AT_ONCE_VALUES", 1)
    writer = WriterAtTick1()
    _run(tmp_path, ticks=60, extra=[writer])
    assert writer.seen and writer.pid is None


@pytest.mark.parametrize("every", [1, 7])
def test_the_values_a_run_will_write_are_counted_ahead(tmp_path, every):
    master, snaps = _run(tmp_path, ticks=100, every=every)
    written = sum((len(lines) - 1) * len(lines[0].split(","))
                  for csv in tmp_path.rglob("*.csv")
                  for lines in [csv.read_text().splitlines()])
    assert snaps.recorder._values_to_write(100) == written > 0


@pytest.mark.parametrize("flush_interval", [0.0, 1e9], ids=["writer-process", "at-close"])
def test_csv_bytes_equal_the_direct_repr_formatting(tmp_path, flush_interval):
    """Through the writer process (tailing as the run goes) or converted at close:
    every CSV byte equals the original in-loop repr formatting of the same data."""
    master, snaps = _run(tmp_path, ticks=3000, flush_interval=flush_interval)
    recorder = snaps.recorder
    assert (recorder.writer_pid is not None) == (flush_interval == 0.0)
    assert recorder.writer_problem is None
    for name, expected in expected_files(master, snaps).items():
        assert (tmp_path / name).read_bytes() == expected, name
    assert not list(tmp_path.rglob("*.f64*"))


def test_rows_across_many_spool_windows_and_a_replaced_array_buffer(tmp_path, monkeypatch):
    """Windows of one page (rows straddle none: each window holds whole rows), and a store
    whose array buffer is a new object from tick 7 on: every CSV byte as the reference."""
    import cosim.results.recorder as recorder_module

    monkeypatch.setattr(recorder_module, "WINDOW_BYTES", 1)

    class NewBuffer:
        def begin(self, master):
            self.master = master

        def after_tick(self, tick, t, values, arrays):
            if tick == 6:
                self.master.arrays = self.master.arrays.copy()

    master, snaps = _run(tmp_path, ticks=600, extra=[NewBuffer()], flush_interval=1e9)
    assert snaps.recorder._arrays_seen is master.arrays
    for name, expected in expected_files(master, snaps).items():
        assert (tmp_path / name).read_bytes() == expected, name


def test_spool_windows_reserve_about_the_rows_the_run_writes(tmp_path, monkeypatch):
    """Each table's windows are sized to the rows its run's ticks give it (whole rows and
    pages): a short run reserves less than a whole window per table, every CSV byte as
    the reference."""
    import cosim.results.recorder as recorder_module

    reserved: dict[int, int] = {}
    real_allocate = os.posix_fallocate

    def allocate(fd, offset, length):
        reserved[fd] = max(reserved.get(fd, 0), offset + length)
        return real_allocate(fd, offset, length)

    monkeypatch.setattr(recorder_module.os, "posix_fallocate", allocate)
    master, snaps = _run(tmp_path, ticks=300, flush_interval=1e9, keep_spool=True)
    for table in snaps.recorder._tables:
        needed = recorder_module.DATA_OFFSET + table.rows * table.row_bytes
        assert table.rows == 300 // table.period + 1
        assert table.header.spool_path.stat().st_size == needed  # cut to its rows
    assert len(reserved) == len(snaps.recorder._tables)
    for table in snaps.recorder._tables:
        assert table.step < table.largest_window  # a whole window would be more than the rows
    assert sorted(reserved.values()) == sorted(
        recorder_module.DATA_OFFSET + -(-t.rows * t.row_bytes // t.step) * t.step
        for t in snaps.recorder._tables)
    for name, expected in expected_files(master, snaps).items():
        assert (tmp_path / name).read_bytes() == expected, name


def test_rows_beyond_the_expected_ones_go_into_further_windows(tmp_path, monkeypatch):
    """A table told to expect fewer rows than it gets keeps every row (windows of
    `WINDOW_BYTES` after the expected ones)."""
    import cosim.results.recorder as recorder_module
    from cosim.results.recorder import _Table

    monkeypatch.setattr(recorder_module, "WINDOW_BYTES", 3 * 4096)
    table = _Table(tmp_path, "t", ["time", "x"], {"every": 1, "formats": ("csv",), "meta": ({}, {})},
                   expected_rows=10)
    assert table._window_size(0) == table.step  # 10 rows of 16 bytes: one page
    for row in range(2000):  # 32 kB: past the expected page, then windows of three pages
        at = table.make_room() if table.at > table.room else table.at  # as `after_tick` does
        table.window[at:at + 16] = np.array([row, -row], dtype=np.float64).tobytes()
        table.at += 16
        table.rows = table.count[0] = row + 1
    table.close()
    data = np.fromfile(table.header.spool_path, dtype=np.float64, offset=recorder_module.DATA_OFFSET)
    assert data.reshape(-1, 2)[:, 0].tolist() == list(range(2000))


@pytest.mark.parametrize("populate", ["one-page", "kernel-refuses"])
def test_pages_faulted_in_ahead_of_the_rows_or_not(tmp_path, monkeypatch, populate):
    """The spool's pages made ready ahead of the rows a page at a time (rows straddle
    pages), or by the rows' own writes when madvise is refused (an older kernel):
    every CSV byte as the reference either way."""
    import cosim.results.recorder as recorder_module

    monkeypatch.setattr(recorder_module, "POPULATE_BYTES", 4096)
    if populate == "kernel-refuses":
        monkeypatch.setattr(recorder_module, "MADV_POPULATE_WRITE", -1)  # EINVAL
    master, snaps = _run(tmp_path, ticks=700, flush_interval=1e9)
    tables = snaps.recorder._tables
    assert all(t.populate == (populate == "one-page") for t in tables)
    assert all(t.ready >= t.at and t.ready % 4096 == 0 for t in tables)
    for name, expected in expected_files(master, snaps).items():
        assert (tmp_path / name).read_bytes() == expected, name


def test_csv_grows_while_the_run_goes(tmp_path):
    """The writer process converts the spool during the run, not only at close."""
    grown = []

    class WaitForWriter:
        def begin(self, master):
            pass

        def after_tick(self, tick, t, values, arrays):
            if tick == 200:  # give the writer up to 60 s to catch up with 150 rows
                end = time.monotonic() + 60
                while len(read_signals(tmp_path / "signals.csv")[1]) < 150 and time.monotonic() < end:
                    time.sleep(0.02)
                grown.append(len(read_signals(tmp_path / "signals.csv")[1]))

    master, snaps = _run(tmp_path, ticks=300, flush_interval=0.0, extra=[WaitForWriter()])
    assert grown[0] >= 150
    assert (tmp_path / "signals.csv").read_bytes() == expected_files(master, snaps)["signals.csv"]


def test_a_dead_writer_is_replaced_by_a_rebuild_at_close(tmp_path, capsys):
    class KillWriter:
        def begin(self, master):
            self.recorder = next(o for o in master.observers if isinstance(o, Recorder))

        def after_tick(self, tick, t, values, arrays):
            if tick == 50:
                os.kill(self.recorder.writer_pid, signal.SIGKILL)

    master, snaps = _run(tmp_path, ticks=400, flush_interval=0.0, extra=[KillWriter()])
    assert "exited with status -9" in snaps.recorder.writer_problem
    assert "CSV files rebuilt from the spools" in capsys.readouterr().err
    for name, expected in expected_files(master, snaps).items():
        assert (tmp_path / name).read_bytes() == expected, name


def test_keep_spool_and_recover_rebuild_the_same_bytes(tmp_path):
    _run(tmp_path, ticks=30, keep_spool=True)
    before = {p: p.read_bytes() for p in tmp_path.rglob("*.csv")}
    header = json.loads((tmp_path / "signals.f64.json").read_text())
    assert header["columns"] == ["time", "noisy.u", "noisy.v", "echo.e"]
    assert (tmp_path / "signals.f64").stat().st_size == 4096 + 31 * 4 * 8  # cut to its rows
    done = recover(tmp_path, keep_spool=True)
    assert sorted((p.relative_to(tmp_path).as_posix(), rows, cut) for p, rows, cut in done) == [
        ("arrays/echo.h.csv", 11, 0), ("arrays/noisy.w.csv", 31, 0), ("arrays/noisy.z.csv", 31, 0),
        ("signals.csv", 31, 0)]
    assert {p: p.read_bytes() for p in tmp_path.rglob("*.csv")} == before
    assert (tmp_path / "signals.f64").exists() and (tmp_path / "arrays" / "echo.h.f64.json").exists()


KILLED_MASTER = """
import sys
sys.path[:0] = [{root!r}]
import tests.results.test_recorder as t
from cosim.engine.master import Master
from cosim.results.recorder import Recorder
recorder = Recorder(sys.argv[1], flush_interval=0.0)
comps = {{"noisy": t._comp("noisy", t.Noisy, seed=7), "echo": t._comp("echo", t.Echo, 3)}}
Master(comps, [t._edge("noisy", "u", "echo", "u")], tick=0.01, total_ticks=10**8,
       observers=[recorder]).run()
"""


def _writer_processes(folder):
    """PIDs of CSV writer processes working on `folder`."""
    found = []
    for proc in Path("/proc").iterdir():
        try:
            cmdline = (proc / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if any(b"csv_writer.py" in a for a in cmdline) and any(str(folder).encode() in a for a in cmdline):
            found.append(int(proc.name))
    return found


def _wait(condition, what, timeout_s=60.0):
    end = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < end, f"timed out waiting for {what}"
        time.sleep(0.05)


def test_killed_master_leaves_a_spool_that_recover_turns_into_the_csv(tmp_path):
    out = tmp_path / "run"
    script = KILLED_MASTER.format(root=str(REPO_ROOT))
    master_proc = subprocess.Popen([sys.executable, "-c", script, str(out)])
    try:
        _wait(lambda: (out / "signals.f64").exists() and len(_spooled_rows(out)) >= 300,
              "300 spooled rows")  # the spool: its header is written just before it
        master_proc.send_signal(signal.SIGKILL)
        master_proc.wait()
        # the orphaned writer sees its stdin close, converts what is on disk and leaves
        _wait(lambda: not _writer_processes(out), "the writer process to finish")
    finally:
        if master_proc.poll() is None:
            master_proc.kill()
            master_proc.wait()
    rows = len(_spooled_rows(out))
    master, snaps = _run(tmp_path / "reference", ticks=rows - 1)
    expected = expected_files(master, snaps)
    assert (out / "signals.csv").read_bytes() == expected["signals.csv"]
    done = {p.relative_to(out).as_posix(): (n, cut) for p, n, cut in recover(out)}
    assert done["signals.csv"] == (rows, 0)  # the count says which rows are complete
    for name, data in expected.items():
        got = (out / name).read_bytes()
        assert data.startswith(got) and got.count(b"\n") - 1 == done[name][0], name
    assert not list(out.rglob("*.f64*"))
    with pytest.raises(UserError, match="no recording spool"):
        recover(out)


def test_recover_names_the_file_and_field_of_a_bad_spool(tmp_path):
    with pytest.raises(UserError, match=r"no recording spool \(\*\.f64"):
        recover(tmp_path)
    with pytest.raises(UserError, match="not a folder"):
        recover(tmp_path / "missing")
    header = tmp_path / "signals.f64.json"
    header.write_text(json.dumps({"format": "cosim-spool-f64", "csv": "signals.csv",
                                  "columns": ["time", ""], "byteorder": "little"}))
    with pytest.raises(UserError, match=r"signals\.f64\.json: columns: .*\['time', ''\]"):
        recover(tmp_path)
    header.write_text(json.dumps({"format": "cosim-spool-f64", "csv": "signals.csv",
                                  "columns": ["time", "a"], "byteorder": "little"}))
    with pytest.raises(UserError, match=r"signals\.f64: cannot read the spool"):
        recover(tmp_path)
    header.write_text("{not json")
    with pytest.raises(UserError, match=r"signals\.f64\.json: unreadable spool header"):
        recover(tmp_path)


def test_cosim_recover_command(tmp_path, capsys):
    from cosim.cli.app import main

    _run(tmp_path, ticks=9, keep_spool=True)
    (tmp_path / "signals.csv").unlink()
    assert main(["recover", str(tmp_path)]) == 0
    assert "signals.csv: 10 rows" in capsys.readouterr().out
    assert read_signals(tmp_path / "signals.csv")[1].shape == (10, 4)
    assert main(["recover", str(tmp_path)]) == 2
    assert "no recording spool" in capsys.readouterr().err


def test_format_rows_is_repr_for_any_float_and_byte_order():
    rng = np.random.default_rng(3)
    values = np.frombuffer(rng.bytes(8 * 60000), dtype=np.float64)
    special = [0.0, -0.0, 5e-324, -1.7976931348623157e308, 0.1, 1 / 3, 1e16, 2.0 ** 70, 1e-7, 12.5]
    values = np.concatenate([values[np.isfinite(values)], special])
    values = values[:len(values) // 6 * 6]
    expected = "".join(",".join(map(repr, row)) + "\n" for row in values.reshape(-1, 6).tolist())
    assert format_rows(values.tobytes(), 6) == expected
    other = "big" if sys.byteorder == "little" else "little"
    assert format_rows(values.byteswap().tobytes(), 6, other) == expected


def test_a_repeated_row_reuses_its_text_only_when_bit_identical():
    rows = [[0.0, 1.5, -0.0], [0.01, 1.5, -0.0], [0.02, 1.5, 0.0], [0.03, 1.5, 0.0], [0.04, 2.5, 0.0]]
    data = np.array(rows).tobytes()
    expected = "".join(",".join(map(repr, row)) + "\n" for row in rows)
    assert format_rows(data, 3) == expected  # -0.0 and 0.0 are equal floats, not the same text
    formatter = RowFormatter(3)
    assert formatter.format(data[:48]) + formatter.format(data[48:]) == expected  # split stream
    assert format_rows(np.array([1.0, 2.0, 2.0]).tobytes(), 1) == "1.0\n2.0\n2.0\n"


def test_a_stalled_writer_is_killed_and_the_csv_rebuilt(tmp_path, monkeypatch):
    import cosim.results.recorder

    monkeypatch.setattr(cosim.results.recorder, "WRITER_STALL_S", 1.0)

    class StopWriter:
        def begin(self, master):
            self.recorder = next(o for o in master.observers if isinstance(o, Recorder))

        def after_tick(self, tick, t, values, arrays):
            if tick == 20:
                os.kill(self.recorder.writer_pid, signal.SIGSTOP)

    master, snaps = _run(tmp_path, ticks=100, flush_interval=0.0, extra=[StopWriter()])
    assert snaps.recorder.writer_problem == "CSV writer process made no progress for 1 s"
    assert not _writer_processes(tmp_path)
    for name, expected in expected_files(master, snaps).items():
        assert (tmp_path / name).read_bytes() == expected, name


def test_close_reads_the_writer_report_in_pieces_up_to_its_exit(tmp_path):
    """The report is read from the pipe as it comes, in as many pieces as the writer
    writes it, up to the end of the pipe."""
    from cosim.results.recorder import _read_while_progressing

    code = ("import sys, time; sys.stdout.write('{\"rows\"'); sys.stdout.flush(); "
            "time.sleep(0.2); print(': {}}')")
    process = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE)
    assert _read_while_progressing(process, [tmp_path / "none.csv"]) == b'{"rows": {}}\n'
    process.wait()


def test_a_writer_that_cannot_start_leaves_the_conversion_to_close(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sys, "executable", str(tmp_path / "no-python"))
    master, snaps = _run(tmp_path / "run", ticks=40, flush_interval=0.0)
    assert snaps.recorder.writer_pid is None
    assert snaps.recorder.writer_problem.startswith("CSV writer process not started:")
    assert "CSV files rebuilt from the spools" in capsys.readouterr().err
    for name, expected in expected_files(master, snaps).items():
        assert (tmp_path / "run" / name).read_bytes() == expected, name


def test_recover_reads_an_older_spool_without_row_count_and_drops_a_torn_row(tmp_path):
    header = tmp_path / "signals.f64.json"
    header.write_text(json.dumps({"format": "cosim-spool-f64", "csv": "signals.csv",
                                  "columns": ["time", "a"], "byteorder": sys.byteorder}))
    rows = np.array([[0.0, 1.5], [0.1, -2.25]])
    (tmp_path / "signals.f64").write_bytes(rows.tobytes() + b"\x01" * 5)
    done = [(p.name, n, cut) for p, n, cut in recover(tmp_path)]
    assert done == [("signals.csv", 2, 5)]
    assert (tmp_path / "signals.csv").read_text() == "time,a\n0.0,1.5\n0.1,-2.25\n"


def test_the_writer_converts_a_backlog_in_bounded_pieces(tmp_path):
    """However far behind the writer process is (a long run on a busy machine), one pump
    reads at most CHUNK_BYTES of spool: its memory does not grow with the run's duration."""
    from cosim.results import csv_writer

    columns = ["time", "a", "b", "c"]
    spool = tmp_path / "t.f64"
    header = csv_writer.write_header(spool, "t.csv", columns, data_offset=0)  # rows from byte 0
    values = np.arange(4.0 * 20000).reshape(20000, 4) / 7.0
    spool.write_bytes(values.tobytes())
    header.csv_path.write_text(header.csv_header_line())
    tail = csv_writer.SpoolTail(header)
    pumped = [tail.pump() for _ in range(3)]
    tail.drain()
    tail.close()
    assert max(pumped) * header.row_bytes <= csv_writer.CHUNK_BYTES and pumped[0] > 0
    assert tail.rows == 20000
    assert header.csv_path.read_text() == header.csv_header_line() + format_rows(values.tobytes(), 4)


def test_a_rebuilt_csv_keeps_the_integer_columns_of_its_spool_header(tmp_path):
    """`cosim recover` and the recorder's fallback (rebuild_csv) read the header's
    integer_columns: an integer signal is "3" there too, not "3.0"."""
    from cosim.results import csv_writer

    spool = tmp_path / "t.f64"
    csv_writer.write_header(spool, "t.csv", ["time", "a", "n"], data_offset=0,
                            integer_columns=("n",))
    spool.write_bytes(np.array([[0.0, 0.5, 3.0], [0.1, 1.5, -4.0]]).tobytes())
    header = read_header(spool.with_name("t.f64.json"))
    assert header.integer_columns == ("n",)
    assert csv_writer.rebuild_csv(header) == (2, 0)
    assert header.csv_path.read_text() == "time,a,n\n0.0,0.5,3\n0.1,1.5,-4\n"
    data = json.loads(header.path.read_text())
    header.path.write_text(json.dumps({**data, "integer_columns": ["time"]}))
    with pytest.raises(csv_writer.SpoolError, match="integer_columns: expected a list of "
                                                    "columns after the time, got"):
        read_header(header.path)
