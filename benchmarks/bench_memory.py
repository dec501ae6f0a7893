"""Peak memory of a run against its duration: the master and every process of a Zenoh run.

Runs satory_nominal over Zenoh (`cosim.execution.run.run_scenario`, recorder
on, as `cosim run` does) for a short and a ten-times longer duration
(`--set duration=...`, default 275 s and 2750 s), each in a fresh Python
process, and prints the peak resident set size (VmHWM from /proc) of:

- the master, through the last tick (an observer reads it at the last tick,
  before the recorder closes) and at the end of the run folder's analysis
  (metrics and figures, as `cosim run` ends: that step loads the whole run);
- each component process (controller, planner) and the recorder's CSV
  writer process, read at the last tick while they still run;
- the process that draws the figure, started before tick 0 as `cosim run`
  starts it (`cosim.execution.figure_process`), read until it exits (VmHWM
  is a high-water mark: the last read holds its peak).

DESIGN.md wants memory flat with duration: the long run's peak within 10 % of
the short one's (`ratio`). Memory is not timing: one run each is enough.

    .venv/bin/python benchmarks/bench_memory.py [--durations 275 2750] [--transport zenoh]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.common import compiled_as_in_a_long_run, emit_results, load_average, table_row  # noqa: E402

SCENARIO = ROOT / "scenarios" / "satory_nominal.yaml"
TARGET = 0.10


def peak_kib(pid: int | str = "self") -> int | None:
    """VmHWM (peak resident set) of a process in KiB, None if it is gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


class PeakAtLastTick:
    """Master observer: at the last tick, the peak RSS of the master and of every other
    process of the run (component processes, the recorder's writer)."""

    def __init__(self) -> None:
        self.peaks: dict[str, int | None] = {}

    def begin(self, master) -> None:
        self.master = master
        self.recorder = next((o for o in master.observers if hasattr(o, "writer_pid")), None)

    def after_tick(self, tick, t, values, arrays) -> None:
        if tick != self.master.total_ticks:
            return
        self.peaks["master (through the last tick)"] = peak_kib()
        for name, comp in self.master.components.items():
            pid = getattr(comp, "pid", None)
            if pid is not None:
                self.peaks[f"{name} process"] = peak_kib(pid)
        if self.recorder is not None and self.recorder.writer_pid:
            self.peaks["CSV writer process"] = peak_kib(self.recorder.writer_pid)


def child(duration: float, transport: str, figures: bool) -> None:
    """One run in this process; prints its peaks as one JSON line."""
    from cosim.execution.finish import analyse_run_folder
    from cosim.execution.run import run_scenario
    from cosim.scenario.loader import load_scenario

    from cosim.execution.figure_process import FigureProcess

    probe = PeakAtLastTick()
    drawer = FigureProcess()
    with tempfile.TemporaryDirectory(prefix="bench-memory-") as tmp:
        scenario = load_scenario(SCENARIO, [f"duration={duration:g}"])
        result = run_scenario(scenario, Path(tmp) / "run", transport=transport, progress=False,
                              observers=[probe], at_tick0=drawer.start if figures else None)
        if result.status != "ok":
            raise SystemExit(f"bench_memory: run failed: {result.error}")
        drawer_peak = _PeakUntilExit(drawer.pid)
        notes = analyse_run_folder(result, figures=figures, drawer=drawer)
        drawer.close()
        if figures and not any(note.startswith("figure: ") for note in notes):
            raise SystemExit(f"bench_memory: no figure: {notes}")
        probe.peaks["master (with metrics and figures)"] = peak_kib()
        if drawer.pid is not None:
            probe.peaks["figure process (with metrics and figures)"] = drawer_peak.result()
        probe.peaks["ticks"] = result.ticks
    print(json.dumps(probe.peaks))


class _PeakUntilExit(threading.Thread):
    """Reads a process's VmHWM every 10 ms until it exits; `result()` is the last read."""

    def __init__(self, pid: int | None) -> None:
        super().__init__(daemon=True)
        self.pid, self.peak = pid, None
        if pid is not None:
            self.start()

    def run(self) -> None:
        while (peak := peak_kib(self.pid)) is not None:
            self.peak = peak
            time.sleep(0.01)

    def result(self) -> int | None:
        if self.pid is not None:
            self.join()
        return self.peak


def measure(duration: float, transport: str, figures: bool) -> dict[str, int | None]:
    """The peaks of one run of `duration` seconds, in a fresh process."""
    done = subprocess.run([sys.executable, __file__, "--child", str(duration), "--transport", transport,
                           *([] if figures else ["--no-figures"])],
                          capture_output=True, text=True, cwd=ROOT)
    if done.returncode != 0:
        raise SystemExit(f"bench_memory: the {duration:g} s run failed: {done.stderr.strip()[-800:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--durations", type=float, nargs=2, default=[275.0, 2750.0], metavar=("SHORT", "LONG"))
    parser.add_argument("--transport", choices=("zenoh", "inproc"), default="zenoh")
    parser.add_argument("--no-figures", action="store_true", help="skip the figures after the run")
    parser.add_argument("--child", type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    compiled_as_in_a_long_run()  # a quick run's controller would otherwise run interpreted
    if args.child is not None:
        child(args.child, args.transport, not args.no_figures)
        return
    short, long = args.durations
    load = load_average()
    peaks = {d: measure(d, args.transport, not args.no_figures) for d in (short, long)}
    print(f"satory_nominal over {args.transport}: peak RSS (VmHWM) in MiB, {short:g} s vs {long:g} s "
          f"({peaks[short]['ticks']} vs {peaks[long]['ticks']} ticks); load average {load}")
    print(f"{'process':<44}{f'{short:g} s':>10}{f'{long:g} s':>10}{'ratio':>8}  flat (< {TARGET:.0%})")
    results = {}
    for name in peaks[short]:
        if name == "ticks":
            continue
        a, b = peaks[short][name], peaks[long].get(name)
        if not a or not b:
            print(f"{name:<44}{'-':>10}{'-':>10}")
            continue
        ratio = b / a
        flat = "yes" if abs(ratio - 1) < TARGET else "NO"
        print(f"{name:<44}{a / 1024:>10.1f}{b / 1024:>10.1f}{ratio:>8.3f}  {flat}")
        results[name] = {"short_mib": a / 1024, "long_mib": b / 1024, "ratio": ratio}
    emit_results("bench_memory", {"durations": [short, long], "transport": args.transport,
                                  "peaks": results, "load": load}, table_rows(short, long, results))


def table_rows(short: float, long: float, results: dict[str, dict[str, float]]) -> list[dict]:
    """Two rows: the run's processes (through the last tick), and the master and the figure's
    process with the analysis."""
    run = {n: r for n, r in results.items() if "with metrics" not in n}
    after = {n: r for n, r in results.items() if "with metrics" in n}
    rows = []
    for label, group in ((f"peak RSS, {long:g} s / {short:g} s run, every process through the last tick", run),
                         (f"peak RSS, {long:g} s / {short:g} s run, after metrics and figures (drawn in their process)", after)):
        if group:
            text = "; ".join(f"{n.replace(' (through the last tick)', '').replace(' (with metrics and figures)', '')}"
                             f" {r['short_mib']:.0f} -> {r['long_mib']:.0f} MiB ({r['ratio']:.2f})"
                             for n, r in group.items())
            rows.append(table_row(label, text, f"< {TARGET:.0%} apart",
                                  all(abs(r["ratio"] - 1) < TARGET for r in group.values())))
    return rows


if __name__ == "__main__":
    main()
