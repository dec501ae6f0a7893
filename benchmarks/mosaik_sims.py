"""A mosaik simulator hosting one component of a cosim scenario (for bench_vs_mosaik.py).

`CosimSim` runs one component of a scenario through the project's own hosts:
the plant FMU through `cosim.fmu.host.FmuComponent`, a Python component
(controller, planner) through `cosim.transport.inproc.InprocComponent`, the
same objects `cosim run --transport inproc` drives. mosaik time is the integer
tick (time_resolution = the scenario's tick); mosaik time 0 is our
initialization phase (`start`), time k our tick k (`step`), t = t0 + k * tick
computed as the master does. Inputs are held between deliveries (our signal
store's zero-order hold); array outputs travel as lists when the simulator is
its own process (mosaik's JSON), as arrays in-process. With `marks_to`, each
simulator writes `<marks_to>/<name>.json` at the end: the clock (`time.perf_counter`,
the system's monotonic clock, the same in every process) when its first step after
time 0 began and when its last step ended, so the benchmark can time ticks 1..N alone
as it does ours.

Run as `python -m benchmarks.mosaik_sims ADDR` for mosaik's one-process-per-
simulator mode (mosaik starts it with "cmd").
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import mosaik_api_v3
import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def _host(scenario_path: str, overrides: list[str], name: str):
    """The project's host of component `name` of the scenario (FMU or Python)."""
    from cosim.execution.prepare import prepare_run
    from cosim.fmu.host import FmuComponent
    from cosim.scenario.loader import load_scenario
    from cosim.transport.inproc import InprocComponent

    prepared = prepare_run(load_scenario(scenario_path, overrides))
    for plan in prepared.fmus:
        if plan.name == name:
            return prepared, FmuComponent(plan.name, plan.path, plan.interface, plan.parameters,
                                          plan.period_ticks)
    launch = next(l for l in prepared.launches if l.name == name)
    return prepared, InprocComponent(launch)


class CosimSim(mosaik_api_v3.Simulator):
    """One scenario component as a time-based mosaik simulator (one entity, "c")."""

    def __init__(self) -> None:
        super().__init__({"type": "time-based", "models": {}})
        self.trajectory: list[tuple[float, ...]] = []
        self.loop_start: float | None = None  # clock when the first step after time 0 began
        self.loop_end: float | None = None    # clock when the last step ended

    def init(self, sid, time_resolution=1.0, scenario="", overrides=(), name="", as_lists=False,
             record=(), record_to="", reads=None, marks_to=""):
        prepared, self.host = _host(scenario, list(overrides), name)
        if reads is not None and hasattr(self.host, "use_outputs"):
            self.host.use_outputs(set(reads))  # what our master tells it: the same work on both sides
        from cosim.execution.fmu_hosting import start_time

        self.t0, self.tick = start_time(prepared.scenario, prepared.fmus), prepared.scenario.tick
        self.period = int(self.host.period_ticks)
        self.as_lists, self.record, self.record_to = as_lists, list(record), record_to
        self.name, self.marks_to = name, marks_to
        self.held = {p.name: p.zero() for p in self.host.inputs}
        self.array_inputs = {p.name for p in self.host.inputs if p.size > 1}
        self.outputs: dict = {}
        attrs = [p.name for p in self.host.inputs] + [p.name for p in self.host.outputs]
        self.meta["models"]["Component"] = {"public": True, "params": [], "attrs": sorted(set(attrs))}
        return self.meta

    def create(self, num, model, **model_params):
        return [{"eid": "c", "type": model}]

    def step(self, time, inputs, max_advance):
        if time >= 1 and self.loop_start is None:
            self.loop_start = _clock()
        for attr, by_source in inputs.get("c", {}).items():
            value = next(iter(by_source.values()))
            self.held[attr] = (np.asarray(value, dtype=np.float64) if attr in self.array_inputs
                               else float(value))
        t = self.t0 + time * self.tick
        if time == 0:
            self.outputs = self.host.start(t, dict(self.held))
        else:
            self.outputs = self.host.step(time, t, dict(self.held))
        if self.record:
            self.trajectory.append(tuple(float(self.outputs[n]) for n in self.record))
        self.loop_end = _clock()
        return time + self.period

    def get_data(self, outputs):
        data = {}
        for attr in outputs.get("c", ()):
            value = self.outputs[attr]
            data[attr] = value.tolist() if self.as_lists and isinstance(value, np.ndarray) else value
        return {"c": data}

    def finalize(self):
        self.host.stop()
        if self.record_to:
            np.save(self.record_to, np.array(self.trajectory, dtype=np.float64))
        if self.marks_to:
            marks = {"loop_start": self.loop_start, "loop_end": self.loop_end}
            (Path(self.marks_to) / f"{self.name}.json").write_text(json.dumps(marks))


_clock = time.perf_counter  # `step`'s argument `time` shadows the module


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    try:
        from loguru import logger   # mosaik_api_v3's logging: its connection attempts are noise here
        logger.remove()
    except ImportError:
        pass
    mosaik_api_v3.start_simulation(CosimSim())
