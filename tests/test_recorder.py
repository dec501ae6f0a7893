"""Recorder: bit-identical round trip, array files, partial files after a failure."""

from __future__ import annotations

import numpy as np
import pytest
from fmpy.util import read_csv

from cosim.component import Component, Port
from cosim.errors import ComponentFailure
from cosim.inproc import InprocComponent, PythonComponentLaunch
from cosim.master import Master
from cosim.recorder import Recorder, read_signals, selected, write_json


class Noisy(Component):
    """Awkward floats (full-precision random, tiny, huge, negative zero) and an array."""

    outputs = (Port("u"), Port("v"), Port("w", size=3))

    def __init__(self, seed: int = 1, fail_at: float = -1.0):
        self.rng = np.random.default_rng(seed)
        self.fail_at = fail_at

    def step(self, t, inputs):
        if t == self.fail_at:
            raise RuntimeError("sensor unplugged")
        a, b = self.rng.standard_normal(2)
        return {"u": a / 3.0, "v": b * 1e-300 if a > 0 else -0.0,
                "w": self.rng.standard_normal(3) * 1e200}


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


def _run(tmp_path, ticks=20, fail_at=-1.0, include=("*",), exclude=()):
    comps = {"noisy": _comp("noisy", Noisy, seed=7, fail_at=fail_at), "echo": _comp("echo", Echo, 3)}
    recorder = Recorder(tmp_path, include, exclude)
    snaps = Snapshots()
    master = Master(comps, [_edge("noisy", "u", "echo", "u")], tick=0.01, total_ticks=ticks,
                    observers=[recorder, snaps])
    try:
        master.run()
    finally:
        recorder.close()
    return master, snaps


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
    assert sorted(p.name for p in (tmp_path / "arrays").iterdir()) == ["echo.h.csv", "noisy.w.csv"]
    assert selected("a.b", ["a.*"], []) and not selected("a.b", ["a.*"], ["*.b"])


def test_partial_csv_after_failure_is_valid(tmp_path):
    with pytest.raises(ComponentFailure, match="'noisy' failed at tick 8 .*RuntimeError: sensor unplugged"):
        _run(tmp_path, ticks=20, fail_at=0.08)
    names, data = read_signals(tmp_path / "signals.csv")
    assert data.shape == (8, 4)  # ticks 0..7, every row complete
    assert data[-1, 0] == 0.07
    assert read_csv(tmp_path / "signals.csv").shape == (8,)


def test_rows_reach_the_disk_as_they_go(tmp_path):
    """With flush_interval 0 every tick is on disk before the next one runs."""
    seen = []

    class Peek:
        def begin(self, master):
            pass

        def after_tick(self, tick, t, values, arrays):
            with open(tmp_path / "signals.csv") as handle:
                seen.append(len(handle.readlines()) - 1)

    comps = {"noisy": _comp("noisy", Noisy)}
    recorder = Recorder(tmp_path, flush_interval=0.0)
    Master(comps, [], tick=0.1, total_ticks=4, observers=[recorder, Peek()]).run()
    recorder.close()
    assert seen == [1, 2, 3, 4, 5]


def test_write_json_replaces_non_finite(tmp_path):
    write_json(tmp_path / "m.json", {"a": float("nan"), "b": [1.5, float("inf")], "c": "x"})
    import json
    assert json.loads((tmp_path / "m.json").read_text()) == {"a": None, "b": [1.5, None], "c": "x"}
