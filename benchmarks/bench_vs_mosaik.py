"""The Satory closed loop in mosaik against ours, in-process and one process per component.

mosaik (PyPI `mosaik`, the `bench` extra) builds satory_nominal's loop from the
project's own classes (benchmarks/mosaik_sims.py: the Vehicle8DOF FMU through
`FmuComponent`, the controller and the planner through `InprocComponent`),
wired from our own resolved edges; an edge into the FMU (no direct
feedthrough) is mosaik's `time_shifted` connection, as our master's one-tick
delay. Four cases, alternated `--repeats` times, wall time of the stepping
loop only, ticks 1..N (start-up excluded on both sides, the initialization
phase at tick 0 too: the planner's road and speed profile, the FMU's
instantiation, the recorder's files; ours from `RunResult.loop_time_s`,
mosaik's from the simulators' clock marks, `benchmarks/mosaik_sims.py`):

- `mosaik in-process`: every simulator a "python" simulator in this process;
- `ours inproc`: `run_scenario(..., transport="inproc")` (`cosim run --transport
  inproc`, recorder included: mosaik records nothing);
- `mosaik processes`: every simulator its own process ("cmd", mosaik's TCP/JSON);
- `ours zenoh`: `run_scenario(..., transport="zenoh")`, which puts the master and
  its component processes on one CPU (`--lockstep-cpu auto`);
- `mosaik processes, one CPU`: mosaik's processes mode with this process and
  its simulators' processes on one CPU too, so that the placement is not what
  the comparison measures: this pair, not mosaik's default placement, carries
  the target.

Before timing anything it checks that the trajectories agree: the vehicle's
x, y, psi, vx at every tick from mosaik (both modes) against ours, bit for bit
(`CHECK FAILED` and exit 1 otherwise). Prints us per tick (min, median), the
two ratios mosaik / ours of the pairs placed alike against the 5x target and
the ratio of mosaik's default placement against ours; then the same for the
whole run, tick 0 included (`world.run` / `RunResult.wall_time_s`): at
`--seconds 10` the initialization phase alone is about 0.1 s, i.e. 100 us
per tick on each side.

    .venv/bin/python benchmarks/bench_vs_mosaik.py [--seconds 20] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.common import (compiled_as_in_a_long_run, emit_results, load_average,  # noqa: E402
                               min_and_median, table_row)

SCENARIO = ROOT / "scenarios" / "satory_nominal.yaml"
TARGET = 5.0
RECORD = ("x", "y", "psi", "vx")
ONE_CPU = "mosaik processes, one CPU"


def _on_one_cpu(run, *args):
    """`run(*args)` with this thread, and the processes it starts, on one CPU (as our zenoh runs)."""
    from cosim.engine.one_cpu import PinnedChain

    with PinnedChain("auto") as chain:
        chain.pin()  # before the simulators start: they inherit the CPU (start-up is not timed)
        return run(*args)


def _edges_and_defaults(overrides: list[str]):
    """Our resolved edges, which components are direct feedthrough, every output's default, and
    each component's outputs the run reads (what our master tells `use_outputs`: the mosaik
    simulators tell our components the same, so both sides do the same work)."""
    from benchmarks.bench_closed_loop_zenoh import _master
    from benchmarks.common import outputs_read
    from cosim.execution.prepare import prepare_run
    from cosim.scenario.loader import load_scenario
    from cosim.transport.inproc import InprocComponent

    prepared = prepare_run(load_scenario(SCENARIO, overrides))
    master = _master(prepared, {l.name: InprocComponent(l) for l in prepared.launches})
    resolved = _resolved_edges(prepared, master)
    edges = [(e.src, e.src_port, e.dst, e.dst_port) for e in resolved]
    feedthrough = {n: bool(getattr(c, "direct_feedthrough", True)) for n, c in master.components.items()}
    defaults = {(n, p.name): p.zero() for n, c in master.components.items() for p in c.outputs}
    reads = outputs_read(master.components, resolved, prepared.scenario)
    master.stop_all()
    return prepared.scenario.total_ticks, list(master.components), edges, feedthrough, defaults, reads


def _resolved_edges(prepared, master):
    from cosim.engine.wiring import resolve_wiring

    hosted = master.components
    unsupported = {n: c.interface.unsupported for n, c in hosted.items() if hasattr(c, "interface")}
    return resolve_wiring(prepared.scenario, {n: (c.inputs, c.outputs) for n, c in hosted.items()}, unsupported)


def run_mosaik(seconds: float, processes: bool, record_to: Path) -> tuple[float, float]:
    """One mosaik run of the loop: seconds per tick of ticks 1..N and of the whole `world.run`.

    Writes the vehicle's trajectory to `record_to`.
    """
    import mosaik

    overrides = [f"duration={seconds:g}"]
    ticks, names, edges, feedthrough, defaults, reads = _edges_and_defaults(overrides)
    if processes:
        cmd = f"{sys.executable} -m benchmarks.mosaik_sims %(addr)s"
        sim_config = {"Cosim": {"cmd": cmd, "cwd": str(ROOT)}}
    else:
        sim_config = {"Cosim": {"python": "benchmarks.mosaik_sims:CosimSim"}}
    world = mosaik.World(sim_config, time_resolution=0.01, skip_greetings=True, configure_logging=False)
    entities = {}
    marks = record_to.with_suffix(".marks")
    marks.mkdir(exist_ok=True)
    for name in names:
        extra = {"record": list(RECORD), "record_to": str(record_to)} if name == "vehicle" else {}
        sim = world.start("Cosim", sim_id=name, scenario=str(SCENARIO), overrides=overrides, name=name,
                          as_lists=processes, reads=sorted(reads[name]), marks_to=str(marks), **extra)
        entities[name] = sim.Component()
    by_pair: dict[tuple[str, str], list[tuple[str, str]]] = {}
    for src, src_port, dst, dst_port in edges:
        by_pair.setdefault((src, dst), []).append((src_port, dst_port))
    for (src, dst), attrs in by_pair.items():
        if feedthrough[dst]:
            world.connect(entities[src], entities[dst], *attrs)
        else:   # our master's implicit one-tick delay into a plant without direct feedthrough
            initial = {a: _jsonable(defaults[(src, a)]) for a, _ in attrs}
            world.connect(entities[src], entities[dst], *attrs, time_shifted=True, initial_data=initial)
    start = time.perf_counter()
    world.run(until=ticks + 1, print_progress=False)
    whole = (time.perf_counter() - start) / ticks
    by_sim = [json.loads((marks / f"{name}.json").read_text()) for name in names]
    loop = max(m["loop_end"] for m in by_sim) - min(m["loop_start"] for m in by_sim)
    return loop / ticks, whole


def _jsonable(value):
    return value.tolist() if isinstance(value, np.ndarray) else value


def run_ours(seconds: float, transport: str, out: Path) -> tuple[float, float]:
    """One `run_scenario`: seconds per tick of ticks 1..N and of the whole master run
    (the run folder stays in `out`)."""
    from cosim.execution.run import run_scenario
    from cosim.scenario.loader import load_scenario

    result = run_scenario(load_scenario(SCENARIO, [f"duration={seconds:g}"]), out, transport=transport,
                          progress=False)
    if result.status != "ok":
        raise SystemExit(f"bench_vs_mosaik: our {transport} run failed: {result.error}")
    return result.loop_time_s / result.ticks, result.wall_time_s / result.ticks


def our_trajectory(run_dir: Path) -> np.ndarray:
    """The vehicle's RECORD signals at every tick from a run folder."""
    from cosim.results.recorder import read_signals

    names, data = read_signals(run_dir / "signals.csv")
    return data[:, [names.index(f"vehicle.{n}") for n in RECORD]]


