"""bench_zenoh's reading of its child processes: the lines they print, the median over rounds."""

from __future__ import annotations

from benchmarks import bench_zenoh


def test_a_childs_lines_are_read_and_other_output_ignored():
    text = "raw 107.0 219.4\ntick 126.3 379.6\nsome warning from a library\nraw1 32.1\n"
    assert bench_zenoh.parse_child(text) == {"raw": (107.0, 219.4), "tick": (126.3, 379.6)}


def test_rounds_combine_into_the_median_of_each_figure_and_only_cases_every_round_has():
    rounds = [{"raw": (100.0, 200.0), "tick": (120.0, 300.0), "raw1": (30.0, 80.0)},
              {"raw": (110.0, 260.0), "tick": (130.0, 390.0)},
              {"raw": (105.0, 220.0), "tick": (90.0, 310.0), "raw1": (31.0, 85.0)}]
    assert bench_zenoh.combine(rounds) == {"raw": (105.0, 220.0), "tick": (120.0, 310.0)}
    assert bench_zenoh.combine([]) == {}
