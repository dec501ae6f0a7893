"""Tests of benchmarks/run_all.py's table writer and of the row readers (no benchmark is run, no timing).

The README's performance section is whatever `readme_block` writes between
the markers, so its format is checked here: the markers, one Markdown table
row per figure with the same number of cells as the header, a failed
benchmark still in the table with its reason, and a replacement that keeps
the rest of the README byte for byte.
"""

from __future__ import annotations

import json

import pytest

from benchmarks import run_all, run_all_rows
from benchmarks.common import RESULT_PREFIX, emit_results, table_row

WHEN, MACHINE = "2026-01-01 00:00 UTC", "2 cores (test CPU)"


def outcomes() -> list[run_all.Outcome]:
    ok = run_all.Outcome("bench_a", [table_row("tick | ratio", "1.20", "<= 1.25", True),
                                     table_row("other", "3.0x", ">= 5x", False)], (1.5, 2.5), 3.0)
    failed = run_all.Outcome("bench_b", [], (0.5, 0.75), 1.0, "exit status 1: boom")
    return [ok, failed]


def table_rows(block: str) -> list[list[str]]:
    """The cells of every table line of a block (header and separator included)."""
    lines = [l for l in block.splitlines() if l.startswith("|")]
    return [[c.strip() for c in l.strip().strip("|").replace("\\|", "\x00").split("|")] for l in lines]


def test_block_has_markers_header_and_one_row_per_figure():
    block = run_all.readme_block(outcomes(), WHEN, False, MACHINE)
    lines = block.splitlines()
    assert lines[0] == run_all.BEGIN and lines[-1] == run_all.END
    assert WHEN in lines[1] and MACHINE in lines[1] and "quick settings" in lines[1]
    rows = table_rows(block)
    assert rows[0] == list(run_all.COLUMNS)
    assert set(rows[1]) == {"---"}
    assert len(rows) == 2 + 2 + 1   # header, separator, two figures, the failed benchmark's row
    assert all(len(r) == len(run_all.COLUMNS) for r in rows)
    assert rows[2][0] == "`bench_a`" and rows[2][1] == "tick \x00 ratio"   # the pipe was escaped
    assert rows[2][4] == "met" and rows[3][4] == "**not met**"
    assert rows[2][5] == "1.5 -> 2.5"
    assert rows[4][:3] == ["`bench_b`", "(benchmark problem)", "exit status 1: boom"]


def test_full_settings_are_named():
    assert "`python benchmarks/run_all.py --full`" in run_all.readme_block(outcomes(), WHEN, True, MACHINE)


def test_replace_block_keeps_the_rest_of_the_readme():
    before, after = "# Title\n\n## Performance\nintro\n\n", "\n\n## Tests\ntext\n"
    readme = before + run_all.BEGIN + "\nold table\n" + run_all.END + after
    block = run_all.readme_block(outcomes(), WHEN, False, MACHINE)
    replaced = run_all.replace_block(readme, block)
    assert replaced == before + block + after
    assert run_all.replace_block(replaced, block) == replaced


@pytest.mark.parametrize("text", ["no markers", run_all.END + "\n" + run_all.BEGIN,
                                  run_all.BEGIN + run_all.END + run_all.BEGIN + run_all.END])
def test_replace_block_refuses_missing_or_broken_markers(text):
    with pytest.raises(ValueError, match="expected one"):
        run_all.replace_block(text, "x")


def test_the_readme_has_the_markers():
    readme = (run_all.ROOT / "README.md").read_text(encoding="utf-8")
    assert run_all.replace_block(readme, "X").count("X") >= 1


def test_rows_come_from_the_result_line(capsys):
    emit_results("bench_x", {"a": 1.0}, [table_row("m", "f", "t", None)])
    line = capsys.readouterr().out.strip()
    assert line.startswith(RESULT_PREFIX)
    assert json.loads(line[len(RESULT_PREFIX):])["rows"] == [
        {"measure": "m", "figure": "f", "target": "t", "met": None}]


ZENOH_OUTPUT = """(a) raw put/sub round trip, 100 B  median     79.7 us   p99    742.5 us   (n=1000)
(b) lockstep tick, 1 component     median     97.6 us   p99    360.4 us   (n=1000)
ratio tick / raw (medians): 1.23  (target <= 1.25)
"""


ZENOH_ONE_CPU = """(a1) the same on one CPU           median     36.4 us   p99     79.2 us   (n=2000)
(b1) the same on one CPU           median     67.3 us   p99    109.8 us   (n=2000)
ratio tick / raw on one CPU (medians): 1.85  (target <= 1.25)
"""


def test_an_output_reader_takes_the_printed_figures():
    (row,) = run_all_rows.zenoh(ZENOH_OUTPUT)
    assert row["figure"] == "97.6 vs 79.7 µs: 1.23" and row["met"] is True
    os_placed, one_cpu = run_all_rows.zenoh(ZENOH_OUTPUT + ZENOH_ONE_CPU)
    assert os_placed == row
    assert one_cpu["figure"] == "67.3 vs 36.4 µs: 1.85" and one_cpu["met"] is False


