"""Benchmark: time from launching `cosim run` to tick 0, over Zenoh and in-process.

Runs the real command line (`cosim run SCENARIO --no-figures`) on a real
scenario, cut to ten ticks with `--set duration=...`, and reads
`time_to_tick0_s` and the start-up marks from each run's manifest.json (time
zero: the start of the `cosim run` process, from /proc, 10 ms resolution).
Transports alternate run by run, so machine load weighs on both alike. Also
measures, as floors for context, a bare interpreter start and `import numpy`
(which every component process needs), and prints the CPU time each process
used before tick 0, which does not depend on the machine's load (the master's
includes the command-line parsing before `cosim run` forks it off its supervisor). Bytecode is
cached as in a normal installation (in a temporary PYTHONPYCACHEPREFIX; this
sandbox sets PYTHONDONTWRITEBYTECODE=1). DESIGN.md target: under 1 s over Zenoh.

    .venv/bin/python benchmarks/bench_startup.py [--scenario scenarios/lane_change.yaml]
        [--repeat 5] [--transports zenoh,inproc,zenoh-noprestart] [--no-bytecode-cache]

"zenoh-nosupervise" runs `cosim run --no-supervise` (no supervisor process
forked: its cost at start-up is the difference to "zenoh").
"zenoh-noprestart" runs `cosim run --no-prestart` (component processes started
after the scenario is loaded instead of while it loads), for comparison.
"zenoh-anycpu" runs `cosim run --lockstep-cpu off` (the processes where the OS
puts them, instead of on the master's CPU).
"zenoh-compiled" runs it for 15,000 controller steps (`controllers.jit.SHORT_RUN_STEPS`) under
COSIM_JIT=auto: the controller process loads numba's compiled projection and step as
it does for the README's first command (satory_nominal, 27,500 steps), which the ten
ticks here would otherwise run interpreted, and the planner keeps its interpreted
road search as there (1,500 planner steps, under its 30,000:
`controllers.road.compiled_path.SHORT_RUN_STEPS`; COSIM_JIT=on would compile it too).
The controller loads them on a thread beside the run (`controllers.jit.beside_the_run`),
so tick 0 does not wait for them; "zenoh-compiledfirst" is the same run with COSIM_JIT=on,
which loads them before tick 0 (and the planner's road search too). The whole command's
wall time is printed beside tick 0 (a compiled case runs its 15,000 ticks).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from controllers.jit import SHORT_RUN_STEPS  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
TARGET_S = 1.0
MARKS = ("scenario_loaded", "spawned", "fmus_ready", "components_ready", "tick0")


def cosim_command() -> list[str]:
    """The `cosim` console script of this interpreter's environment, else `python -m`."""
    script = Path(sys.executable).parent / "cosim"
    return [str(script)] if script.is_file() else [sys.executable, "-m", "cosim.cli.app"]


def run_once(scenario: Path, transport: str, out: Path, duration: float,
             env: dict[str, str]) -> dict:
    """One `cosim run`; returns its manifest (raises if the run failed)."""
    variants = {"noprestart": ["--no-prestart"], "nosupervise": ["--no-supervise"],
                "anycpu": ["--lockstep-cpu", "off"], "compiled": [], "compiledfirst": []}
    kinds = transport.split("-")[1:]
    extra = [arg for v in kinds for arg in variants[v]]
    if "compiled" in kinds or "compiledfirst" in kinds:
        env = {**env, "COSIM_JIT": "on" if "compiledfirst" in kinds else "auto"}
        duration = SHORT_RUN_STEPS * controller_period(scenario)
    cmd = [*cosim_command(), "run", str(scenario), "--out", str(out), "--no-figures",
           "--transport", transport.split("-")[0], "--set", f"duration={duration!r}", *extra]
    start = time.perf_counter()
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({done.returncode}):\n{done.stderr}")
    return {**json.loads((out / "manifest.json").read_text()), "command_wall_s": wall}


def controller_period(scenario: Path) -> float:
    """The period of the scenario's component named `controller` (else its tick), s: a run of
    SHORT_RUN_STEPS of them has COSIM_JIT=auto compile the controller."""
    spec = yaml.safe_load(scenario.read_text())
    controller = (spec.get("components") or {}).get("controller") or {}
    return float(controller.get("period", spec["tick"]))


