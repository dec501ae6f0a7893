"""Run every benchmark, print one performance table, and write it into README.md.

Each benchmark runs as its own process (quick settings by default, `--full`
for the settings of DESIGN.md's targets: longer runs, more repeats, the
275 s / 2750 s memory runs). The table has one row per figure: what is
measured, the figure, the target, whether it is met, and the 1-minute load
average before and after that benchmark (the machine is shared: the same
figure moves with load). The newer benchmarks print their rows themselves (a
`RESULT {json}` line, `benchmarks.common.emit_results`); for the older ones,
`benchmarks/run_all_rows.py` reads the figures from the lines they print.
A benchmark that fails or whose figures cannot be read still gets a row
saying so. The README's performance section between the markers
`<!-- perf-table:begin -->` and `<!-- perf-table:end -->` is then replaced by
the table (`--no-readme`: print only), so every figure there comes from this
command.

    .venv/bin/python benchmarks/run_all.py [--full] [--only NAME ...] [--no-readme] [--readme README.md]
"""

from __future__ import annotations

import argparse
import importlib.util
import datetime
import json
import os
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks import run_all_rows  # noqa: E402
from benchmarks.common import RESULT_PREFIX, load_average, speed_anchor  # noqa: E402
from controllers.jit import SHORT_RUN_STEPS  # noqa: E402
from controllers.road.compiled_path import SHORT_RUN_STEPS as ROAD_SEARCH_STEPS  # noqa: E402

BEGIN = "<!-- perf-table:begin -->"
END = "<!-- perf-table:end -->"
COLUMNS = ("benchmark", "measure", "figure", "target", "met", "load 1 min (before -> after)")


@dataclass(frozen=True)
class Benchmark:
    """How to run one benchmark: its file, quick and full arguments, and how its rows are read."""

    name: str
    quick: tuple[str, ...]
    full: tuple[str, ...]
    rows_from_output: object = None   # callable(stdout) -> rows, for benchmarks without RESULT lines


BENCHMARKS = (
    Benchmark("bench_fmu_step", ("--steps", "300", "--repeats", "5", "--check-steps", "1000"),
              ("--steps", "500", "--repeats", "30"), run_all_rows.fmu_step),
    Benchmark("bench_master_overhead", ("--ticks", "5000", "--repeats", "3"),
              ("--ticks", "20000", "--repeats", "5"), run_all_rows.master_overhead),
    Benchmark("bench_closed_loop", ("--seconds", "10", "--repeats", "3"),
              ("--seconds", "20", "--repeats", "5"), run_all_rows.closed_loop),
    Benchmark("bench_vs_libcosim", ("--steps", "2000", "--repeats", "5"),
              ("--steps", "5000", "--repeats", "9"), run_all_rows.libcosim),
    Benchmark("bench_zenoh", ("--ticks", "2000", "--blocks", "10"),
              ("--ticks", "5000", "--blocks", "20"), run_all_rows.zenoh),
    Benchmark("bench_closed_loop_zenoh", ("--seconds", "10", "--repeats", "3"),
              ("--seconds", "20", "--repeats", "7")),
    Benchmark("bench_vs_mosaik", ("--seconds", "10", "--repeats", "3"),
              ("--seconds", "20", "--repeats", "5")),
    Benchmark("bench_startup",
              ("--repeat", "3", "--transports", "zenoh,inproc,zenoh-compiled,zenoh-compiledfirst"),
              ("--repeat", "5", "--transports", "zenoh,inproc,zenoh-compiled,zenoh-compiledfirst,zenoh-noprestart"),
              run_all_rows.startup),
    Benchmark("bench_figure", ("--repeat", "3"), ("--repeat", "5")),
    Benchmark("bench_foxglove", ("--duration", "10", "--repeats", "2"),
              ("--duration", "20", "--repeats", "3"), run_all_rows.foxglove),
    Benchmark("bench_sweep", ("--samples", "6", "--seconds", "10", "--repeats", "2"),
              ("--samples", "12", "--seconds", "30", "--repeats", "3")),
    Benchmark("bench_memory", ("--durations", "27.5", "275"),
              ("--durations", "275", "2750")),
)


@dataclass
class Outcome:
    """What one benchmark gave: its rows, the load before and after, its wall time, its status."""

    name: str
    rows: list[dict] = field(default_factory=list)
    load: tuple[float, float] = (0.0, 0.0)
    seconds: float = 0.0
    problem: str = ""


def run_benchmark(bench: Benchmark, full: bool) -> Outcome:
    """Run one benchmark in its own process and read its rows."""
    argv = [sys.executable, str(ROOT / "benchmarks" / f"{bench.name}.py"), *(bench.full if full else bench.quick)]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)}
    before, start = os.getloadavg()[0], time.perf_counter()
    done = subprocess.run(argv, capture_output=True, text=True, cwd=ROOT, env=env)
    outcome = Outcome(bench.name, load=(before, os.getloadavg()[0]), seconds=time.perf_counter() - start)
    results = [json.loads(line[len(RESULT_PREFIX):]) for line in done.stdout.splitlines()
               if line.startswith(RESULT_PREFIX)]
    if results:
        outcome.rows = [dict(r) for result in results for r in result.get("rows", [])]
    elif bench.rows_from_output is not None:
        outcome.rows = bench.rows_from_output(done.stdout)
    if done.returncode != 0:
        last = (done.stderr.strip() or done.stdout.strip()).splitlines()[-1:] or ["no output"]
        outcome.problem = f"exit status {done.returncode}: {last[0][:200]}"
    elif not outcome.rows:
        outcome.problem = "no figure found in its output"
    return outcome