ZENOH_POOLS = """default pools / one runtime thread, raw round trip: 181.5 / 105.5 us = 1.72x
default pools / one runtime thread, lockstep tick: 195.7 / 107.2 us = 1.83x
default pools / one runtime thread, lockstep tick on one CPU: 74.1 / 44.8 us = 1.65x
"""


def test_the_zenoh_reader_takes_the_default_pools_comparison():
    rows = run_all_rows.zenoh(ZENOH_OUTPUT + ZENOH_ONE_CPU + ZENOH_POOLS)
    assert [r["figure"] for r in rows[2:]] == ["195.7 vs 107.2 µs: 1.83x", "74.1 vs 44.8 µs: 1.65x"]
    assert "where the OS puts them" in rows[2]["measure"] and "one CPU" in rows[3]["measure"]
    assert all(r["met"] is None for r in rows[2:])


def test_an_output_reader_finds_nothing_in_a_changed_format():
    assert run_all_rows.zenoh("ratio: 1.2\n") == []
    assert run_all_rows.closed_loop("") == [] and run_all_rows.master_overhead("") == []


def closed_loop_section(mode: str, controller: float, untimed: float, rtf: int) -> str:
    """One projection's table as bench_closed_loop prints it."""
    return (f"-- paths: {mode}\npart                                   us/tick   share\n"
            f"FMU step (vehicle)                        5.45     12%\n"
            f"controller (every tick)                  {controller:5.2f}     59%\n"
            f"planner (amortized, 1 in 10 ticks)        7.02     16%\n"
            f"master overhead                           5.75     13%\ntotal                                    43.98\n"
            f"untimed runs: {untimed:.2f} us/tick (cpu clock), real-time factor {rtf}x; target 500x; ratio 0.4\n")


CLOSED_LOOP_OUTPUT = ("backstepping + planner (lane_keeping) + Vehicle8DOF (platform FMU host, shim path)\n"
                      + closed_loop_section("interpreted", 25.76, 43.04, 232)
                      + closed_loop_section("compiled", 12.96, 19.50, 513))


def test_the_closed_loop_reader_gives_one_row_per_projection():
    interpreted, compiled = run_all_rows.closed_loop(CLOSED_LOOP_OUTPUT)
    assert interpreted["measure"].endswith("interpreted projection, step and road search") and interpreted["met"] is False
    assert interpreted["figure"] == ("43.0 µs/tick = 232x real time "
                                     "(controller 25.8, planner 7.0, master 5.8, FMU 5.5 µs)")
    assert compiled["measure"].endswith("compiled projection, step and road search (numba)") and compiled["met"] is True


FMU_STEP_OUTPUT = (
    "FMU                     step us  null us  step-null  C-loop us  step/null  C-loop/null\n"
    "Bicycle.fmu                7.94     6.83       1.11       1.09       1.16         0.16\n"
    "Vehicle8DOF.fmu           10.74     6.92       3.82       4.18       1.55         0.60\n"
    "FMU                           per-call            shim  ratio    raw per-call        raw shim  ratio  outputs\n"
    "Vehicle8DOF.fmu         10.28 /  10.59   6.63 /   6.92   1.53   7.22 /   7.40   5.49 /   5.72   1.29  bit-identical\n"
    "Bicycle.fmu              6.75 /   6.87   3.10 /   3.22   2.13   3.68 /   3.76   1.98 /   2.07   1.82  bit-identical\n")


def test_fmu_step_rows_put_the_physics_beside_the_host_step():
    physics, host = run_all_rows.fmu_step(FMU_STEP_OUTPUT)
    assert physics["figure"] == "4.18 vs 6.92 µs: 0.60" and physics["met"] is True
    assert host["figure"] == ("10.59 vs 6.92 µs (1.53x), outputs bit-identical; "
                              "the model's physics alone 4.18 µs (C loop)")
    assert host["target"] == "<= 3 µs (issue 14)" and host["met"] is False


def test_fmu_step_host_row_without_the_physics_table():
    shim_only = FMU_STEP_OUTPUT.split("FMU                           per-call")[1]
    (host,) = run_all_rows.fmu_step(shim_only)
    assert host["figure"] == "10.59 vs 6.92 µs (1.53x), outputs bit-identical"


STARTUP_OUTPUT = (
    "transport           median      min      max   target 1.0 s\n"
    "zenoh                0.812    0.660    0.901   met\n"
    "inproc               0.580    0.570    0.600   met\n"
    "zenoh-compiled       1.104    0.998    1.250   NOT met\n")


def test_startup_rows_one_per_transport_the_compiled_start_apart():
    zenoh, inproc, compiled = run_all_rows.startup(STARTUP_OUTPUT)
    assert zenoh["measure"] == "`cosim run` to tick 0, zenoh (lane_change)"
    assert zenoh["figure"] == "median 0.81 s (min 0.66)" and zenoh["met"] is True
    assert inproc["figure"] == "median 0.58 s (min 0.57)" and inproc["met"] is True
    assert compiled["measure"].startswith("`cosim run` to tick 0, zenoh, controller compiled")
    assert compiled["figure"] == "median 1.10 s (min 1.00)" and compiled["met"] is False
    assert run_all_rows.startup(STARTUP_OUTPUT.replace("zenoh-compiled", "zenoh-other")) == [zenoh, inproc]
