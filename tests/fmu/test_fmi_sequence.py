"""FMI correctness of the FMU hosts, with tests/fmus/Faulty (co-simulation) and FaultyME
(Model Exchange, the fault at a time event): no call the standard forbids after
Fatal or Error, a termination request recorded as fmpy records it,
the FMU's log in run.log and in error messages, DefaultExperiment's start time,
canBeInstantiatedOnlyOncePerProcess."""

from __future__ import annotations

from types import SimpleNamespace

import fmpy
import pytest
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.fmi3 import FMU3Model, FMU3Slave

from cosim.errors import ComponentFailure, StopRequested, UserError
from cosim.execution import fmu_hosting
from cosim.fmu.interface import describe_fmu
from cosim.fmu.isolated import IsolatedFmu
from cosim.fmu.model_exchange import ModelExchangeComponent
from cosim.fmu.typed import TypedFmuComponent, hosted_fmu

FATAL, ERROR, TERMINATE, WARNINGS = 5, 6, 7, 9
CVODE = {"method": "cvode", "rtol": 1e-5, "atol": None, "max_step": 0.02}


def _faulty(path, mode, log_file=None, fault_time=0.03):
    """The host of a Faulty FMU: co-simulation, or Model Exchange (CVode) for FaultyME."""
    parameters = {"fault_mode": mode, "fault_time": fault_time}
    if path.stem.startswith("FaultyME"):
        return ModelExchangeComponent("plant", path, describe_fmu(path, {}), parameters, 1,
                                      CVODE, log_file)
    return hosted_fmu("plant", path, describe_fmu(path, {}), parameters, 1, log_file)


def _run(fmu, ticks, h=0.01):
    """Start and step `fmu`; the outputs after every tick, then the exception that ended it."""
    rows = [fmu.start(0.0, {n.name: 0.0 for n in fmu.inputs})]
    try:
        for k in range(1, ticks + 1):
            rows.append(fmu.step(k, k * h, {n.name: 0.0 for n in fmu.inputs}))
    except (ComponentFailure, StopRequested) as exc:
        return rows, exc
    return rows, None


@pytest.fixture
def calls(monkeypatch):
    """Names of the fmpy lifecycle calls made (terminate, freeInstance), in order."""
    made = []
    for cls in (FMU2Slave, FMU3Slave, FMU2Model, FMU3Model):
        for name in ("terminate", "freeInstance"):
            original = getattr(cls, name)

            def spy(self, *args, _original=original, _name=name, **kwargs):
                made.append(_name)
                return _original(self, *args, **kwargs)
            monkeypatch.setattr(cls, name, spy)
    return made


@pytest.mark.parametrize("model", ["Faulty", "FaultyME"])
@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("mode, allowed", [(FATAL, []), (ERROR, ["freeInstance"]),
                                           (TERMINATE, ["terminate", "freeInstance"])])
def test_after_fatal_no_call_after_error_only_free(faulty_fmus, calls, model, version, mode,
                                                   allowed):
    fmu = _faulty(faulty_fmus[model, version], mode)
    _, ended = _run(fmu, 10)
    assert isinstance(ended, StopRequested if mode == TERMINATE else ComponentFailure)
    assert (ended.tick, ended.time) == (3, 0.03)
    if mode != TERMINATE:
        status = "Fatal" if mode == FATAL else "Error"
        assert ended.details == {"kind": "fmi_status", "status": status}
        assert f"injected {'fatal ' if mode == FATAL else ''}error" in ended.cause
    fmu.stop()
    assert calls == allowed


@pytest.mark.parametrize("model, options", [
    ("Faulty", {"step_size": 0.01}),
    ("FaultyME", {"fmi_type": "ModelExchange", "record_events": True})])
@pytest.mark.parametrize("version", [2, 3])
def test_the_step_that_asks_to_terminate_is_recorded_as_fmpy_does(faulty_fmus, version, model,
                                                                   options):
    """Faulty asks in its doStep to t = 0.03; FaultyME at its time event t = 0.03
    (newDiscreteStates / updateDiscreteStates): the rows are fmpy's up to that point,
    for FaultyME the last one its event row (record_events)."""
    path = faulty_fmus[model, version]
    reference = fmpy.simulate_fmu(str(path), stop_time=0.1, output_interval=0.01,
                                  start_values={"fault_mode": TERMINATE, "fault_time": 0.03},
                                  output=["y", "u_echo"], **options)
    fmu = _faulty(path, TERMINATE)
    rows, ended = _run(fmu, 10)
    assert isinstance(ended, StopRequested) and (ended.tick, ended.time) == (3, 0.03)
    rows.append(ended.outputs)
    fmu.stop()
    assert [(r["y"], r["u_echo"]) for r in rows] == [(r["y"], r["u_echo"]) for r in reference]
    assert [k * 0.01 for k in range(len(rows))] == list(reference["time"])


