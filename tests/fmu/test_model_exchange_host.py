"""Model Exchange FMUs as components (cosim.fmu.model_exchange), FMI 2.0 and 3.0, held
against fmpy.simulate_fmu(fmi_type="ModelExchange") under the same settings.

Stated tolerance: ME_TOL = 1e-9 between the master and fmpy with CVode or Euler
(the master drives fmpy's own CVode with the same calls, so the observed
difference is 0.0). RK4 is held against the analytic bouncing ball (exact
between events, events bisected to 1e-12 s): RK4_TOL = 1e-8.
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import fmpy
import numpy as np
import pytest

from cosim.errors import UserError
from cosim.execution.run import run_scenario
from cosim.execution.validate import validate_scenario
from cosim.scenario.loader import load_scenario
from tests.fmu.test_model_exchange_fmu import analytic

VERSIONS = [2, 3]
ME_TOL = 1e-9
RK4_TOL = 1e-8


def scenario_file(tmp_path: Path, component: str, duration: float = 2.0,
                  extra: str = "") -> Path:
    """A scenario YAML with one FMU component `ball` (or `lag`) given as a YAML flow map."""
    path = tmp_path / "me.yaml"
    path.write_text(f"name: me\nduration: {duration}\ntick: 0.01\n"
                    f"components:\n  {component}\n{extra}")
    return path


def run(tmp_path: Path, yaml: Path) -> tuple[dict[str, np.ndarray], dict]:
    """Run in-process; (column -> values, manifest)."""
    result = run_scenario(load_scenario(yaml), tmp_path / "run", progress=False)
    assert result.status == "ok", result.error
    with result.signals.open() as stream:
        rows = list(csv.DictReader(stream))
    columns = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    return columns, json.loads(result.manifest.read_text())


def fmpy_me(fmu: Path, stop: float, solver: str, **kwargs) -> np.ndarray:
    return fmpy.simulate_fmu(str(fmu), fmi_type="ModelExchange", stop_time=stop,
                             output_interval=0.01, step_size=0.01, solver=solver,
                             record_events=False, **kwargs)


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("method", ["cvode", "euler"])
def test_bouncing_ball_matches_fmpy(tmp_path, test_fmu, version, method) -> None:
    fmu = test_fmu("BouncingBall", version)
    solver = ("{method: cvode, rtol: 1.0e-6, max_step: 0.08}" if method == "cvode"  # fmpy's: 4 s / 50
              else "{method: euler, max_step: 0.01}")
    ours, manifest = run(tmp_path, scenario_file(
        tmp_path, f"ball: {{fmu: {fmu}, interface: model_exchange, solver: {solver}}}", 4.0))
    ref = fmpy_me(fmu, 4.0, "CVode" if method == "cvode" else "Euler", relative_tolerance=1e-6)
    assert np.array_equal(ours["time"], ref["time"])
    for name in ("h", "v"):
        assert np.max(np.abs(ours[f"ball.{name}"] - ref[name])) <= ME_TOL, name
    for name in ("bounces", "resting", "kicked"):  # Int32 / Integer and Booleans: exact
        assert ours[f"ball.{name}"].tolist() == ref[name].astype(float).tolist(), name
    assert manifest["signals"]["ball.bounces"]["type"] == ("Integer" if version == 2 else "Int32")
    assert manifest["fmus"]["ball"]["fmi_type"] == "ModelExchange"
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    # impacts at 0.45, 1.08, 1.53, 1.84, 2.05 (rest), 3.82 s; the kick at 3 s
    assert (metrics["ball.state_events"], metrics["ball.time_events"]) == (6.0, 1.0)


@pytest.mark.parametrize("version", VERSIONS)
def test_rk4_follows_the_analytic_ball_through_its_events(tmp_path, test_fmu, version) -> None:
    fmu = test_fmu("BouncingBallME", version)  # ME only: no `interface:` needed
    ours, manifest = run(tmp_path, scenario_file(
        tmp_path, f"ball: {{fmu: {fmu}, solver: {{method: rk4, max_step: 0.005}}}}", 5.0))
    assert manifest["fmus"]["ball"]["fmi_type"] == "ModelExchange"
    for k in range(0, len(ours["time"]), 37):
        _, (h, v, _) = analytic(ours["time"][k])
        assert ours["ball.h"][k] == pytest.approx(h, abs=RK4_TOL)
        assert ours["ball.v"][k] == pytest.approx(v, abs=RK4_TOL)


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("method", ["cvode", "euler"])
def test_an_input_step_is_an_input_event_as_in_fmpy(tmp_path, test_fmu, version, method) -> None:
    """u steps 0 -> 1 at 0.5 s: the master holds u over each tick, so the lag
    sees the step at 0.5 s, where fmpy's input table (a repeated time) puts it."""
    fmu = test_fmu("LagME", version)
    max_step = 0.04 if method == "cvode" else 0.01  # fmpy's: 2 s / 50, and its Euler's tick
    yaml = scenario_file(tmp_path, f"lag: {{fmu: {fmu}, interface: model_exchange, "
                         f"solver: {{method: {method}, max_step: {max_step}}}}}",
                         extra="sources:\n  u: {kind: step, initial: 0.0, final: 1.0, at: 0.5}\n"
                               "connections:\n  - u.value -> lag.u\n")
    ours, _ = run(tmp_path, yaml)
    table = np.array([(0.0, 0.0), (0.5, 0.0), (0.5, 1.0), (2.0, 1.0)],
                     dtype=[("time", float), ("u", float)])
    ref = fmpy_me(fmu, 2.0, "CVode" if method == "cvode" else "Euler", input=table)
    assert np.max(np.abs(ours["lag.y"] - ref["y"])) <= ME_TOL
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["lag.input_events"] == 1.0
    k = int(np.searchsorted(ours["time"], 1.5))  # y = K (1 - exp(-(t - 0.5) / tau))
    exact = 2.0 * (1.0 - np.exp(-(ours["time"][k] - 0.5) / 0.5))
    assert ours["lag.y"][k] == pytest.approx(exact, rel=2e-2 if method == "euler" else 1e-4)


