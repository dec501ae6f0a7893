"""CSV vs Parquet for one run: file sizes, write time from the spool, load time with pandas.

Runs a scenario once (`cosim run SCENARIO --transport inproc --no-figures`, with
`record.format=[csv, parquet]`) and measures on its run folder:

- size: signals.csv + arrays/*.csv against signals.parquet + arrays/*.parquet;
- write time from the spool: the run removes its spools, so each table's
  spool is rebuilt from the run's Parquet file (the same float64 rows, bit for
  bit, as the tests check); then `rebuild_csv` (the one-pass CSV conversion of
  the recorder's fallback and `cosim recover`; during a run the CSV writer
  process does the same work on the other core) and `write_parquet` (what
  `close` runs in the master) are timed on it, interleaved, `--repeats` times;
- load time: `pandas.read_csv("signals.csv")` against `pandas.read_parquet(
  "signals.parquet")`, and `cosim.load_run(folder).signals` with and without
  the Parquet files beside the CSV, interleaved.

Times are the median over the repeats of this process's CPU time (`--clock
cpu`, default: other jobs on a shared machine are not counted) or wall time.

Run: .venv/bin/python benchmarks/bench_results_formats.py [--scenario scenarios/satory_nominal.yaml]
     [--repeats 5] [--clock cpu|wall] [--keep DIR]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _clock(kind: str) -> Callable[[], float]:
    return time.process_time if kind == "cpu" else time.perf_counter


def _run(scenario: Path, out: Path) -> float:
    """Run the scenario with CSV and Parquet; its wall time (s)."""
    cosim = Path(sys.executable).with_name("cosim")
    started = time.perf_counter()
    subprocess.run([str(cosim), "run", str(scenario), "--transport", "inproc", "--no-figures",
                    "--out", str(out), "--set", "record.format=[csv, parquet]"],
                   check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started


def _sizes(folder: Path, suffix: str) -> int:
    return sum(p.stat().st_size for p in folder.rglob(f"*{suffix}"))


def _spools(folder: Path, work: Path) -> list:
    """Each table's spool, rebuilt in `work` from the run's Parquet files (the same rows)."""
    import numpy as np

    from cosim.results.csv_writer import DATA_OFFSET, write_header
    from cosim.results.parquet import read_parquet_table

    headers = []
    for parquet in sorted(folder.rglob("*.parquet")):
        names, data = read_parquet_table(parquet)
        target = work / parquet.relative_to(folder).parent
        target.mkdir(parents=True, exist_ok=True)
        spool = target / (parquet.stem + ".f64")
        header = write_header(spool, parquet.stem + ".csv", names,
                              formats=("csv", "parquet"))
        with open(spool, "wb") as out:
            out.write(len(data).to_bytes(8, sys.byteorder, signed=True).ljust(DATA_OFFSET, b"\0"))
            out.write(np.ascontiguousarray(data, dtype=np.float64).tobytes())
        headers.append(header)
    return headers


def _time(step: Callable[[], object], clock: Callable[[], float]) -> float:
    started = clock()
    step()
    return clock() - started


def _interleaved(steps: dict[str, Callable[[], object]], repeats: int,
                 clock: Callable[[], float]) -> dict[str, float]:
    """Median time of each step, the steps run in turn, `repeats` rounds."""
    times: dict[str, list[float]] = {name: [] for name in steps}
    for _ in range(repeats):
        for name, step in steps.items():
            times[name].append(_time(step, clock))
    return {name: statistics.median(values) for name, values in times.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", type=Path, default=ROOT / "scenarios" / "satory_nominal.yaml")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--clock", choices=("cpu", "wall"), default="cpu")
    parser.add_argument("--keep", type=Path, default=None, help="run folder to keep")
    args = parser.parse_args(argv)
    import pandas as pd

    import cosim
    from cosim.results.csv_writer import rebuild_csv
    from cosim.results.parquet import write_parquet

    clock = _clock(args.clock)
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp) / "run"
        print(f"load average before: {open('/proc/loadavg').read().split()[:3]}")
        wall = _run(args.scenario, folder)
        rows, cols = cosim.load_run(folder).signals.shape
        print(f"run: {args.scenario.name}, {rows} rows x {cols} columns, {wall:.1f} s wall")
        csv_bytes, parquet_bytes = _sizes(folder, ".csv"), _sizes(folder, ".parquet")
        signals_csv = (folder / "signals.csv").stat().st_size
        signals_parquet = (folder / "signals.parquet").stat().st_size
        print(f"size signals:  csv {signals_csv / 1e6:.2f} MB, parquet {signals_parquet / 1e6:.2f} MB "
              f"({signals_csv / signals_parquet:.1f}x smaller)")
        print(f"size all tables: csv {csv_bytes / 1e6:.2f} MB, parquet {parquet_bytes / 1e6:.2f} MB "
              f"({csv_bytes / parquet_bytes:.1f}x smaller)")
        headers = _spools(folder, Path(tmp) / "spools")
        writes = _interleaved({"csv": lambda: [rebuild_csv(h) for h in headers],
                               "parquet": lambda: [write_parquet(h) for h in headers]},
                              args.repeats, clock)
        print(f"write from the spool, all tables ({args.clock} s, median of {args.repeats}): "
              f"csv {writes['csv']:.3f}, parquet {writes['parquet']:.3f}")
        csv_only = Path(tmp) / "csv-only"
        shutil.copytree(folder, csv_only, ignore=shutil.ignore_patterns("*.parquet"))
        loads = _interleaved({
            "pandas.read_csv": lambda: pd.read_csv(folder / "signals.csv"),
            "pandas.read_parquet": lambda: pd.read_parquet(folder / "signals.parquet"),
            "load_run csv": lambda: cosim.load_run(csv_only).signals,
            "load_run parquet": lambda: cosim.load_run(folder).signals,
        }, args.repeats, clock)
        print(f"load signals ({args.clock} s, median of {args.repeats}): "
              + ", ".join(f"{k} {v:.3f}" for k, v in loads.items()))
        by_pandas = pd.read_csv(folder / "signals.csv").to_numpy()
        exact = cosim.load_run(csv_only).signals.reset_index().to_numpy()
        differ = int((by_pandas.view("u8") != exact.view("u8")).sum())
        print(f"pandas.read_csv's default float parse: {differ} of {exact.size} values differ "
              f"in their bits from the recorded float64 (cosim.load_run and Parquet: none)")
        print(f"load average after: {open('/proc/loadavg').read().split()[:3]}")
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    sys.exit(main())
