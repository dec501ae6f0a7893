"""The Faulty test FMU (tests/fmus/Faulty, FaultyOnce) behaves as documented under fmpy.

Every fault mode of tests/fmus/README.md, in FMI 2.0 and 3.0: the modes that
kill or block the process run in a child process (run_isolated) with a
timeout; the others run in this process and check the FMI status, the logged
message (status, category, text) and the termination flag. The non-Real
outputs (Int32, UInt8, Int16, Boolean, Float32) are read back with their values.

All runs: fault_time = 0.5 s, communication step 0.1 s, so the fault fires in
the step from t = 0.4 to 0.5 and the last completed communication point
before it is t = 0.4.
"""
from __future__ import annotations

import signal

import fmpy
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2LastSuccessfulTime, fmi2Terminated
from fmpy.validation import validate_fmu

VERSIONS = [2, 3]
FAULT = {"fault_time": 0.5}
OK, WARNING, DISCARD, ERROR, FATAL = range(5)  # fmi2Status / fmi3Status values


def simulate(path, start_values, messages, stop_time=1.0):
    """fmpy.simulate_fmu at 0.1 s with a logger appending (status, category, message)."""
    def log2(env, name, status, category, message):
        messages.append((status, category.decode(), message.decode()))

    def log3(env, status, category, message):
        messages.append((status, category.decode(), message.decode()))

    version = fmpy.read_model_description(str(path)).fmiVersion
    return fmpy.simulate_fmu(str(path), stop_time=stop_time, output_interval=0.1,
                             start_values=start_values,
                             logger=log2 if version == "2.0" else log3)


@pytest.mark.parametrize("model", ["Faulty", "FaultyOnce"])
@pytest.mark.parametrize("version", VERSIONS)
def test_fmpy_validate_reports_no_problem(test_fmu, model, version):
    assert validate_fmu(str(test_fmu(model, version))) == []


@pytest.mark.parametrize("version", VERSIONS)
def test_model_description_declares_the_types(test_fmu, version):
    md = fmpy.read_model_description(str(test_fmu("Faulty", version)))
    types = {v.name: v.type for v in md.modelVariables}
    variability = {v.name: v.variability for v in md.modelVariables}
    if version == 2:
        expect = {"y": "Real", "y_f32": "Real", "ticks": "Integer", "ticks_u8": "Integer",
                  "ticks_i16": "Integer", "flag": "Boolean", "k_in": "Integer",
                  "b_in": "Boolean", "tick_increment": "Integer", "invert_flag": "Boolean"}
    else:
        expect = {"y": "Float64", "y_f32": "Float32", "ticks": "Int32", "ticks_u8": "UInt8",
                  "ticks_i16": "Int16", "flag": "Boolean", "k_in": "Int32",
                  "b_in": "Boolean", "tick_increment": "Int32", "invert_flag": "Boolean"}
    assert {k: types[k] for k in expect} == expect
    assert variability["ticks"] == variability["flag"] == "discrete"
    assert variability["y"] == "continuous"
    assert md.coSimulation.canBeInstantiatedOnlyOncePerProcess is False
    assert md.modelExchange is None


@pytest.mark.parametrize("version", VERSIONS)
def test_no_fault_outputs_of_every_type(test_fmu, version):
    """fault_mode 0: ramp, counters and flags read back exactly, with their types."""
    messages = []
    res = simulate(test_fmu("Faulty", version),
                   {"fault_mode": 0, "tick_increment": 3, "invert_flag": True, "k_in": -21,
                    "b_in": True, "u": 1.5}, messages)
    n = np.arange(11)
    np.testing.assert_array_equal(res["time"], n * 0.1)
    np.testing.assert_array_equal(res["y"], res["time"])
    np.testing.assert_array_equal(res["y_f32"], res["time"].astype(np.float32))
    np.testing.assert_array_equal(res["u_echo"], 1.5)
    np.testing.assert_array_equal(res["ticks"], 3 * n)
    np.testing.assert_array_equal(res["ticks_u8"], n % 256)
    np.testing.assert_array_equal(res["ticks_i16"], -n)
    np.testing.assert_array_equal(res["flag"], (n % 2 == 1) != True)  # noqa: E712 (inverted)
    np.testing.assert_array_equal(res["k_twice"], -42)
    np.testing.assert_array_equal(res["b_not"], False)
    assert res["ticks"].dtype.kind == "i" and res["flag"].dtype == np.bool_
    assert messages == []