def test_a_model_exchange_request_inside_a_tick_says_when(faulty_fmus):
    """FaultyME asks at t = 0.025, in the step of tick 3 (to t = 0.03): that tick's row
    holds the outputs at 0.025."""
    fmu = _faulty(faulty_fmus["FaultyME", 3], TERMINATE, fault_time=0.025)
    rows, ended = _run(fmu, 10)
    fmu.stop()
    assert isinstance(ended, StopRequested) and (ended.tick, ended.time) == (3, 0.03)
    assert len(rows) == 3 and ended.outputs["y"] == pytest.approx(0.025, abs=1e-12)
    assert "the FMU asked to terminate the simulation at t=0.025 s (" in ended.reason


def test_an_error_quotes_the_fmus_last_logged_message_and_log_goes_to_run_log(
        faulty_fmus, tmp_path, capsys):
    log = tmp_path / "run.log"
    fmu = _faulty(faulty_fmus["Faulty", 2], ERROR, log)
    _, ended = _run(fmu, 10)
    fmu.stop()
    assert "Faulty: injected error in the step from t = 0.02 to 0.03 (fault_mode 6)" in str(ended)
    assert "initialized at t = 0" not in str(ended)  # the errors, not every message
    lines = log.read_text().splitlines()
    assert "t=0 plant: [OK/logInfo] Faulty initialized at t = 0" in lines
    assert any(line.startswith("t=0.03 plant: [Error/logStatusError] Faulty: injected error")
               for line in lines), lines
    assert "FMU t=0.03 plant: [Error/logStatusError] Faulty: injected error" in capsys.readouterr().err


def test_warnings_reach_the_terminal_a_limited_number_of_times(faulty_fmus, tmp_path, capsys):
    fmu = _faulty(faulty_fmus["Faulty", 3], WARNINGS, tmp_path / "run.log", fault_time=0.01)
    rows, ended = _run(fmu, 40)
    fmu.stop()
    assert ended is None and len(rows) == 41
    shown = [l for l in capsys.readouterr().err.splitlines() if "injected warning" in l]
    assert len(shown) == 20 and shown[-1].endswith("(further messages only in run.log)")
    assert (tmp_path / "run.log").read_text().count("[Warning/logStatusWarning]") == 40


def test_without_log_nothing_is_written_but_errors_still_quote_the_fmu(faulty_fmus, tmp_path):
    fmu = _faulty(faulty_fmus["Faulty", 3], ERROR)
    _, ended = _run(fmu, 10)
    fmu.stop()
    assert "injected error" in str(ended) and not list(tmp_path.iterdir())


def _plan(name, start=None, once=False, path="x.fmu"):
    md = SimpleNamespace(defaultExperiment=SimpleNamespace(startTime=start),
                         coSimulation=SimpleNamespace(canBeInstantiatedOnlyOncePerProcess=once))
    return SimpleNamespace(name=name, interface=SimpleNamespace(model_description=md,
                                                                model_identifier="M"),
                           path=path)


def test_start_time_comes_from_the_scenario_else_the_default_experiment():
    scenario = SimpleNamespace(start_time=None, where=lambda path: "s.yaml: start_time")
    assert fmu_hosting.start_time(scenario, [_plan("a", 2.5), _plan("b")]) == 2.5
    assert fmu_hosting.start_time(scenario, [_plan("b")]) == 0.0
    with pytest.raises(UserError, match=r"start times differ \(a: 2.5 s, b: 1 s\)"):
        fmu_hosting.start_time(scenario, [_plan("a", 2.5), _plan("b", 1.0)])
    assert fmu_hosting.start_time(SimpleNamespace(start_time=-1.0), [_plan("a", 2.5)]) == -1.0


def test_a_second_instance_of_a_once_per_process_fmu_is_isolated(faulty_fmus, tmp_path):
    path = faulty_fmus["FaultyOnce", 2]
    interface = describe_fmu(path, {})
    plans = [SimpleNamespace(name=n, path=path, interface=interface, parameters={},
                             period_ticks=1) for n in ("a", "b", "c")]
    spec = SimpleNamespace(log=False, isolate=False, variables={})
    scenario = SimpleNamespace(components={"a": spec, "b": spec, "c": spec})
    hosted = fmu_hosting.host_fmus(scenario, plans, tmp_path, {"a": 5, "b": 5, "c": 5}, False)
    try:
        assert [type(h) for h in hosted.values()] == [TypedFmuComponent, IsolatedFmu,
                                                      IsolatedFmu]
        finals = []
        for fmu in hosted.values():
            rows, ended = _run(fmu, 5)
            finals.append(rows[-1]["y"])
        assert ended is None and finals == [0.05, 0.05, 0.05]
    finally:
        for fmu in hosted.values():
            fmu.stop()
