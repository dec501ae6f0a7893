"""How much time the master adds per tick over the components' own work (in-process).

Three trivial components shaped like the closed loop (a plant without
feedthrough with 6 outputs, a controller reading them plus a reference, a
planner at 1/10 of the rate) run for N ticks twice: called directly in a
hand-written loop with prebuilt input dicts, and through `cosim.engine.master.Master`
with `InprocComponent` hosts. The difference per tick is the master's overhead
(gather, scatter, output checks, scheduling, hosting). A second case gives the
planner a trajectory window (7 arrays of 64 points) as in the real scenarios,
and a third adds the recorder writing signals.csv.

Run: .venv/bin/python benchmarks/bench_master_overhead.py [--ticks N]
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


def direct_loop(ticks: int, window: bool) -> float:
    """Seconds for `ticks` ticks of the components called directly."""
    plant, planner = Plant(), Planner(window)
    ctrl = WindowController() if window else Controller()
    u = {"delta": 0.0, "torque": 0.0}
    ref = planner.step(0.0, {"x": 0.0, "y": 0.0})
    start = time.perf_counter()
    for k in range(1, ticks + 1):
        t = k * 0.01
        s = plant.step(t, u)
        if k % 10 == 0:
            ref = planner.step(t, {"x": s["x"], "y": s["y"]})
        u = ctrl.step(t, {**s, **ref})
    return time.perf_counter() - start


def _master(ticks: int, window: bool, observers=()) -> Master:
    class HostedPlant(InprocComponent):
        direct_feedthrough = False

    here = "bench_master_overhead"
    ctrl_class = "WindowController" if window else "Controller"
    comps = {
        "plant": HostedPlant(PythonComponentLaunch("plant", f"{here}:Plant", {}, 1)),
        "controller": InprocComponent(PythonComponentLaunch("controller", f"{here}:{ctrl_class}", {}, 1)),
        "planner": InprocComponent(PythonComponentLaunch("planner", f"{here}:Planner",
                                                         {"window": window}, 10)),
    }
    edges = [Edge("plant", n, "controller", n) for n in STATES]
    edges += [Edge("plant", n, "planner", n) for n in ("x", "y")]
    edges += [Edge("controller", n, "plant", n) for n in ("delta", "torque")]
    edges += [Edge("planner", p.name, "controller", p.name) for p in comps["planner"].outputs]
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


def best_of(fn, repeats: int, *args) -> float:
    """Minimum over repeats (least disturbed by the other jobs on the machine)."""
    return min(fn(*args) for _ in range(repeats))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    sys.modules.setdefault("bench_master_overhead", sys.modules[__name__])
    n = args.ticks
    print(f"{n} ticks, best of {args.repeats}")
    print(f"{'case':<34}{'direct us/tick':>16}{'master us/tick':>16}{'overhead us':>13}{'ratio':>8}")
    for label, window, record in (("scalars", False, False), ("with trajectory window", True, False),
                                  ("window + recorder", True, True)):
        direct = best_of(direct_loop, args.repeats, n, window) / n * 1e6
        master = best_of(master_loop, args.repeats, n, window, record) / n * 1e6
        print(f"{label:<34}{direct:>16.2f}{master:>16.2f}{master - direct:>13.2f}"
              f"{master / direct:>8.2f}")


if __name__ == "__main__":
    main()
