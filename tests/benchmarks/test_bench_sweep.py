"""Tests of bench_sweep's split of a sweep's time into a fixed part and a cost per run (no sweep is run)."""

from __future__ import annotations

import argparse

import pytest

from benchmarks import bench_sweep


def test_line_through_two_workloads_gives_fixed_part_and_cost_per_run():
    # 30 ms + 6 x 70 ms and 30 ms + 24 x 70 ms
    fixed, per_run = bench_sweep.sweep_parts((6, 24), (0.450, 1.710))
    assert fixed == pytest.approx(30.0)
    assert per_run == pytest.approx(70.0)


def test_split_per_worker_count_from_median_rates(capsys):
    args = argparse.Namespace(workers=[1, 2], samples=6, long_samples=24)
    # runs/min from sweep times: 1 worker 20 + 80 N ms, 2 workers 40 + 41 N ms
    def rate(samples: int, fixed_ms: float, per_run_ms: float) -> float:
        return samples / ((fixed_ms + samples * per_run_ms) / 1e3) * 60.0

    rates = {(6, 1): [rate(6, 20, 80)] * 3, (24, 1): [rate(24, 20, 80), 1.0, 1e6],
             (6, 2): [rate(6, 40, 41)], (24, 2): [rate(24, 40, 41)]}
    figures = bench_sweep.fixed_and_per_run(args, rates)
    assert figures["1 workers fixed ms"] == pytest.approx(20.0)
    assert figures["1 workers ms per run"] == pytest.approx(80.0)
    assert figures["2 workers fixed ms"] == pytest.approx(40.0)
    assert figures["2 workers ms per run"] == pytest.approx(41.0)
    assert figures["per-run scaling"] == pytest.approx(80.0 / 41.0)
    assert "fixed part 20 / 40 ms a sweep, 80.0 / 41.0 ms a run: the runs alone scale 1.95x" in capsys.readouterr().out


@pytest.mark.parametrize("workers, long_samples", [([1], 24), ([1, 2], 0), ([1, 2], 6)])
def test_no_split_without_both_worker_counts_and_two_workloads(workers, long_samples):
    args = argparse.Namespace(workers=workers, samples=6, long_samples=long_samples)
    assert bench_sweep.fixed_and_per_run(args, {}) == {}


def test_no_split_when_the_longer_workload_was_not_slower(capsys):
    # noise: 24 runs on 2 workers took no longer than 6, so the line has no cost per run
    args = argparse.Namespace(workers=[1, 2], samples=6, long_samples=24)
    rates = {(6, 1): [60.0], (24, 1): [120.0], (6, 2): [120.0], (24, 2): [480.0]}
    assert bench_sweep.fixed_and_per_run(args, rates) == {}
    assert "no cost per run above 0" in capsys.readouterr().out
