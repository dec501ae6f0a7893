"""How much time the master adds per tick over the components' own work (in-process).

Three trivial components shaped like the closed loop (a plant without
feedthrough with 6 outputs, a controller reading them plus a reference, a
planner at 1/10 of the rate) run for N ticks twice: called directly in a
hand-written loop with prebuilt input dicts, and through `cosim.engine.master.Master`
with `InprocComponent` hosts. The difference per tick is the master's overhead
(gather, scatter, output checks, scheduling, hosting). A second case gives the
planner a trajectory window (7 arrays of 64 points) as in the real scenarios,
and a third adds the recorder writing signals.csv.

Then the values lane (`Component.step_values`), A/B interleaved in thread CPU
time: a controller shaped like the real one (6 scalars and the 7 window
arrays in, 17 scalars out) stepped through the master on mappings (its `step`
returns `dict(zip(names, values))`, as `controllers.tracking.finite_outputs`
does) and on the lane (`step_values` returns the values), each beside its
direct loop (the same calls without the master).

Run: .venv/bin/python benchmarks/bench_master_overhead.py [--ticks N] [--only table|lane]
Target (DESIGN.md): the master adds under 10 us per tick.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import interleaved, load_average, min_and_median, speed_anchor  # noqa: E402
from cosim.component import Component, Port  # noqa: E402
from cosim.transport.inproc import InprocComponent, PythonComponentLaunch  # noqa: E402
from cosim.engine.master import Master  # noqa: E402
from cosim.results.recorder import Recorder  # noqa: E402
from cosim.engine.wiring import Edge  # noqa: E402

STATES = ("x", "y", "psi", "vx", "vy", "r")
WINDOW = 64
FIELDS = ("x", "y", "psi", "kappa", "s", "v", "a")


class Plant(Component):
    """Integrates nothing much: outputs move with the inputs."""

    inputs = (Port("delta"), Port("torque"))
    outputs = tuple(Port(n) for n in STATES)

    def __init__(self):
        self.s = [0.0] * 6

    def step(self, t, inputs):
        s = self.s
        s[0] += 0.01
        s[1] += 0.001 * inputs["delta"]
        s[3] = 10.0 + 0.0001 * inputs["torque"]
        return dict(zip(STATES, s))


class Controller(Component):
    """A few arithmetic operations on its inputs."""

    inputs = tuple(Port(n) for n in STATES) + (Port("goal_y"), Port("goal_v"))
    outputs = (Port("delta"), Port("torque"))

    def step(self, t, inputs):
        return {"delta": 0.1 * (inputs["goal_y"] - inputs["y"]) - 0.2 * inputs["psi"],
                "torque": 50.0 * (inputs["goal_v"] - inputs["vx"])}


class Planner(Component):
    """Outputs a constant reference (optionally with a trajectory window)."""

    inputs = (Port("x"), Port("y"))

    def __init__(self, window: bool = False):
        self.window = window
        self.outputs = (Port("goal_y"), Port("goal_v"))
        if window:
            self.outputs += tuple(Port(f"ref_{f}", size=WINDOW) for f in FIELDS)
        self.arrays = {f"ref_{f}": np.linspace(0.0, 1.0, WINDOW) for f in FIELDS}

    def step(self, t, inputs):
        out = {"goal_y": 1.0, "goal_v": 12.0}
        if self.window:
            out.update(self.arrays)
        return out


class WindowController(Controller):
    """The controller reading the window too (as the real one does)."""

    inputs = Controller.inputs + tuple(Port(f"ref_{f}", size=WINDOW) for f in FIELDS)


CONTROL_OUTPUTS = ("delta", "torque") + tuple(f"internal_{i}" for i in range(15))
LANE_INPUTS = STATES + tuple(f"ref_{f}" for f in FIELDS)


def _control_law(x, y, psi, vx, vy, r, ref_x, ref_y) -> tuple[float, ...]:
    """17 floats from a few operations on the states and two window points."""
    ey, ev = float(ref_y[3]) - y, 12.0 - vx
    delta, torque = 0.1 * ey - 0.2 * psi, 50.0 * ev
    return (delta, torque, ey, ev, psi, vy, r, x - float(ref_x[0]), delta * delta, torque * 1e-3,
            ey * ev, vy * r, 0.5 * ev * ev, ey + ev, psi * vx, r * 0.1, vy - r)


class MappingController(Component):
    """The controller-shaped component on mappings: reads its inputs by name, returns a dict."""

    inputs = tuple(Port(n) for n in STATES) + tuple(Port(f"ref_{f}", size=WINDOW) for f in FIELDS)
    outputs = tuple(Port(n) for n in CONTROL_OUTPUTS)

    def step(self, t, inputs):
        values = _control_law(inputs["x"], inputs["y"], inputs["psi"], inputs["vx"], inputs["vy"],
                              inputs["r"], inputs["ref_x"], inputs["ref_y"])
        return dict(zip(CONTROL_OUTPUTS, values))


class LaneController(MappingController):
    """The same on the values lane: a tuple in declared order in, the 17 floats out."""

    def step_values(self, t, inputs):
        x, y, psi, vx, vy, r, ref_x, ref_y, *_ = inputs
        return _control_law(x, y, psi, vx, vy, r, ref_x, ref_y)


def direct_loop(ticks: int, window: bool, ctrl: Component | None = None, call=None,
                clock=time.perf_counter) -> float:
    """Seconds (of `clock`) for `ticks` ticks of the components called directly.

    `call(t, plant_outputs, planner_outputs)` steps the controller and returns its outputs;
    default: `ctrl.step` on the merged dict.
    """
    plant, planner = Plant(), Planner(window)
    ctrl = ctrl or (WindowController() if window else Controller())
    call = call or (lambda t, s, ref: ctrl.step(t, {**s, **ref}))
    u = {"delta": 0.0, "torque": 0.0}
    ref = planner.step(0.0, {"x": 0.0, "y": 0.0})
    start = clock()
    for k in range(1, ticks + 1):
        t = k * 0.01
        s = plant.step(t, u)
        if k % 10 == 0:
            ref = planner.step(t, {"x": s["x"], "y": s["y"]})
        u = call(t, s, ref)
    return clock() - start


def _master(ticks: int, window: bool, observers=(), ctrl_class: str | None = None) -> Master:
    """Plant, controller (`ctrl_class`, default by `window`) and planner, wired, through the master."""
    class HostedPlant(InprocComponent):
        direct_feedthrough = False

    here = "bench_master_overhead"
    ctrl_class = ctrl_class or ("WindowController" if window else "Controller")
    comps = {
        "plant": HostedPlant(PythonComponentLaunch("plant", f"{here}:Plant", {}, 1)),
        "controller": InprocComponent(PythonComponentLaunch("controller", f"{here}:{ctrl_class}", {}, 1)),
        "planner": InprocComponent(PythonComponentLaunch("planner", f"{here}:Planner",
                                                         {"window": window}, 10)),
    }
    edges = [Edge("plant", n, "controller", n) for n in STATES]
    edges += [Edge("plant", n, "planner", n) for n in ("x", "y")]
    edges += [Edge("controller", n, "plant", n) for n in ("delta", "torque")]
    read = {port.name for port in comps["controller"].inputs}
    edges += [Edge("planner", p.name, "controller", p.name) for p in comps["planner"].outputs if p.name in read]
    return Master(comps, edges, tick=0.01, total_ticks=ticks, observers=list(observers))


def master_loop(ticks: int, window: bool, record: bool = False) -> float:
    """Seconds for `ticks` ticks through the master (initialization excluded)."""
    with tempfile.TemporaryDirectory() as tmp:
        recorder = Recorder(tmp) if record else None
        master = _master(ticks, window, [recorder] if recorder else [])
        master.initialize()
        start = time.perf_counter()
        for k in range(1, ticks + 1):
            master.step_tick(k)
        elapsed = time.perf_counter() - start
        if recorder:
            recorder.close()
    return elapsed


def lane_direct(ticks: int, lane: bool) -> float:
    """Thread CPU seconds per tick of plant, controller and windowed planner called directly
    (the controller through `step_values` on a tuple, or `step` on a dict)."""
    ctrl = LaneController()
    window: list = [None, ()]     # the planner's outputs last seen, and their window as a tuple

    def on_tuple(t, s, ref):
        if ref is not window[0]:      # a new window only when the planner stepped
            window[:] = [ref, tuple(ref[f"ref_{f}"] for f in FIELDS)]
        out = ctrl.step_values(t, (*s.values(), *window[1]))
        return {"delta": out[0], "torque": out[1]}

    return direct_loop(ticks, True, ctrl, on_tuple if lane else None, time.thread_time) / ticks


def lane_master(ticks: int, lane: bool) -> float:
    """Thread CPU seconds per tick of the same three through the master (initialization excluded)."""
    master = _master(ticks, True, ctrl_class="LaneController" if lane else "MappingController")
    on_lane = {p.name for p in master._plans if p.step_values is not None}
    if on_lane != ({"controller"} if lane else set()):
        raise SystemExit(f"the controller is not on the lane it should be on: {on_lane}")
    master.initialize()
    start = time.thread_time()
    for k in range(1, ticks + 1):
        master.step_tick(k)
    return (time.thread_time() - start) / ticks


def lane_ab(ticks: int, repeats: int) -> None:
    """The values lane against the mapping path, interleaved; prints min / median us per tick."""
    print(f"\nvalues lane, controller-shaped (6 scalars + 7 x {WINDOW} in, 17 out): {ticks} ticks, "
          f"{repeats} interleaved rounds, thread CPU time; load {load_average()}, "
          f"anchor {speed_anchor():.1f} ns")
    samples = interleaved({
        "mapping direct": lambda: lane_direct(ticks, False),
        "mapping master": lambda: lane_master(ticks, False),
        "lane direct": lambda: lane_direct(ticks, True),
        "lane master": lambda: lane_master(ticks, True)}, repeats)
    medians = {}
    print(f"{'path':<10}{'direct us/tick':>22}{'master us/tick':>22}{'overhead us':>14}   (min / median)")
    for path in ("mapping", "lane"):
        direct = [x * 1e6 for x in samples[f"{path} direct"]]
        master = [x * 1e6 for x in samples[f"{path} master"]]
        overheads = [m - d for m, d in zip(master, direct)]
        (d_min, d_med), (m_min, m_med) = min_and_median(direct), min_and_median(master)
        o_min, o_med = min_and_median(overheads)
        medians[path] = m_med
        print(f"{path:<10}{d_min:>11.2f} / {d_med:<8.2f}{m_min:>11.2f} / {m_med:<8.2f}"
              f"{o_min:>7.2f} / {o_med:<6.2f}")
    print(f"lane - mapping through the master (medians): {medians['lane'] - medians['mapping']:+.2f} us/tick;"
          f" load {load_average()}")


def best_of(fn, repeats: int, *args) -> float:
    """Minimum over repeats (least disturbed by the other jobs on the machine)."""
    return min(fn(*args) for _ in range(repeats))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--only", choices=("table", "lane"), default=None,
                        help="only the three cases' table, or only the values lane A/B")
    args = parser.parse_args()
    sys.modules.setdefault("bench_master_overhead", sys.modules[__name__])
    n = args.ticks
    if args.only != "lane":
        overhead_table(n, args.repeats)
    if args.only != "table":
        lane_ab(n, args.repeats)


def overhead_table(n: int, repeats: int) -> None:
    """The three cases: direct and master seconds per tick (best of `repeats`), and their difference."""
    print(f"{n} ticks, best of {repeats}")
    print(f"{'case':<34}{'direct us/tick':>16}{'master us/tick':>16}{'overhead us':>13}{'ratio':>8}")
    for label, window, record in (("scalars", False, False), ("with trajectory window", True, False),
                                  ("window + recorder", True, True)):
        direct = best_of(direct_loop, repeats, n, window) / n * 1e6
        master = best_of(master_loop, repeats, n, window, record) / n * 1e6
        print(f"{label:<34}{direct:>16.2f}{master:>16.2f}{master - direct:>13.2f}"
              f"{master / direct:>8.2f}")


if __name__ == "__main__":
    main()