def test_an_fmu_with_both_interfaces_runs_co_simulation_unless_asked(tmp_path, test_fmu) -> None:
    fmu = test_fmu("BouncingBall", 2)
    default = validate_scenario(load_scenario(scenario_file(tmp_path, f"ball: {{fmu: {fmu}}}")))
    assert default["order"] == ["ball"]
    _, manifest = run(tmp_path, scenario_file(tmp_path, f"ball: {{fmu: {fmu}}}"))
    assert (manifest["fmus"]["ball"]["fmi_type"], manifest["fmus"]["ball"]["solver"]) == \
        ("CoSimulation", None)


@pytest.mark.parametrize("model, fields, message", [
    ("BouncingBall", "solver: {method: rk4}",
     r"me\.yaml:\d+: components\.ball\.solver: solver: applies to Model Exchange only"),
    ("Lag", "interface: model_exchange",
     r"Lag\.fmu: the FMU does not offer model exchange \(it offers: co_simulation\)"),
    ("BouncingBallME", "solver: {method: dopri}", r"components\.ball\.solver\.method"),
    ("BouncingBallME", "host: far",
     r"components\.ball\.host: a Model Exchange FMU runs in the master's process"),
])
def test_interface_and_solver_mistakes_are_located(tmp_path, test_fmu, model, fields,
                                                   message) -> None:
    yaml = scenario_file(tmp_path, f"ball: {{fmu: {test_fmu(model, 2)}, {fields}}}")
    with pytest.raises(UserError, match=message):
        validate_scenario(load_scenario(yaml))


def test_default_cvode_settings_are_fmpys(tmp_path, test_fmu) -> None:
    """No `solver:`: CVode, rtol 1e-5, max_step duration / 50, as fmpy.simulate_fmu."""
    fmu = test_fmu("BouncingBallME", 3)
    ours, manifest = run(tmp_path, scenario_file(tmp_path, f"ball: {{fmu: {fmu}}}", 2.5))
    assert manifest["fmus"]["ball"]["solver"] == {"method": "cvode", "rtol": 1e-5,
                                                  "atol": None, "max_step": 0.05}
    ref = fmpy_me(fmu, 2.5, "CVode")
    assert np.max(np.abs(ours["ball.h"] - ref["h"])) <= ME_TOL


def lag_component(fmu: Path, method: str = "cvode"):
    from cosim.fmu.interface import describe_fmu
    from cosim.fmu.model_exchange import ModelExchangeComponent

    interface = describe_fmu(fmu, kind="model_exchange")
    interface.model_description.modelExchange.needsCompletedIntegratorStep = True
    settings = {"method": method, "rtol": 1e-5, "atol": None, "max_step": 0.01}
    return ModelExchangeComponent("lag", fmu, interface, {}, 1, settings)


