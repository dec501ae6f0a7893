"""Model Exchange in the FMU framework: tests/fmus/BouncingBall (ME + CS) and
BouncingBallME (ME only), FMI 2.0 and 3.0, against the analytic solution.

Defaults: h0 = 1 m, g = 9.81 m/s2, e = 0.7, v_min = 1 m/s, kick of 4 m/s at
t_kick = 3 s. The impacts are at 0.4515, 1.0837, 1.5261, 1.8359, 2.0526 s
(rest), the kick at 3 s, then impacts at 3.8155, 4.3863, 4.7859 s.

- fmpy's ModelExchange simulation with CVode must find every event at the
  analytic time: within 1e-6 s with relative_tolerance = 1e-8 (observed
  6e-8 s), within 1e-3 s with fmpy's default tolerance (observed 8e-5 s by
  the 5th impact: CVode's error, it shrinks with the tolerance: 6e-6 s at
  1e-6, 7e-10 s at 1e-10).
- Co-simulation goes through the framework's RK4 integrator with bisection
  event location: exact for this piecewise-parabolic motion, so h and v at the
  communication points match the analytic ones within STATE_TOL = 1e-8.
"""
from __future__ import annotations

import ctypes
import math

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

VERSIONS = [2, 3]
EVENT_TOL = 1e-6   # s, ME event times vs analytic, CVode relative_tolerance 1e-8
STATE_TOL = 1e-8   # m and m/s, CS states vs analytic
DEFAULTS = dict(h0=1.0, v0=0.0, g=9.81, e=0.7, v_min=1.0, t_kick=3.0, v_kick=4.0)
ERROR = 3


def analytic(t_stop: float, p: dict = DEFAULTS):
    """Exact motion up to t_stop: (events [(t, "impact"|"kick")], final (h, v, bounces))."""
    t, h, v = 0.0, p["h0"], p["v0"]
    resting, kicked, bounces, events = h == 0.0 and v == 0.0, False, 0, []
    g = p["g"]
    while True:
        t_hit = math.inf if resting else t + (v + math.sqrt(v * v + 2 * g * h)) / g
        t_kick = math.inf if kicked else p["t_kick"]
        t_next = min(t_hit, t_kick, t_stop)
        if not resting:
            dt = t_next - t
            h, v = h + v * dt - 0.5 * g * dt * dt, v - g * dt
        t = t_next
        if t_next == t_stop:
            return events, (h, v, bounces)
        if t_kick <= t_hit:
            kicked, v = True, v + p["v_kick"]
            if resting:
                resting, v = (False, v) if v > 0 else (True, 0.0)
            events.append((t, "kick"))
        else:
            bounces, h, v = bounces + 1, 0.0, -p["e"] * v
            if v < p["v_min"]:
                resting, v = True, 0.0
            events.append((t, "impact"))


def event_times(res) -> np.ndarray:
    """fmpy records an event as two rows at the same time (before and after)."""
    t = res["time"]
    return t[1:][np.diff(t) == 0]


@pytest.mark.parametrize("model", ["BouncingBall", "BouncingBallME"])
@pytest.mark.parametrize("version", VERSIONS)
def test_fmpy_validate_reports_no_problem(test_fmu, model, version):
    assert validate_fmu(str(test_fmu(model, version))) == []


@pytest.mark.parametrize("version", VERSIONS)
def test_model_description_declares_model_exchange(test_fmu, version):
    md = fmpy.read_model_description(str(test_fmu("BouncingBall", version)))
    assert md.modelExchange.modelIdentifier == "BouncingBall"
    assert md.coSimulation.modelIdentifier == "BouncingBall"
    assert md.numberOfEventIndicators == 1
    assert [(d.variable.name, d.variable.derivative.name) for d in md.derivatives] == \
        [("der_h", "h"), ("der_v", "v")]
    if version == 3:
        assert [u.variable.name for u in md.eventIndicators] == ["z_floor"]
    types = {v.name: v.type for v in md.modelVariables}
    assert types["bounces"] == ("Integer" if version == 2 else "Int32")
    assert types["resting"] == types["kicked"] == "Boolean"
    only_me = fmpy.read_model_description(str(test_fmu("BouncingBallME", version)))
    assert only_me.coSimulation is None and only_me.modelExchange is not None


@pytest.mark.parametrize("rtol,event_tol", [(1e-8, EVENT_TOL), (None, 1e-3)],
                         ids=["rtol1e-8", "default-rtol"])
@pytest.mark.parametrize("model", ["BouncingBall", "BouncingBallME"])
@pytest.mark.parametrize("version", VERSIONS)
def test_cvode_event_times_match_the_analytic_ones(test_fmu, model, version, rtol, event_tol):
    options = {} if rtol is None else {"relative_tolerance": rtol}
    res = fmpy.simulate_fmu(str(test_fmu(model, version)), fmi_type="ModelExchange",
                            solver="CVode", stop_time=5.0, output_interval=0.01, **options)
    events, (h_end, v_end, bounces_end) = analytic(5.0)
    expected = [t for t, _ in events]
    found = event_times(res)
    assert len(found) == len(expected) == 9, (found, expected)
    np.testing.assert_allclose(found, expected, rtol=0, atol=event_tol)
    assert res["bounces"][-1] == bounces_end == 8
    np.testing.assert_allclose([res["h"][-1], res["v"][-1]], [h_end, v_end],
                               atol=100 * event_tol)


