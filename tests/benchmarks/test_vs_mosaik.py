"""Tests of benchmarks/bench_vs_mosaik.py (no timing asserted): the comparison is honest only if
mosaik runs the very same loop, so its vehicle trajectory must be ours bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mosaik", reason="mosaik is in the bench extra")

from benchmarks import bench_vs_mosaik as bench  # noqa: E402


@pytest.mark.parametrize("processes", [False, pytest.param(True, marks=pytest.mark.integration)])
def test_mosaik_builds_our_loop_bit_for_bit(tmp_path, monkeypatch, processes):
    monkeypatch.setenv("PYTHONPATH", str(bench.ROOT))
    bench.run_mosaik(2.0, processes, tmp_path / "m.npy")
    bench.run_ours(2.0, "inproc", tmp_path / "ours")
    ours = bench.our_trajectory(tmp_path / "ours")
    assert ours.shape == (201, len(bench.RECORD))
    bench.check_same("mosaik", np.load(tmp_path / "m.npy"), ours)   # SystemExit if they differ


def test_a_different_trajectory_is_reported(tmp_path):
    ours = np.zeros((5, 4))
    other = ours.copy()
    other[3, 1] = 1e-300
    with pytest.raises(SystemExit, match="CHECK FAILED: .*first different tick 3"):
        bench.check_same("mosaik", other, ours)