def check_same(label: str, mosaik_traj: np.ndarray, ours: np.ndarray) -> None:
    """Bit-identical trajectories, or CHECK FAILED and exit 1."""
    if mosaik_traj.shape != ours.shape or not np.array_equal(mosaik_traj, ours):
        rows = min(len(mosaik_traj), len(ours))
        bad = np.flatnonzero((mosaik_traj[:rows] != ours[:rows]).any(axis=1))
        first = int(bad[0]) if bad.size else rows
        raise SystemExit(f"CHECK FAILED: {label}: trajectory differs from ours (shapes {mosaik_traj.shape} "
                         f"vs {ours.shape}, first different tick {first})")
    print(f"check: {label} trajectory (vehicle {', '.join(RECORD)} at {len(ours)} ticks) bit-identical to ours")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=3, help="rounds of the alternating cases")
    args = parser.parse_args()
    compiled_as_in_a_long_run()  # a quick run's controller would otherwise run interpreted
    if not (args.seconds >= 1 and args.repeats >= 1):
        parser.error(f"need --seconds >= 1 and --repeats >= 1, got {args.seconds} and {args.repeats}")
    os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    logging.getLogger("mosaik").setLevel(logging.WARNING)
    try:
        from loguru import logger
        logger.remove()
    except ImportError:
        pass
    before = load_average()
    cases = {"mosaik in-process": lambda tmp: run_mosaik(args.seconds, False, tmp / "m.npy"),
             "ours inproc": lambda tmp: run_ours(args.seconds, "inproc", tmp / "inproc"),
             "mosaik processes": lambda tmp: run_mosaik(args.seconds, True, tmp / "p.npy"),
             "ours zenoh": lambda tmp: run_ours(args.seconds, "zenoh", tmp / "zenoh"),
             ONE_CPU: lambda tmp: _on_one_cpu(run_mosaik, args.seconds, True, tmp / "p1.npy")}
    samples: dict[str, list[float]] = {label: [] for label in cases}
    whole: dict[str, list[float]] = {label: [] for label in cases}  # tick 0 included
    with tempfile.TemporaryDirectory(prefix="bench-mosaik-") as name:
        tmp = Path(name)
        for round_ in range(args.repeats):
            for label, case in cases.items():
                loop, run = case(tmp)
                samples[label].append(loop)
                whole[label].append(run)
            if round_ == 0:
                ours = our_trajectory(tmp / "inproc")
                check_same("ours zenoh", our_trajectory(tmp / "zenoh"), ours)
                check_same("mosaik in-process", np.load(tmp / "m.npy"), ours)
                check_same("mosaik processes", np.load(tmp / "p.npy"), ours)
                check_same(ONE_CPU, np.load(tmp / "p1.npy"), ours)
    print(f"satory_nominal, {args.seconds:g} s simulated, {args.repeats} alternating repeats, wall time of the "
          f"stepping loop (ticks 1..N); load average {before} before, {load_average()} after")
    figures: dict[str, float] = {}
    rows = []
    print(f"{'case':<24}{'min us/tick':>13}{'median':>10}")
    for label, values in samples.items():
        low, mid = min_and_median(values)
        figures[f"{label} min"], figures[f"{label} median"] = low * 1e6, mid * 1e6
        print(f"{label:<24}{low * 1e6:>13.1f}{mid * 1e6:>10.1f}")
    # the target's pairs place both sides alike: in-process, and processes on one CPU (ours
    # does that by default; mosaik's own default, the OS placement, is printed for reference)
    for mosaik_case, ours_case, targeted in (("mosaik in-process", "ours inproc", True),
                                             (ONE_CPU, "ours zenoh", True),
                                             ("mosaik processes", "ours zenoh", False)):
        ratio = figures[f"{mosaik_case} min"] / figures[f"{ours_case} min"]
        ratio_median = figures[f"{mosaik_case} median"] / figures[f"{ours_case} median"]
        figures[f"ratio {mosaik_case}"] = ratio
        verdict = f"; target >= {TARGET:g}x: {'met' if ratio >= TARGET else 'not met'}" if targeted else ""
        print(f"{mosaik_case} / {ours_case}: {ratio:.2f}x faster (medians: {ratio_median:.2f}x){verdict}")
        placed = " (both on one CPU)" if mosaik_case == ONE_CPU else (
            " (mosaik where the OS puts it, ours on one CPU)" if not targeted else "")
        rows.append(table_row(f"Satory loop, ticks 1..N: {mosaik_case} / {ours_case}{placed} (same trajectory, "
                              f"bit for bit)",
                              f"{figures[f'{mosaik_case} min']:.0f} vs {figures[f'{ours_case} min']:.0f} "
                              f"µs/tick: {ratio:.2f}x", f">= {TARGET:g}x" if targeted else "-",
                              (ratio >= TARGET) if targeted else None))
    print("the whole run, tick 0 (initialization) included:")
    for label, values in whole.items():
        low, mid = min_and_median(values)
        figures[f"{label} whole run min"] = low * 1e6
        print(f"{label:<24}{low * 1e6:>13.1f}{mid * 1e6:>10.1f}")
    for mosaik_case, ours_case in (("mosaik in-process", "ours inproc"), ("mosaik processes", "ours zenoh"),
                                   (ONE_CPU, "ours zenoh")):
        ratio = figures[f"{mosaik_case} whole run min"] / figures[f"{ours_case} whole run min"]
        print(f"{mosaik_case} / {ours_case}, whole run: {ratio:.2f}x")
    emit_results("bench_vs_mosaik", {**figures, "seconds": args.seconds, "repeats": args.repeats,
                                     "load": f"{before} -> {load_average()}"}, rows)


if __name__ == "__main__":
    main()
