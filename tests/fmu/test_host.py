"""The fmpy host with a foreign (non-vehicle) FMU built by the test: tests/fmus/Lag.

Lag is a first-order lag with its own variable names (u_cmd, y_out, tau, gain),
mapped to the canonical names u and y. Its exact step solution
y(t + h) = K u + (y - K u) exp(-h / tau) is recomputed here in Python with the
same h (t_k - t_{k-1}) and the same operation order, so the results must match
bit for bit, in FMI 2.0 and FMI 3.0. Last, two hosts of one built-in FMU in one
process (vehicle_following's lead and follower) must not share state.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pytest

from cosim.component import Component, Port
from cosim.errors import ComponentFailure
from cosim.fmu.host import FmuComponent
from cosim.fmu.interface import describe_fmu
from cosim.transport.inproc import InprocComponent, PythonComponentLaunch
from cosim.engine.master import Master
from cosim.results.recorder import read_signals
from cosim.engine.wiring import Edge
from tests.helpers.fmus import LAG_SCENARIO as SCENARIO
from tests.helpers.fmus import built_fmu

LAG_NAMES = {"u": "u_cmd", "y": "y_out"}


class Steps(Component):
    """u = level from t >= 0.25 on, 0 before (a test source)."""

    outputs = (Port("u"),)

    def __init__(self, level: float = 1.0):
        self.level = level

    def step(self, t, inputs):
        return {"u": self.level if t >= 0.25 else 0.0}


def lag_step(y: float, u: float, gain: float, tau: float, h: float) -> float:
    """The Lag model's exact step, in the C code's operation order."""
    target = gain * u
    return target + (y - target) * math.exp(-h / tau)


def _lag(path: Path, period: int, **params) -> FmuComponent:
    return FmuComponent("lag", path, describe_fmu(path, LAG_NAMES), params, period)


@pytest.mark.parametrize("version", [2, 3])
def test_open_loop_multirate_matches_exact_solution(lag_fmus, version):
    comps = {"lag": _lag(lag_fmus[version], 2, tau=0.3, gain=2.0, y_init=0.5),
             "src": InprocComponent(PythonComponentLaunch("src", f"{__name__}:Steps", {}, 1))}
    master = Master(comps, [Edge("src", "u", "lag", "u")], tick=0.05, total_ticks=20, trace=True)
    master.run()
    assert master.order == ["lag", "src"]
    lag_calls = [(k, inputs["u"]) for k, name, inputs in master.trace if name == "lag"]
    # steps every 2 ticks, from t_{k-2} to t_k, with the inputs as they stand at the
    # start of tick k (the source's value of tick k-1: it switched at tick 5)
    assert lag_calls == [(0, 0.0), (2, 0.0), (4, 0.0), (6, 1.0), (8, 1.0), (10, 1.0),
                         (12, 1.0), (14, 1.0), (16, 1.0), (18, 1.0), (20, 1.0)]
    y = 0.5
    for k, u in lag_calls[1:]:
        y = lag_step(y, u, 2.0, 0.3, master.time_of(k) - master.time_of(k - 2))
    assert master.value("lag", "y") == y
    master.stop_all()


def test_fmi2_and_fmi3_builds_agree_bit_for_bit(lag_fmus):
    finals = []
    for version in (2, 3):
        comps = {"lag": _lag(lag_fmus[version], 1, tau=0.2),
                 "src": InprocComponent(PythonComponentLaunch("src", f"{__name__}:Steps", {}, 1))}
        master = Master(comps, [Edge("src", "u", "lag", "u")], tick=0.01, total_ticks=50)
        master.run()
        finals.append(list(master.values))
        master.stop_all()
    assert np.array(finals[0]).tobytes() == np.array(finals[1]).tobytes()


@pytest.mark.parametrize("version", [2, 3])
def test_invalid_parameter_reports_the_fmu_log(lag_fmus, version):
    comp = _lag(lag_fmus[version], 1, tau=0.0)
    master = Master({"lag": comp}, [], tick=0.1, total_ticks=3)
    with pytest.raises(ComponentFailure) as err:
        master.run()
    message = str(err.value)
    assert message.startswith("component 'lag' failed during initialization (t=0 s): ")
    assert "ExitInitializationMode" in message and "Lag: tau must be > 0, got 0" in message
    metrics, errors = master.stop_all()
    assert errors == [] and metrics == {"lag": {}}


def test_unknown_parameter_is_refused_before_start(lag_fmus):
    with pytest.raises(Exception, match="no parameter 'mass'"):
        _lag(lag_fmus[2], 1, mass=3.0)


def closed_loop_reference(tick: float, ticks: int, kp: float, gain: float, tau: float):
    """y and u per tick for the scenario above (controller every 2 ticks)."""
    y, u, rows = 0.0, 0.0, []
    time_of = [0.0 + k * tick for k in range(ticks + 1)]
    for k in range(ticks + 1):
        if k:
            y = lag_step(y, u, gain, tau, time_of[k] - time_of[k - 1])
        if k % 2 == 0:
            u = kp * ((1.0 if time_of[k] >= 0.1 else 0.0) - y)
        rows.append((time_of[k], y, u))
    return rows


@pytest.mark.parametrize("version", [2, 3])
def test_scenario_with_foreign_fmu_runs_through_the_master(tmp_path, lag_fmus, version):
    from cosim.execution.run import run_scenario
    from cosim.scenario.loader import load_scenario

    path = tmp_path / "lag.yaml"
    path.write_text(SCENARIO.format(fmu=lag_fmus[version]))
    result = run_scenario(load_scenario(path), tmp_path / "run", "inproc", progress=False)
    assert result.status == "ok" and result.ticks == 100
    names, data = read_signals(result.signals)
    assert names == ["time", "plant.y", "controller.u", "ref.value"]
    expected = closed_loop_reference(0.01, 100, 3.0, 1.5, 0.4 * 0.5)
    assert [tuple(row[:3]) for row in data.tolist()] == expected
    manifest = json.loads(result.manifest.read_text())
    assert manifest["status"] == "ok" and manifest["ticks"] == 100
    assert manifest["step_order"] == ["plant", "ref", "controller"]
    digest = hashlib.sha256(lag_fmus[version].read_bytes()).hexdigest()
    assert manifest["fmus"]["plant"]["sha256"] == digest
    assert manifest["fmus"]["plant"]["parameters"] == {"tau": 0.2, "gain": 1.5}
    assert json.loads((tmp_path / "run" / "metrics.json").read_text()) == {"controller.steps": 51.0}


@pytest.mark.parametrize("version", [2, 3])
def test_input_out_of_range_mid_run_names_tick_and_fmu_message(lag_fmus, version):
    comps = {"lag": _lag(lag_fmus[version], 1),
             "src": InprocComponent(PythonComponentLaunch("src", f"{__name__}:Steps",
                                                          {"level": 2.0e6}, 1))}
    master = Master(comps, [Edge("src", "u", "lag", "u")], tick=0.05, total_ticks=20)
    with pytest.raises(ComponentFailure) as err:
        master.run()
    message = str(err.value)
    # the source switches at tick 5; the lag receives the value at tick 6
    assert message.startswith("component 'lag' failed at tick 6 (t=0.3 s): ")
    assert "u_cmd = 2e+06 is outside its valid range" in message
    assert master.ticks_done == 5
    metrics, errors = master.stop_all()
    assert errors == []


def _plant_trace(comps: dict[str, FmuComponent], inputs: dict[str, dict], ticks: int) -> dict[str, list]:
    """Start the FMU hosts, step them in turn (interleaved), return each one's outputs per tick."""
    trace = {name: [comp.start(0.0, inputs[name])] for name, comp in comps.items()}
    for k in range(1, ticks + 1):
        for name, comp in comps.items():
            trace[name].append(comp.step(k, 0.01 * k, inputs[name]))
    for comp in comps.values():
        comp.stop()
    return trace


