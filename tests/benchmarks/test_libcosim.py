"""Tests of benchmarks/bench_vs_libcosim.py and benchmarks/common.py (no timing asserted).

What is checked is what makes the comparison honest: libcosim and our loops
run the same FMU to the same final state (bit for bit with libcosim's time
arithmetic, to 1e-9 through the master), the recorder's last row is the
master's final state, and an unusable libcosim is reported with its reason
and exit status 0.
"""

from __future__ import annotations

import sys

import pytest

from benchmarks import bench_vs_libcosim as bench
from benchmarks.common import interleaved, min_and_median
from cosim.fmu.interface import describe_fmu
from cosim.results.recorder import read_signals
from tests.helpers.fmus import built_fmu

STEPS = 300


@pytest.fixture(scope="module")
def vehicle(fmu_dir):
    """(fmu path, interface) of the Vehicle8DOF FMI 2.0 FMU the test session shares."""
    fmu, _ = built_fmu(fmu_dir, bench.MODEL, 2)
    return fmu, describe_fmu(fmu)


@pytest.fixture(scope="module")
def lib():
    """libcosimpy, loaded as the benchmark loads it (skip when not installed)."""
    pytest.importorskip("libcosimpy")
    return bench.load_libcosim()


def test_interleaved_alternates_cases_and_keeps_samples():
    calls = []

    def case(label, value):
        def run():
            calls.append(label)
            return value + len(calls)
        return run

    samples = interleaved({"a": case("a", 10.0), "b": case("b", 20.0)}, 3)
    assert calls == ["a", "b", "a", "b", "a", "b"]
    assert samples == {"a": [11.0, 13.0, 15.0], "b": [22.0, 24.0, 26.0]}
    assert min_and_median([3.0, 1.0, 2.0, 8.0]) == (1.0, 2.5)
    with pytest.raises(ValueError, match="repeats must be >= 1, got 0"):
        interleaved({"a": case("a", 0.0)}, 0)


def test_direct_loop_matches_libcosim_bit_for_bit(vehicle, lib, tmp_path):
    fmu, interface = vehicle
    outputs = [p.name for p in interface.outputs]
    _, libcosim = bench.run_libcosim(lib, fmu, outputs, STEPS)
    _, direct = bench.run_direct(fmu, interface, STEPS, tmp_path)
    assert direct == libcosim
    # the inputs really acted: torque 150 N.m accelerates from vx0 = 10, delta > 0 turns left
    assert libcosim["vx"] > 10.0 and libcosim["y"] > 0.0 and libcosim["r"] > 0.0
    assert libcosim["x"] == pytest.approx(STEPS * bench.H * 10.0, rel=0.1)


def test_master_agrees_with_libcosim_and_recorder_holds_final_state(vehicle, lib, tmp_path):
    fmu, interface = vehicle
    outputs = [p.name for p in interface.outputs]
    _, libcosim = bench.run_libcosim(lib, fmu, outputs, STEPS)
    _, plain = bench.run_master(fmu, interface, STEPS)
    _, recorded = bench.run_master(fmu, interface, STEPS, tmp_path)
    assert plain == recorded
    worst, relative = bench.max_difference(plain, libcosim)
    assert relative <= bench.AGREEMENT
    names, rows = read_signals(tmp_path / "signals.csv")
    assert rows.shape[0] == STEPS + 1  # tick 0 (initialization) to tick STEPS
    assert rows[-1, 0] == pytest.approx(STEPS * bench.H, abs=1e-12)
    assert {n: rows[-1, names.index(f"vehicle.{n}")] for n in outputs} == plain


def test_check_finals_names_each_dishonest_result():
    state = {"vx": 12.0, "x": 30.0}
    good = {bench.MASTER: [state], bench.RECORDED: [state], bench.LIBCOSIM: [state, state],
            bench.DIRECT: [state]}
    assert bench.check_finals(good) == []
    off = {**state, "x": 30.0 + 1e-6}
    bad = {**good, bench.RECORDED: [off], bench.DIRECT: [off], bench.LIBCOSIM: [state, off]}
    problems = bench.check_finals(bad)
    assert len(problems) == 3
    assert problems[0].startswith(f"{bench.LIBCOSIM}: the repeats ended in different states")
    assert "differs from libcosim (max |diff| 1e-06)" in problems[1]
    assert problems[2].startswith(f"{bench.RECORDED} disagrees with libcosim: max |diff| 1e-06")


def test_full_run_prints_every_case_and_the_verdict(lib, capsys):
    assert bench.main(["--steps", "50", "--repeats", "2"]) == 0
    out = capsys.readouterr().out
    for label in (bench.MASTER, bench.RECORDED, bench.LIBCOSIM, bench.LIBCOSIM_BARE, bench.DIRECT):
        assert label in out
    assert "direct loop == libcosim bit for bit" in out
    assert "target (DESIGN.md): master at least 2x faster per step than libcosim: " in out


def test_fmi3_fmu_is_reported_with_libcosims_reason(lib, capsys):
    assert bench.main(["--fmi", "3", "--steps", "2", "--repeats", "1"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("libcosim comparison not run: libcosim cannot load Vehicle8DOF-fmi3.fmu: ")
    assert "Unsupported FMI version" in out


def test_missing_libcosimpy_is_reported_and_exits_0(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "libcosimpy", None)  # makes the import fail
    assert bench.main(["--steps", "2", "--repeats", "1"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("libcosim comparison not run: libcosimpy cannot be imported (")
    assert "pip install libcosimpy" in out
