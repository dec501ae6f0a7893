"""What a run's figure adds to the whole `cosim run` command, over Zenoh and in-process.

Runs the real command line, `cosim run SCENARIO --transport T --out DIR`, with its
figure (drawn by the process the command starts once tick 0 is done,
`cosim.execution.figure_process`) and with `--no-figures`, alternating the two run
by run, `--repeat` times each per transport, and times each whole process from
launch to exit. Prints the medians, the seconds the figure adds and the ratio. The
bytecode cache is on, in a temporary folder, as in `bench_startup`; a warm-up run
builds the FMUs and fills it first.

    .venv/bin/python benchmarks/bench_figure.py [--scenario scenarios/lane_change.yaml]
        [--repeat 5] [--transports zenoh,inproc]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.bench_startup import bench_env, cosim_command  # noqa: E402
from benchmarks.common import emit_results, load_average, table_row  # noqa: E402


def whole_command_s(scenario: Path, transport: str, out: Path, figures: bool,
                    env: dict[str, str]) -> float:
    """Wall seconds of one `cosim run`, launch to exit (raises if it failed or drew nothing)."""
    cmd = [*cosim_command(), "run", str(scenario), "--transport", transport, "--out", str(out),
           *([] if figures else ["--no-figures"])]
    start = time.perf_counter()
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({done.returncode}):\n{done.stderr[-2000:]}")
    if figures and "figure: " not in done.stdout:
        raise SystemExit(f"{' '.join(cmd)} drew no figure:\n{done.stdout[-2000:]}")
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", type=Path, default=ROOT / "scenarios" / "lane_change.yaml")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--transports", default="zenoh,inproc")
    args = parser.parse_args()
    transports = args.transports.split(",")
    load = load_average()
    times: dict[tuple[str, bool], list[float]] = {(t, f): [] for t in transports for f in (True, False)}
    with tempfile.TemporaryDirectory(prefix="bench-figure-") as tmp:
        env = bench_env(Path(tmp), keep_as_is=False)
        whole_command_s(args.scenario, "inproc", Path(tmp) / "warm", True, env)
        for i in range(args.repeat):
            for transport in transports:
                for figures in (True, False):
                    key = (transport, figures)
                    times[key].append(whole_command_s(args.scenario, transport,
                                                      Path(tmp) / f"{transport}{figures}{i}",
                                                      figures, env))
    print(f"{args.scenario.name}, whole `cosim run` command, {args.repeat} alternated runs each; "
          f"load average {load} -> {load_average()}")
    print(f"{'transport':<10}{'figure':>10}{'no figure':>11}{'adds':>8}{'ratio':>8}   (medians, s)")
    figures_out, rows = {}, []
    for transport in transports:
        with_s = statistics.median(times[transport, True])
        without_s = statistics.median(times[transport, False])
        print(f"{transport:<10}{with_s:>10.2f}{without_s:>11.2f}{with_s - without_s:>8.2f}"
              f"{with_s / without_s:>8.2f}")
        figures_out[transport] = {"with figure s": with_s, "without s": without_s,
                                  "with": times[transport, True], "without": times[transport, False]}
        rows.append(table_row(f"`cosim run {args.scenario.stem}` whole command, {transport}: with its "
                              f"figure (drawn beside the run) / `--no-figures` (medians)",
                              f"{with_s:.2f} vs {without_s:.2f} s: the figure adds "
                              f"{with_s - without_s:.2f} s ({with_s / without_s:.2f}x)", "-", None))
    emit_results("bench_figure", {"scenario": args.scenario.name, "repeat": args.repeat,
                                  "load": load, **figures_out}, rows)


if __name__ == "__main__":
    main()
