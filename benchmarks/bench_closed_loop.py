"""Cost per tick of the in-process closed loop: Vehicle8DOF FMU, controller, planner, master.

Writes a scenario (two-lane road with a 150 m bend, 10 ms tick, the planner at
10 Hz, lane keeping or lane change; like the Satory scenarios it leaves the
planner's alternative window out of the record, so the planner, told that
nobody reads it, does not plan it: `--record-alternative` puts it back), then runs it through the real master
(`cosim.engine.master.Master` over `FmuComponent` and `InprocComponent` hosts, the
hosts `cosim run --transport inproc` uses, no recorder) for N simulated
seconds, in alternating repetitions of two kinds:

- timed: each host's `step` wrapped with a timer; gives the time per tick of
  the FMU step, the controller, the planner (amortized: its time over all
  ticks) and the master overhead (the run's tick-loop time minus the
  components'), all from one run;
- untimed: the master loop as is; its time per tick gives the real-time
  factor (tick / time per tick), which DESIGN.md wants at least 500.

Times are this thread's CPU time by default (`--clock cpu`: on a shared
machine, time the scheduler gives to other jobs is not counted) or elapsed
time (`--clock wall`). The timers' own costs (measured on an empty step just
before the run) are taken off. The timed run with the smallest total and the fastest untimed run
are reported (least disturbed by other jobs on a shared machine).

With `--profile`, one more untimed run goes under a profiler (benchmarks.common.profile_call;
`--profiler pyinstrument`, the default, or `py-spy`):
it prints the time inside each part (FMU step, controller, planner, the whole tick loop) and the
functions with the most self time, and `--profile-out FILE` (.html or text) keeps the call tree.

Run: .venv/bin/python benchmarks/bench_closed_loop.py [--seconds 20] [--repeats 5] [--clock cpu|wall]
     [--controller backstepping|feedforward|stanley|pure_pursuit] [--manoeuvre lane_keeping|lane_change]
     [--profile] [--profile-out FILE] [--profiler pyinstrument|py-spy] [--fmu-host platform|fmpy]
     [--paths interpreted|compiled|both] [--record-alternative]

`--paths` picks the controllers' per-tick paths (the window projection, controllers.road.projection,
the backstepping step, controllers.backstepping.step_kernel, and the planner's road search,
controllers.road.compiled_path): interpreted, compiled by numba
(the `jit` extra; COSIM_JIT=on), or both in alternating runs, each with its own table (the default
when numba is installed). Both give the same bits.

`--fmu-host platform` (the default) hosts the FMU as `cosim run` does: `FmuComponent` through
the C stepping shim (`cosim.fmu.stepper`, one C call per step); `--fmu-host fmpy` takes the
host's per-call path instead (three ctypes calls per step, what a machine without a compiler
gets). The first line printed is a machine-speed anchor (`benchmarks.common.speed_anchor`),
so figures from different sessions can be compared.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import tempfile
import time
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import (PROFILERS, load_average, profile_call, speed_anchor,  # noqa: E402
                               outputs_read)

from cosim.errors import UserError  # noqa: E402
from cosim.fmu.host import FmuComponent  # noqa: E402
from cosim.transport.inproc import InprocComponent  # noqa: E402
from cosim.engine.master import Master  # noqa: E402
from cosim.execution.prepare import prepare_run  # noqa: E402
from cosim.scenario.loader import load_scenario  # noqa: E402
from cosim.engine.wiring import resolve_wiring  # noqa: E402
from cosim.execution import fmu_hosting  # noqa: E402
from controllers import jit  # noqa: E402
from controllers.backstepping import step_path  # noqa: E402
from controllers.road import compiled_path, projection  # noqa: E402

TARGET_RTF = 500.0
PATHS = {"interpreted": ("interpreted",), "compiled": ("compiled",), "both": ("interpreted", "compiled")}
DEFAULT_PATHS = "both" if importlib.util.find_spec("numba") else "interpreted"
CLOCKS = {"cpu": time.thread_time, "wall": time.perf_counter}
CLOCK = time.thread_time      # set from --clock in main()
CONTROLLERS = {
    "backstepping": ("controllers.backstepping:BacksteppingController",
                     {"adaptive": True, "lateral_law": "faithful", "mu0": 0.8}),
    "feedforward": ("controllers.backstepping:BacksteppingController",
                    {"adaptive": True, "lateral_law": "feedforward", "mu0": 0.8}),
    "stanley": ("controllers.baselines:StanleyController", {}),
    "pure_pursuit": ("controllers.baselines:PurePursuitController", {}),
}
MANOEUVRES = {
    "lane_keeping": {"type": "lane_keeping"},
    "lane_change": {"type": "lane_change", "at": 80.0, "to_lane": 1, "a_lat": 1.5, "j_lat": 2.0},
}


def write_scenario(folder: Path, seconds: float, controller: str, manoeuvre: str,
                   record_alternative: bool = False) -> Path:
    """The benchmark's scenario YAML in `folder`; returns its path.

    Args:
        folder: where to write it; seconds: duration;
        controller: a CONTROLLERS key; manoeuvre: a MANOEUVRES key;
        record_alternative: record (so have the planner compute) its alternative window `alt_*`.
    """
    python, parameters = CONTROLLERS[controller]
    scenario = {
        "name": f"bench_closed_loop_{controller}_{manoeuvre}",
        "duration": seconds, "tick": 0.01,
        "components": {
            "vehicle": {"fmu": "Vehicle8DOF", "parameters": {"vx0": 10.0, "cx": 0.42}},
            "controller": {"python": python, "period": 0.01, "parameters": parameters},
            "planner": {"python": "controllers.planning:Planner", "period": 0.1, "parameters": {
                "road": {"builder": "two_lane", "length": max(400.0, 100.0 + 12.0 * seconds), "radius": 150.0},
                "lane": 0, "manoeuvre": MANOEUVRES[manoeuvre],
                "speed": {"v_max": 12.0, "a_lat_max": 2.0, "a_max": 1.0, "d_max": 1.5, "j_max": 1.0}}},
        },
        "connections": ["vehicle -> controller", "vehicle -> planner", "planner -> controller",
                        "controller.delta -> vehicle.delta", "controller.torque -> vehicle.torque"],
    }
    if not record_alternative:      # as the Satory scenarios: nothing reads it, so the planner does not plan it
        scenario["record"] = {"exclude": ["planner.alt_*"]}
    path = folder / "bench_closed_loop.yaml"
    path.write_text(yaml.safe_dump(scenario, sort_keys=False))
    return path


class StepTimer:
    """Wraps a host's `step` (and its `step_values`, the master's values lane) and adds up the time inside."""

    def __init__(self, hosted) -> None:
        self.seconds = 0.0
        self.calls = 0
        self.step = hosted.step = self._timed(hosted.step)
        if getattr(hosted, "step_values", None) is not None:
            hosted.step_values = self._timed(hosted.step_values)

    def _timed(self, inner):
        """`inner` (a step or step_values), timed."""
        def timed(tick, t, inputs):
            start = CLOCK()
            outputs = inner(tick, t, inputs)
            self.seconds += CLOCK() - start
            self.calls += 1
            return outputs
        return timed


def timer_cost(calls: int = 20000) -> tuple[float, float]:
    """(time a StepTimer reports, time it adds to its caller's time), per call of an empty step."""
    class Empty:
        def step(self, tick, t, inputs):
            return inputs

    empty = Empty()
    direct = empty.step
    start = CLOCK()
    for k in range(calls):
        direct(k, 0.0, None)
    bare = CLOCK() - start
    timer = StepTimer(empty)
    start = CLOCK()
    for k in range(calls):
        timer.step(k, 0.0, None)
    wrapped = CLOCK() - start
    return timer.seconds / calls, max(wrapped - bare, 0.0) / calls


FMU_HOSTS = ("platform", "fmpy")
FMU_HOST = "platform"   # set from --fmu-host in main()
PATHS_SEEN: set[str] = set()   # the FMU host's step paths the runs took ("shim", "per-call")


def build_hosts(prepared) -> dict:
    """The run's hosts in declaration order: the FMU and the Python components, all in-process.

    The FMU host is the platform's FmuComponent: through the stepping shim, or with
    FMU_HOST "fmpy" on its per-call path (use_shim=False).
    """
    hosted = {plan.name: FmuComponent(plan.name, plan.path, plan.interface, plan.parameters,
                                      plan.period_ticks, use_shim=FMU_HOST != "fmpy")
              for plan in prepared.fmus}
    hosted.update({launch.name: InprocComponent(launch) for launch in prepared.launches})
    return {name: hosted[name] for name in prepared.names}


def build_master(prepared, hosted: dict) -> Master:
    """The master over the hosts, wired as the scenario says, without observers."""
    scenario = prepared.scenario
    unsupported = {n: c.interface.unsupported for n, c in hosted.items() if isinstance(c, FmuComponent)}
    edges = resolve_wiring(scenario, {n: (c.inputs, c.outputs) for n, c in hosted.items()}, unsupported)
    return Master(hosted, edges, scenario.tick, scenario.total_ticks,
                  fmu_hosting.start_time(scenario, prepared.fmus),
                  outputs_read=outputs_read(hosted, edges, scenario))  # as `cosim run` tells them


def run_once(prepared, timed: bool) -> tuple[float, dict[str, tuple[float, int]]]:
    """One run: seconds (CLOCK) of the tick loop and, if timed, (seconds, calls) inside each host's step."""
    hosted = build_hosts(prepared)
    timers = {name: StepTimer(comp) for name, comp in hosted.items()} if timed else {}
    master = build_master(prepared, hosted)
    try:
        master.initialize()
        PATHS_SEEN.update("shim" if c._stepper is not None else "per-call"
                          for c in hosted.values() if isinstance(c, FmuComponent))
        start = CLOCK()
        for k in range(1, master.total_ticks + 1):
            master.step_tick(k)
        elapsed = CLOCK() - start
    finally:
        master.stop_all()
    return elapsed, {name: (timer.seconds, timer.calls) for name, timer in timers.items()}


def profile_run(prepared, out: str | None, profiler: str) -> None:
    """One untimed run under the profiler: time per tick inside each part and the hottest functions."""
    hosted = build_hosts(prepared)
    master = build_master(prepared, hosted)

    def loop() -> None:
        for k in range(1, master.total_ticks + 1):
            master.step_tick(k)

    def step_in(*files: str):     # files: path endings, such as "fmu/host.py"
        return lambda function, path: (function in ("step", "step_values")
                                       and Path(path).as_posix().endswith(files))

    groups = {"FMU step (FmuComponent.step)": step_in("fmu/host.py"),
              "controller (*Controller.step)": step_in("backstepping/component.py", "controllers/baselines.py"),
              "planner (Planner.step, amortized)": step_in("planning/planner.py"),
              "tick loop (Master.step_tick)": lambda function, path: (
                  function == "step_tick" and Path(path).name == "master.py")}
    try:
        master.initialize()
        figures = profile_call(loop, units=master.total_ticks, groups=groups, out=out, profiler=profiler)
    finally:
        master.stop_all()
    parts = sum(v for k, v in figures.items() if not k.startswith(("tick loop", "total")))
    loop_us = figures.get("tick loop (Master.step_tick)", 0.0)
    print(f"  {'master (tick loop minus the parts)':<40}{loop_us - parts:>9.2f} us/tick")


def timed_figures(prepared, ticks: int) -> dict[str, float]:
    """One timed run as us per tick: each component, `master overhead` and `total`, timer costs taken off."""
    inner_bias, outer_cost = timer_cost()
    elapsed, parts = run_once(prepared, timed=True)
    calls = sum(c for _, c in parts.values())
    figures = {name: max(seconds - c * inner_bias, 0.0) / ticks * 1e6 for name, (seconds, c) in parts.items()}
    total = (elapsed - calls * outer_cost) / ticks * 1e6
    figures["master overhead"] = total - sum(figures.values())
    figures["total"] = total
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=5, help="runs of each kind (the best is kept)")
    parser.add_argument("--controller", choices=sorted(CONTROLLERS), default="backstepping")
    parser.add_argument("--manoeuvre", choices=sorted(MANOEUVRES), default="lane_keeping")
    parser.add_argument("--clock", choices=sorted(CLOCKS), default="cpu",
                        help="cpu: this thread's CPU time (not inflated when other jobs take the core); "
                             "wall: elapsed time")
    parser.add_argument("--profile", action="store_true",
                        help="also profile one untimed run (pyinstrument) and print the hot spots")
    parser.add_argument("--profile-out", metavar="FILE",
                        help="with --profile: keep the profile there (pyinstrument: .html or text tree; "
                             "py-spy: collapsed stacks)")
    parser.add_argument("--profiler", choices=PROFILERS, default="pyinstrument",
                        help="pyinstrument (in-process, inflates Python code ~2x) or py-spy (attaches "
                             "from outside, needs ptrace rights, no slow-down)")
    parser.add_argument("--paths", choices=sorted(PATHS), default=DEFAULT_PATHS,
                        help="the controllers' per-tick paths (window projection, backstepping step): "
                             "interpreted, compiled (numba, the jit extra) or both, alternating (default: "
                             "both when numba is installed)")
    parser.add_argument("--record-alternative", action="store_true",
                        help="record the planner's alternative window (planner.alt_*), which the Satory "
                             "scenarios leave out, so that the planner plans it at every step")
    parser.add_argument("--fmu-host", choices=FMU_HOSTS, default="platform",
                        help="platform: cosim's FmuComponent as runs use it (the C stepping shim, 1 call "
                             "per step); fmpy: its per-call path (3 ctypes calls, as without a compiler)")
    args = parser.parse_args()
    if not (args.seconds >= 0.1 and args.repeats >= 1):
        parser.error(f"need --seconds >= 0.1 and --repeats >= 1, got {args.seconds} and {args.repeats}")
    global CLOCK, FMU_HOST
    CLOCK, FMU_HOST = CLOCKS[args.clock], args.fmu_host
    print(f"machine-speed anchor: {speed_anchor():.1f} ns per pure-Python loop iteration "
          f"(benchmarks.common.speed_anchor); load average {load_average()}")
    modes = PATHS[args.paths]
    with tempfile.TemporaryDirectory() as tmp:
        prepared = prepare_run(load_scenario(write_scenario(Path(tmp), args.seconds, args.controller,
                                                            args.manoeuvre, args.record_alternative)))
        ticks, tick = prepared.scenario.total_ticks, prepared.scenario.tick
        plain, timed = {mode: [] for mode in modes}, {mode: [] for mode in modes}
        for _ in range(args.repeats):
            for mode in modes:      # alternating, so both see the same machine
                use_paths(mode)
                plain[mode].append(run_once(prepared, timed=False)[0] / ticks * 1e6)
                timed[mode].append(timed_figures(prepared, ticks))
        if args.profile or args.profile_out:
            use_paths(modes[-1])
            profile_run(prepared, args.profile_out, args.profiler)
    path = " + ".join(sorted(PATHS_SEEN))
    print(f"{args.controller} + planner ({args.manoeuvre}) + Vehicle8DOF ({args.fmu_host} FMU host, {path} path), "
          f"{ticks} ticks of "
          f"{tick * 1e3:g} ms, {args.clock} clock, best of {args.repeats} timed runs (timer costs taken off)")
    for mode in modes:
        report(mode, timed[mode], plain[mode], tick, args.clock)