@pytest.mark.parametrize("version", VERSIONS)
def test_typed_get_and_set_through_the_api(test_fmu, open_fmu, version):
    """Typed access: each variable through the function of its type; a wrong type is an error."""
    inst = open_fmu(test_fmu("Faulty", version))
    inst.init({"tick_increment": -7, "k_in": 5, "b_in": False})
    for k in range(4):
        inst.fmu.doStep(k * 0.1, 0.1)
    assert inst.get("ticks") == -28 and inst.get("ticks_u8") == 4 and inst.get("ticks_i16") == -4
    # fmpy returns FMI2 Booleans as int (fmi2Boolean is a C int), FMI3 ones as bool
    assert bool(inst.get("flag")) is False and bool(inst.get("b_not")) is True
    assert inst.get("k_twice") == 10
    inst.set({"k_in": 1000000, "b_in": True})
    inst.fmu.doStep(0.4, 0.1)
    assert inst.get("k_twice") == 2000000 and bool(inst.get("b_not")) is False
    getter = inst.fmu.getReal if version == 2 else inst.fmu.getFloat64
    with pytest.raises(FMICallException):
        getter([inst.vr["ticks"]])
    expected = "ticks is a Int32 variable (use the function of its type)"
    assert any(expected in m for m in inst.texts()), inst.messages


@pytest.mark.parametrize("version", VERSIONS)
def test_integer_parameters_are_range_checked(test_fmu, open_fmu, version):
    inst = open_fmu(test_fmu("Faulty", version))
    inst.set({"tick_increment": 5000})
    with pytest.raises(FMICallException):
        inst.init()
    assert any("parameter tick_increment = 5000 is outside its valid range [-1000, 1000]" in m
               for m in inst.texts()), inst.messages


@pytest.mark.parametrize("version", VERSIONS)
def test_non_integral_fault_mode_is_rejected(test_fmu, open_fmu, version):
    inst = open_fmu(test_fmu("Faulty", version))
    inst.set({"fault_mode": 2.5})
    with pytest.raises(FMICallException):
        inst.init()
    assert any("fault_mode must be an integer 0..10, got 2.5" in m for m in inst.texts())


CRASHES = {1: -signal.SIGSEGV, 2: -signal.SIGABRT, 3: 3}


@pytest.mark.parametrize("mode", sorted(CRASHES))
@pytest.mark.parametrize("version", VERSIONS)
def test_crash_modes_kill_the_process_in_the_fault_step(test_fmu, run_isolated, version, mode):
    """1 segfault -> SIGSEGV, 2 abort() -> SIGABRT, 3 exit(3) -> exit code 3, after t = 0.4."""
    run = run_isolated(test_fmu("Faulty", version), {"fault_mode": mode, **FAULT})
    assert run.returncode == CRASHES[mode], run.stderr
    assert run.result is None and run.exception is None
    assert run.times == pytest.approx([0.1, 0.2, 0.3, 0.4])


@pytest.mark.parametrize("mode", [4, 8])
@pytest.mark.parametrize("version", VERSIONS)
def test_hang_modes_never_return_from_the_fault_step(test_fmu, run_isolated, version, mode):
    """4 busy loop, 8 sleeping: doStep does not return; the child is killed after 3 s."""
    run = run_isolated(test_fmu("Faulty", version), {"fault_mode": mode, **FAULT}, timeout=3.0)
    assert run.returncode is None
    assert run.times == pytest.approx([0.1, 0.2, 0.3, 0.4])
    assert run.result is None and run.exception is None


@pytest.mark.parametrize("version", VERSIONS)
def test_fatal_mode_returns_fatal_with_a_message(test_fmu, run_isolated, version):
    """5: doStep returns Fatal (in a child: fmpy does not free an instance after Fatal)."""
    run = run_isolated(test_fmu("Faulty", version), {"fault_mode": 5, **FAULT})
    assert run.returncode == 0 and run.status == FATAL
    assert f"fmi{version}DoStep" in run.exception
    assert (ERROR, "logStatusError",
            "Faulty: injected fatal error in the step from t = 0.4 to 0.5 (fault_mode 5)") \
        in run.messages


@pytest.mark.parametrize("version", VERSIONS)
def test_error_mode_logs_then_returns_error(test_fmu, open_fmu, version):
    """6: a clear message in category logStatusError, then doStep returns Error."""
    inst = open_fmu(test_fmu("Faulty", version))
    inst.init({"fault_mode": 6, **FAULT})
    for k in range(4):
        inst.fmu.doStep(k * 0.1, 0.1)
    with pytest.raises(FMICallException) as err:
        inst.fmu.doStep(0.4, 0.1)
    assert err.value.status == ERROR
    assert inst.messages[0] == (ERROR, "logStatusError",
                                "Faulty: injected error in the step from t = 0.4 to 0.5 (fault_mode 6)")
    assert inst.get("y") == pytest.approx(0.4)  # the failed step did not update the outputs
    with pytest.raises(FMICallException):  # the instance stays in error
        inst.fmu.doStep(0.5, 0.1)