@pytest.mark.parametrize("version", [2, 3])
def test_two_instances_of_one_builtin_fmu_in_one_process_are_independent(tmp_path, version):
    """vehicle_following's case: the same .fmu twice in the master's process, other parameters and
    inputs. Each instance gives, bit for bit, what it gives alone (no state shared through the
    library: the framework keeps all state per instance, and each host unzips its own copy)."""
    path, _ = built_fmu(tmp_path, "Vehicle8DOF", version)
    interface = describe_fmu(path)
    base = {p.name: 0.0 for p in interface.inputs} | {"mu": 1.0}
    inputs = {"vehicle": base | {"delta": 0.02, "torque": 300.0},
              "lead": base | {"delta": -0.01, "torque": -200.0}}
    params = {"vehicle": {"vx0": 10.0}, "lead": {"vx0": 8.0, "x0": 30.0, "m": 1800.0}}

    def host(name):
        return FmuComponent(name, path, interface, params[name], 1)

    together = _plant_trace({"vehicle": host("vehicle"), "lead": host("lead")}, inputs, 200)
    for name in ("vehicle", "lead"):
        alone = _plant_trace({name: host(name)}, inputs, 200)[name]
        assert together[name] == alone
    assert together["vehicle"][-1]["x"] != together["lead"][-1]["x"]
    assert together["lead"][-1]["x"] > 30.0