@pytest.mark.parametrize("version", VERSIONS)
def test_discrete_outputs_change_at_the_events(test_fmu, version):
    """Int32 bounces and Boolean resting/kicked, recorded through Model Exchange."""
    res = fmpy.simulate_fmu(str(test_fmu("BouncingBall", version)), fmi_type="ModelExchange",
                            stop_time=5.0, output_interval=0.01, relative_tolerance=1e-8)
    t = res["time"]
    assert res["bounces"].dtype.kind == "i" and res["resting"].dtype == np.bool_
    impacts = [t for t, kind in analytic(5.0)[0] if kind == "impact"]
    for k in range(len(impacts) + 1):  # between impact k and k+1 the count is k
        lo = impacts[k - 1] if k else 0.0
        hi = impacts[k] if k < len(impacts) else 5.0
        inside = (t > lo + 1e-6) & (t < hi - 1e-6)
        assert set(res["bounces"][inside]) == {k}, k
    rest = (t > impacts[4] + 1e-6) & (t < 3.0 - 1e-9)
    assert res["resting"][rest].all() and not res["resting"][t < impacts[4] - 1e-6].any()
    assert not res["kicked"][t < 3.0 - 1e-9].any() and res["kicked"][t > 3.0 + 1e-9].all()
    np.testing.assert_array_equal(res["h"][rest], 0.0)


@pytest.mark.parametrize("version", VERSIONS)
def test_cosimulation_matches_the_analytic_motion(test_fmu, version):
    """The framework's integrator: h, v and bounces at every communication point."""
    res = fmpy.simulate_fmu(str(test_fmu("BouncingBall", version)), fmi_type="CoSimulation",
                            stop_time=5.0, output_interval=0.01)
    for row in res[::7]:
        _, (h, v, bounces) = analytic(float(row["time"]))
        assert row["h"] == pytest.approx(h, abs=STATE_TOL), row["time"]
        assert row["v"] == pytest.approx(v, abs=STATE_TOL), row["time"]
        assert row["bounces"] == bounces, row["time"]


@pytest.mark.parametrize("version", VERSIONS)
def test_cosimulation_with_large_steps_still_catches_every_event(test_fmu, version):
    res = fmpy.simulate_fmu(str(test_fmu("BouncingBall", version)), fmi_type="CoSimulation",
                            stop_time=5.0, output_interval=0.25)
    _, (h, v, bounces) = analytic(5.0)
    assert res["bounces"][-1] == bounces
    assert [res["h"][-1], res["v"][-1]] == pytest.approx([h, v], abs=STATE_TOL)


def test_parameters_change_the_events(test_fmu):
    params = dict(DEFAULTS, h0=2.0, e=0.5, v_min=0.5, t_kick=10.0)
    res = fmpy.simulate_fmu(str(test_fmu("BouncingBall", 2)), fmi_type="ModelExchange",
                            stop_time=4.0, output_interval=0.01, relative_tolerance=1e-8,
                            start_values={k: params[k] for k in ("h0", "e", "v_min", "t_kick")})
    expected = [t for t, _ in analytic(4.0, params)[0]]
    np.testing.assert_allclose(event_times(res), expected, rtol=0, atol=EVENT_TOL)


@pytest.mark.parametrize("version", VERSIONS)
def test_model_exchange_only_variant_refuses_cosimulation(test_fmu, open_fmu, version):
    with pytest.raises(Exception) as err:
        open_fmu(test_fmu("BouncingBallME", version), "CoSimulation")
    assert (ERROR, "logStatusError", "instantiate: BouncingBallME does not support "
            "co-simulation (Model Exchange only)") in err.value.messages


@pytest.mark.parametrize("version", VERSIONS)
def test_cosimulation_only_model_refuses_model_exchange(test_fmu, open_fmu, version):
    with pytest.raises(Exception) as err:
        open_fmu(test_fmu("Faulty", version), "ModelExchange")
    assert (ERROR, "logStatusError", "instantiate: Faulty does not support Model Exchange "
            "(co-simulation only)") in err.value.messages


@pytest.mark.parametrize("version", VERSIONS)
def test_model_exchange_call_sequence_by_hand(test_fmu, open_fmu, version):
    """The ME functions directly: states, derivatives, indicators, event update."""
    inst = open_fmu(test_fmu("BouncingBall", version), "ModelExchange")
    inst.init()
    fmu = inst.fmu
    update = fmu.newDiscreteStates if version == 2 else fmu.updateDiscreteStates
    get_dx = fmu.getDerivatives if version == 2 else fmu.getContinuousStateDerivatives
    # (discreteStatesNeedUpdate, terminate, nominalsChanged, valuesChanged,
    #  nextEventTimeDefined, nextEventTime), the same tuple in fmpy for FMI 2 and 3
    assert tuple(update()) == (False, False, False, False, True, 3.0)
    fmu.enterContinuousTimeMode()
    x, dx, z = (ctypes.c_double * 2)(), (ctypes.c_double * 2)(), (ctypes.c_double * 1)()
    fmu.getContinuousStates(x, 2)
    assert list(x) == [1.0, 0.0]
    fmu.setTime(0.5)
    fmu.setContinuousStates((ctypes.c_double * 2)(-0.01, -4.9), 2)
    get_dx(dx, 2)
    fmu.getEventIndicators(z, 1)
    assert list(dx) == [-4.9, -9.81] and list(z) == [-0.01]
    assert inst.get("h") == -0.01
    fmu.enterEventMode()
    needs, terminate, _, changed, defined, t_next = update()
    assert changed and not needs and not terminate and defined and t_next == 3.0
    fmu.getContinuousStates(x, 2)
    assert list(x) == pytest.approx([0.0, 0.7 * 4.9])
    assert inst.get("bounces") == 1
    with pytest.raises(Exception):  # wrong number of states
        fmu.getContinuousStates((ctypes.c_double * 3)(), 3)
    assert any("has 2 continuous states, not 3" in m for m in inst.texts()), inst.messages