def floor_s(code: str, repeat: int, env: dict[str, str]) -> float:
    """Median wall time of `python -c code`, s."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True, env=env)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def print_report(results: dict[str, list[dict]], floors: dict[str, float]) -> None:
    """Medians per transport vs the target, and the start-up marks of the median run."""
    print(f"\nload average at the end: {os.getloadavg()[0]:.2f} (2-core machine; "
          f"figures scale with load)")
    for name, value in floors.items():
        print(f"floor: {name:<28} {value:6.3f} s")
    print(f"\n{'transport':<20} {'median':>8} {'min':>8} {'max':>8}   target {TARGET_S:.1f} s")
    for transport, manifests in results.items():
        times = [m["time_to_tick0_s"] for m in manifests]
        verdict = "met" if statistics.median(times) < TARGET_S else "NOT met"
        print(f"{transport:<20} {statistics.median(times):8.3f} {min(times):8.3f} "
              f"{max(times):8.3f}   {verdict}")
    print(f"\n{'transport':<20} whole command, s: median (min-max); loop, s: median")
    for transport, manifests in results.items():
        walls = [m["command_wall_s"] for m in manifests]
        loop = statistics.median(m["loop_time_s"] for m in manifests)
        print(f"{transport:<20} {statistics.median(walls):6.3f} ({min(walls):.3f}-{max(walls):.3f}); "
              f"{loop:6.3f}")
    for transport, manifests in results.items():
        ordered = sorted(manifests, key=lambda m: m["time_to_tick0_s"])
        median = ordered[len(ordered) // 2]
        marks = median["startup"]
        line = "  ".join(f"{k}={marks[k + '_s']:.3f}" for k in MARKS if k + "_s" in marks)
        cpu = "  ".join(f"{k}={marks['cpu_s'][k]:.3f}" for k in MARKS if k in marks["cpu_s"])
        print(f"\n{transport} (median run), master, s since its start: {line}")
        print(f"  master CPU s used by then:           {cpu}")
        for name, ages in (median.get("startup_processes_s") or {}).items():
            print(f"  process {name}, s since its own start: "
                  + "  ".join(f"{k}={v:.3f}" for k, v in ages.items() if v is not None))
    print_cpu_estimate(results)


def print_cpu_estimate(results: dict[str, list[dict]]) -> None:
    """CPU work before tick 0, median over runs: a view that does not depend on load.

    On an idle 2-core machine the zenoh path cannot reach tick 0 before
    max(master CPU, (master + processes CPU) / 2), nor before the master's CPU
    up to the spawn plus the slowest process's CPU to its handshake.
    """
    for transport, manifests in results.items():
        master = statistics.median(m["startup"]["cpu_s"]["tick0"] for m in manifests)
        spawn = [m["startup"]["cpu_s"].get("spawned") for m in manifests]
        children = [sum(a["cpu"] for a in (m.get("startup_processes_s") or {}).values())
                    for m in manifests]
        slowest = [max([a["cpu"] for a in (m.get("startup_processes_s") or {}).values()] or [0])
                   for m in manifests]
        total = statistics.median(children)
        line = f"\n{transport}: CPU s before tick 0: master {master:.3f}"
        if total:
            bound = max(master, (master + total) / 2,
                        statistics.median(spawn) + statistics.median(slowest))
            line += (f", component processes {total:.3f} (slowest {statistics.median(slowest):.3f})"
                     f"; idle 2-core lower bound {bound:.3f} s")
        print(line)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", type=Path, default=ROOT / "scenarios" / "lane_change.yaml")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--transports", default="zenoh,inproc,zenoh-noprestart")
    parser.add_argument("--no-bytecode-cache", action="store_true",
                        help="keep PYTHONDONTWRITEBYTECODE as set (every process then "
                             "compiles the cosim and controllers sources again)")
    args = parser.parse_args()
    transports = args.transports.split(",")
    duration = 10 * float(yaml.safe_load(args.scenario.read_text())["tick"])
    print(f"scenario {args.scenario.name}, {args.repeat} runs per transport, "
          f"duration cut to {duration:g} s")
    results: dict[str, list[dict]] = {t: [] for t in transports}
    with tempfile.TemporaryDirectory(prefix="bench-startup-") as tmp:
        env = bench_env(Path(tmp), args.no_bytecode_cache)
        run_once(args.scenario, "inproc", Path(tmp) / "warm", duration, env)  # FMUs, .pyc
        for i in range(args.repeat):
            for transport in transports:
                manifest = run_once(args.scenario, transport, Path(tmp) / f"{transport}{i}",
                                    duration, env)
                results[transport].append(manifest)
                print(f"run {i + 1} {transport:<20} time to tick 0: "
                      f"{manifest['time_to_tick0_s']:.3f} s", flush=True)
        floors = {"python -c pass": floor_s("pass", 3, env),
                  "python -c 'import numpy'": floor_s("import numpy", 3, env)}
    print_report(results, floors)


def bench_env(tmp: Path, keep_as_is: bool) -> dict[str, str]:
    """The environment of the runs: bytecode cached (in `tmp`, not in the source
    tree) as in a normal installation, unless `keep_as_is`."""
    env = dict(os.environ)
    if keep_as_is:
        print(f"bytecode cache: as set (PYTHONDONTWRITEBYTECODE="
              f"{env.get('PYTHONDONTWRITEBYTECODE', '')!r})")
        return env
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPYCACHEPREFIX"] = str(tmp / "pycache")
    print("bytecode cache: on, in a temporary PYTHONPYCACHEPREFIX (filled by a warm-up run)")
    return env


if __name__ == "__main__":
    main()