@pytest.mark.parametrize("version", VERSIONS)
def test_a_step_event_from_completed_integrator_step_runs_the_event_iteration(
        test_fmu, version) -> None:
    comp = lag_component(test_fmu("LagME", version))
    comp.start(0.0, {"u": 1.0})
    calls, entered = [], []
    real_completed, real_enter = comp._fmu.completedIntegratorStep, comp._fmu.enterEventMode
    comp._fmu.completedIntegratorStep = lambda: (calls.append(real_completed()) or
                                                 (len(calls) == 3, False))
    comp._fmu.enterEventMode = lambda: entered.append(real_enter())
    for tick in range(1, 6):
        comp.step(tick, tick * 0.01, {"u": 1.0})
    metrics = comp.stop()
    assert len(calls) == 5 and len(entered) == 1
    assert metrics == {"time_events": 0.0, "state_events": 0.0, "step_events": 1.0,
                       "input_events": 0.0}


def test_a_termination_request_from_completed_integrator_step_ends_the_run(test_fmu) -> None:
    """The step that asked is the tick's row: the outputs at its end (y of the lag at 0.01,
    one RK4 step: local error O((h / tau)^5), 1.3e-9 relative here)."""
    from cosim.errors import StopRequested

    comp = lag_component(test_fmu("LagME", 3), method="rk4")
    comp.start(0.0, {"u": 1.0})
    comp._fmu.completedIntegratorStep = lambda: (False, True)
    with pytest.raises(StopRequested, match="the FMU asked to terminate the simulation") as asked:
        comp.step(1, 0.01, {"u": 1.0})
    comp.stop()
    assert (asked.value.tick, asked.value.time) == (1, 0.01)
    assert asked.value.outputs["y"] == pytest.approx(2.0 * (1.0 - np.exp(-0.01 / 0.5)), rel=1e-8)


@pytest.mark.parametrize("version", VERSIONS)
def test_a_fatal_status_inside_cvode_fails_the_step_and_no_fmi_call_follows(
        test_fmu, version, monkeypatch) -> None:
    """CVode calls the derivatives from C: a Fatal there ends the step with the failure
    (no traceback, no further integration) and no FMI function is called after it."""
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Model
    from fmpy.fmi3 import FMU3Model

    from cosim.errors import ComponentFailure

    cls = FMU2Model if version == 2 else FMU3Model
    derivatives = "getDerivatives" if version == 2 else "getContinuousStateDerivatives"
    made, state = [], {"armed": False}
    for name in (derivatives, "getEventIndicators", "setTime", "setContinuousStates",
                 "getContinuousStates", "completedIntegratorStep", "enterEventMode",
                 "terminate", "freeInstance"):
        def spy(self, *args, _original=getattr(cls, name), _name=name):
            made.append(_name)
            if _name == derivatives and state["armed"]:
                state["armed"], state["fatal_at"] = False, len(made)
                raise FMICallException(f"fmi{version}GetDerivatives", 4)
            return _original(self, *args)
        monkeypatch.setattr(cls, name, spy)
    comp = lag_component(test_fmu("LagME", version))
    comp.start(0.0, {"u": 1.0})
    comp.step(1, 0.01, {"u": 1.0})
    state["armed"] = True
    with pytest.raises(ComponentFailure, match="failed with status 4") as failed:
        comp.step(2, 0.02, {"u": 1.0})
    comp.stop()
    assert failed.value.details == {"kind": "fmi_status", "status": "Fatal"}
    assert (failed.value.tick, failed.value.time) == (2, 0.02)
    assert made[state["fatal_at"]:] == []


@pytest.mark.parametrize("version", VERSIONS)
def test_an_isolated_model_exchange_fmu_gives_the_same_bits(tmp_path, test_fmu, version) -> None:
    """isolate: true runs the same host and solver in a process of its own: the bouncing
    ball's state and time events and the lag's input event give identical signals."""
    ball, lag = test_fmu("BouncingBallME", version), test_fmu("LagME", version)
    results = []
    for isolate in ("false", "true"):
        folder = tmp_path / isolate
        folder.mkdir()
        yaml = scenario_file(folder, f"ball: {{fmu: {ball}, isolate: {isolate}}}\n"
                             f"  lag: {{fmu: {lag}, interface: model_exchange, isolate: {isolate}, "
                             "solver: {method: rk4, max_step: 0.01}}", 3.5,
                             extra="sources:\n  u: {kind: step, initial: 0.0, final: 1.0, "
                                   "at: 0.5}\nconnections:\n  - u.value -> lag.u\n")
        columns, manifest = run(folder, yaml)
        metrics = json.loads((folder / "run" / "metrics.json").read_text())
        results.append((columns, {k: v for k, v in metrics.items() if k.endswith("_events")}))
    (ours, events), (isolated, isolated_events) = results
    assert list(ours) == list(isolated) and len(ours["time"]) == 351
    assert all(np.array_equal(ours[k], isolated[k]) for k in ours)
    assert events == isolated_events
    assert (events["ball.state_events"], events["ball.time_events"]) == (5.0, 1.0)
    assert events["lag.input_events"] == 1.0