def use_paths(mode: str) -> None:
    """The controllers' paths for the next runs: 'interpreted' or 'compiled' (numba: projection, step
    and the planner's road search)."""
    os.environ[jit.JIT_VARIABLE] = "off" if mode == "interpreted" else "on"
    for gate in (projection.compiled_kernel, step_path.compiled_step, compiled_path.compiled_geometry):
        gate.cache_clear()
        gate()        # imports and loads the compiled code now, not inside a timed run


def report(mode: str, timed: list[dict], plain: list[float], tick: float, clock: str) -> None:
    """One mode's table: the best timed run per part and the fastest untimed run's real-time factor."""
    best = min(timed, key=lambda figures: figures["total"])
    labels = {"vehicle": "FMU step (vehicle)", "controller": "controller (every tick)",
              "planner": "planner (amortized, 1 in 10 ticks)"}
    print(f"-- paths: {mode}")
    print(f"{'part':<36}{'us/tick':>10}{'share':>8}")
    for name, value in best.items():
        share = f"{100 * value / best['total']:>7.0f}%" if name != "total" else ""
        print(f"{labels.get(name, name):<36}{value:>10.2f}{share}")
    total = min(plain)
    rtf = tick * 1e6 / total
    print(f"untimed runs: {total:.2f} us/tick ({clock} clock), real-time factor {rtf:.0f}x; target {TARGET_RTF:.0f}x; "
          f"ratio {rtf / TARGET_RTF:.3f}")

if __name__ == "__main__":
    try:
        main()
    except UserError as error:      # a scenario or component problem: the message, no traceback
        sys.exit(f"bench_closed_loop: {error}")