def table_lines(outcomes: Sequence[Outcome]) -> list[str]:
    """The Markdown table: one line per row of every benchmark (a failed one: a row saying why)."""
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    for outcome in outcomes:
        load = f"{outcome.load[0]:.1f} -> {outcome.load[1]:.1f}"
        for row in outcome.rows:
            cells = [f"`{outcome.name}`", str(row["measure"]), str(row["figure"]), str(row["target"]),
                     _met(row.get("met")), load]
            lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
        if outcome.problem:
            lines.append("| " + " | ".join(_cell(c) for c in (f"`{outcome.name}`", "(benchmark problem)",
                                                                 outcome.problem, "-", "-", load)) + " |")
    return lines


def _met(met: object) -> str:
    return {True: "met", False: "**not met**"}.get(met, "-")   # type: ignore[arg-type]


def _cell(text: str) -> str:
    """A table cell: no line breaks, pipes escaped."""
    return " ".join(str(text).split()).replace("|", "\\|")


def readme_block(outcomes: Sequence[Outcome], when: str, full: bool, machine: str) -> str:
    """The README's performance block, markers included."""
    settings = "`--full` settings" if full else "quick settings (`--full`: the long ones)"
    head = (f"Written by `python benchmarks/run_all.py{' --full' if full else ''}` on {when}, {settings}; "
            f"{machine}. Load average (1 min) before and after each benchmark in the last column: the "
            f"machine is shared, so compare the ratios, not the microseconds.")
    return "\n".join([BEGIN, head, "", *table_lines(outcomes), END])


def replace_block(text: str, block: str) -> str:
    """`text` with the part between the markers (markers included) replaced by `block`.

    Raises:
        ValueError: the markers are missing, repeated or out of order.
    """
    if text.count(BEGIN) != 1 or text.count(END) != 1 or text.index(BEGIN) > text.index(END):
        raise ValueError(f"expected one {BEGIN} followed by one {END}")
    start, stop = text.index(BEGIN), text.index(END) + len(END)
    return text[:start] + block + text[stop:]


def machine_line() -> str:
    """Cores and CPU model, for the README."""
    model = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{os.cpu_count()} cores ({model}); {projection_line()}"


def projection_line() -> str:
    """Which paths (window projection, backstepping step, road search) the controllers of these runs use
    (COSIM_JIT, numba)."""
    mode = os.environ.get("COSIM_JIT", "auto")
    found = importlib.util.find_spec("numba") is not None
    compiled = mode.strip().lower() in ("on", "1", "yes", "true") or (found and mode.strip().lower() in ("auto", ""))
    how = "compiled (numba installed)" if compiled else ("interpreted (numba not installed)" if not found
                                                         else "interpreted")
    return (f"controllers' projection, step and road search {how}, COSIM_JIT={mode} (bench_closed_loop "
            f"measures both; the Zenoh, memory and mosaik loops run with on, as a run of "
            f"{SHORT_RUN_STEPS} steps or more does under auto, and the planner's road search too, "
            f"which auto compiles from {ROAD_SEARCH_STEPS} planner steps)")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="the long settings (DESIGN.md's targets)")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="run only these benchmarks")
    parser.add_argument("--no-readme", action="store_true", help="print the table, leave README.md alone")
    parser.add_argument("--readme", type=Path, default=ROOT / "README.md")
    args = parser.parse_args(argv)
    known = {b.name for b in BENCHMARKS}
    if args.only and not set(args.only) <= known:
        parser.error(f"unknown benchmark(s) {sorted(set(args.only) - known)}; choose from {sorted(known)}")
    machine = (f"{machine_line()}, speed anchor {speed_anchor():.1f} ns per iteration of a fixed "
               "pure-Python loop (`benchmarks.common.speed_anchor`, before the benchmarks)")
    outcomes, started, load_at_start = [], time.perf_counter(), load_average()
    print(f"load average (1 / 5 / 15 min) at the start: {load_at_start}", file=sys.stderr, flush=True)
    for bench in BENCHMARKS:
        if args.only and bench.name not in args.only:
            continue
        print(f"running {bench.name} ...", file=sys.stderr, flush=True)
        outcomes.append(run_benchmark(bench, args.full))
        print(f"  {outcomes[-1].seconds:.0f} s{', ' + outcomes[-1].problem if outcomes[-1].problem else ''}",
              file=sys.stderr, flush=True)
    when = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    overall = (f"load average (1 / 5 / 15 min) {load_at_start} at the start, {load_average()} at the "
               f"end; {(time.perf_counter() - started) / 60:.1f} min in all")
    print(overall, file=sys.stderr, flush=True)
    block = readme_block(outcomes, when, args.full, f"{machine}; {overall}")
    print(block)
    if not args.no_readme and not args.only:
        args.readme.write_text(replace_block(args.readme.read_text(encoding="utf-8"), block), encoding="utf-8")
        print(f"written into {args.readme}", file=sys.stderr)
    elif args.only and not args.no_readme:
        print("--only: README.md left alone (its table holds every benchmark)", file=sys.stderr)
    return 1 if any(o.problem for o in outcomes) else 0


if __name__ == "__main__":
    sys.exit(main())