@pytest.mark.parametrize("version", VERSIONS)
def test_terminate_mode_requests_the_end_of_the_simulation(test_fmu, open_fmu, version):
    """7: FMI2 Discard + fmi2Terminated + lastSuccessfulTime; FMI3 OK + terminateSimulation."""
    inst = open_fmu(test_fmu("Faulty", version))
    inst.init({"fault_mode": 7, **FAULT})
    for k in range(4):
        inst.fmu.doStep(k * 0.1, 0.1)
    if version == 2:
        assert not inst.fmu.getBooleanStatus(fmi2Terminated)
        with pytest.raises(FMICallException) as err:
            inst.fmu.doStep(0.4, 0.1)
        assert err.value.status == DISCARD
        assert inst.fmu.getBooleanStatus(fmi2Terminated)
        assert inst.fmu.getRealStatus(fmi2LastSuccessfulTime) == pytest.approx(0.5)
    else:
        event, terminate, early, last = inst.fmu.doStep(0.4, 0.1)
        assert terminate and not event and not early and last == pytest.approx(0.5)
    assert inst.get("y") == pytest.approx(0.5) and inst.get("ticks") == 5  # the step completed
    with pytest.raises(FMICallException):
        inst.fmu.doStep(0.5, 0.1)
    assert any("asked to end the simulation at t = 0.5; call terminate" in m for m in inst.texts())


@pytest.mark.parametrize("version", VERSIONS)
def test_terminate_mode_ends_an_fmpy_simulation_at_fault_time(test_fmu, version):
    messages = []
    res = simulate(test_fmu("Faulty", version), {"fault_mode": 7, **FAULT}, messages)
    assert res["time"][-1] == pytest.approx(0.5) and res["ticks"][-1] == 5
    assert messages == []


@pytest.mark.parametrize("version", VERSIONS)
def test_warning_mode_logs_every_step_from_fault_time_on(test_fmu, version):
    """9: Warning status and a logStatusWarning message per step; the values stay right."""
    messages = []
    res = simulate(test_fmu("Faulty", version), {"fault_mode": 9, **FAULT}, messages)
    np.testing.assert_array_equal(res["ticks"], np.arange(11))
    starts = [0.4, 0.5, 0.6, 0.7, 0.8, 0.9]
    assert [status for status, _, _ in messages] == [WARNING] * len(starts)
    assert {category for _, category, _ in messages} == {"logStatusWarning"}
    assert messages[0][2] == "Faulty: injected warning in the step from t = 0.4 to 0.5 (fault_mode 9)"


@pytest.mark.parametrize("version", VERSIONS)
def test_nan_mode_is_caught_by_the_output_check(test_fmu, open_fmu, version):
    """10: y = NaN; the framework fails the step with Error naming the output."""
    inst = open_fmu(test_fmu("Faulty", version))
    inst.init({"fault_mode": 10, **FAULT})
    for k in range(4):
        inst.fmu.doStep(k * 0.1, 0.1)
    with pytest.raises(FMICallException) as err:
        inst.fmu.doStep(0.4, 0.1)
    assert err.value.status == ERROR
    assert any("doStep: Faulty output y = nan is not finite at t = 0.5" in m for m in inst.texts())


@pytest.mark.parametrize("version", VERSIONS)
def test_debug_log_names_the_fault_when_logging_is_on(test_fmu, open_fmu, version):
    inst = open_fmu(test_fmu("Faulty", version), logging_on=True)
    inst.init({"fault_mode": 7, **FAULT})
    for k in range(4):
        inst.fmu.doStep(k * 0.1, 0.1)
    try:
        inst.fmu.doStep(0.4, 0.1)
    except FMICallException:  # FMI2: Discard
        pass
    assert (OK, "logInfo", "Faulty: fault_mode 7 (termination request) fires in the step "
                           "from t = 0.4 to 0.5") in inst.messages


@pytest.mark.parametrize("version", VERSIONS)
def test_once_per_process_variant_refuses_a_second_instance(test_fmu, open_fmu, version):
    """FaultyOnce declares canBeInstantiatedOnlyOncePerProcess and enforces it.

    The count is per loaded binary: a second copy of the FMU extracted elsewhere
    is another library with its own count (what an importer must not rely on).
    """
    path = test_fmu("FaultyOnce", version)
    assert fmpy.read_model_description(str(path)).coSimulation.canBeInstantiatedOnlyOncePerProcess
    first = open_fmu(path)
    with pytest.raises(Exception) as err:
        open_fmu(path, unzip=first.unzip)
    assert (ERROR, "logStatusError",
            'instantiate: FaultyOnce can be instantiated only once per process '
            '(canBeInstantiatedOnlyOncePerProcess="true") and 1 instance(s) exist') \
        in err.value.messages
    first.free()
    again = open_fmu(path, unzip=first.unzip)  # the first one is gone: allowed again
    again.init()
    again.fmu.doStep(0.0, 0.1)
    assert again.get("ticks") == 1


@pytest.mark.parametrize("version", VERSIONS)
def test_plain_faulty_allows_two_instances(test_fmu, open_fmu, version):
    a = open_fmu(test_fmu("Faulty", version))
    b = open_fmu(test_fmu("Faulty", version), unzip=a.unzip)  # the same loaded binary
    for inst in (a, b):
        inst.init()
        inst.fmu.doStep(0.0, 0.1)
    assert a.get("ticks") == b.get("ticks") == 1
