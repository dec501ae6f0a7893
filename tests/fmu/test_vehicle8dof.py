"""Physics tests of the Vehicle8DOF plant FMU (fmus/Vehicle8DOF), through fmpy.

The FMU is built once per test session from its C sources with
cosim.fmu.build (the cache of tests/helpers/fmus.py) and simulated with
fmpy.simulate_fmu. Every expectation comes from an analytic result (linear
bicycle steady-state gain, drag law, roll gradient, friction limit) or an exact
symmetry, never from a recorded run. They run the model's default tyre, the
Magic Formula (tyre_model = 1); where the Dugoff tyre (tyre_model = 0, the
design model's mu-scaled tyre) behaves differently, both are asserted. Tests of
steady states at constant speed set the road loads (cx, f_rr) to 0.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy.fmi1 import FMICallException  # noqa: E402

from cosim.fmu.build import FMUS_DIR  # noqa: E402
from tests.helpers.fmus import built_fmu, parse_variables_def  # noqa: E402

G = 9.81
INPUTS = ("delta", "torque", "wind_fx", "wind_fy", "mu")
# Table I defaults and this model's defaults (fmus/Vehicle8DOF/variables.def).
M, IZ, C_F, C_R, L_F, L_R, I_Y, R_W = 1500.0, 2454.0, 57500.0, 57500.0, 1.006, 1.462, 1.2, 0.3
M_UNSPRUNG, H_CG, H_RC, K_ROLL = 200.0, 0.55, 0.1, 88000.0
WHEELBASE = L_F + L_R
VARIABLES_DEF = FMUS_DIR / "Vehicle8DOF" / "variables.def"
M_E = M + I_Y / R_W**2                # eq. 5: iy is the four wheels together (each iy / 4)
F_RR = 0.012                          # default rolling resistance coefficient
PAC_X = (1.5, 0.3, 80000.0)           # default pCx, pEx, Ck of the Magic Formula tyre
STEADY = {"cx": 0.0, "f_rr": 0.0}     # no road load: constant speed in the steady-state tests


@pytest.fixture(scope="module")
def fmu_dir(tmp_path_factory):
    """The unzipped FMI 2.0 FMU (simulate_fmu then skips the unzip), built once per session."""
    return built_fmu(tmp_path_factory.mktemp("fmus"), "Vehicle8DOF", 2)[1]


@pytest.fixture(scope="module")
def bicycle_dir(tmp_path_factory):
    """The paper's linear model, from the same session cache, for cross-checks."""
    return built_fmu(tmp_path_factory.mktemp("bicycle"), "Bicycle", 2)[1]


def simulate(fmu_dir, stop_time, params=None, inputs=None, times=None):
    """Run the FMU with a 10 ms communication step and return the result array.

    Args:
        fmu_dir: unzipped FMU folder.
        stop_time: end time, s.
        params: start values of parameters, by name.
        inputs: per input name, a constant or an array over `times`.
        times: time grid of array inputs (default: [0, stop_time]).
    """
    times = np.array([0.0, stop_time] if times is None else times, dtype=float)
    values = {"delta": 0.0, "torque": 0.0, "wind_fx": 0.0, "wind_fy": 0.0, "mu": 1.0}
    values.update(inputs or {})
    signal = np.zeros(len(times), dtype=[("time", float)] + [(n, float) for n in INPUTS])
    signal["time"] = times
    for name in INPUTS:
        signal[name] = values[name]
    result = fmpy.simulate_fmu(fmu_dir, stop_time=stop_time, step_size=0.01,
                               output_interval=0.01, start_values=params or {},
                               input=signal)
    for name in result.dtype.names:
        assert np.all(np.isfinite(result[name])), f"output {name} is not finite"
    return result


def test_the_expectations_use_the_models_defaults():
    """The constants above are the defaults of fmus/Vehicle8DOF/variables.def."""
    table = {row["name"]: row["start"] for row in parse_variables_def(VARIABLES_DEF)}
    constants = {"m": M, "Iz": IZ, "Cf": C_F, "Cr": C_R, "lf": L_F, "lr": L_R, "iy": I_Y,
                 "Rw": R_W, "m_unsprung": M_UNSPRUNG, "h_cg": H_CG, "h_rc": H_RC, "k_roll": K_ROLL,
                 "f_rr": F_RR, "pCx": PAC_X[0], "pEx": PAC_X[1], "Ck": PAC_X[2], "tyre_model": 1.0}
    assert {name: table[name] for name in constants} == constants


def understeer_gradient(mu=1.0, m=M):
    """K of the paper's linear model (per-tyre Cf, Cr: axle stiffness 2 mu C), s^2/m."""
    return m * (L_R * C_R - L_F * C_F) / (2.0 * mu * C_F * C_R * WHEELBASE)


@pytest.mark.parametrize("tyre, vx0, delta, mu", [
    (1.0, 10.0, 0.01, 1.0), (1.0, 20.0, 0.004, 1.0), (1.0, 15.0, 0.024, 1.0), (1.0, 15.0, 0.005, 0.6),
    (0.0, 10.0, 0.01, 1.0), (0.0, 15.0, 0.005, 0.6)])
def test_steady_yaw_rate_equals_linear_bicycle_gain(fmu_dir, tyre, vx0, delta, mu):
    """In the linear range the yaw gain is the linear bicycle's with Table I's
    stiffness. Magic Formula (tyre 1): mu caps the peak only, so on mu = 0.6 the
    small-slip gain is still the mu = 1 gain (and > 5 % off the mu-scaled one);
    Dugoff (tyre 0, the design model's tyre): the gain with the stiffness mu C."""
    res = simulate(fmu_dir, 6.0, {"vx0": vx0, "tyre_model": tyre, **STEADY},
                   {"delta": delta, "mu": mu})
    end = res[-1]
    assert 0.1 < abs(end["ay"]) < 2.0, "test must stay in the linear range"
    vx = end["vx"]
    gain = {m: vx / (WHEELBASE + understeer_gradient(m) * vx**2) * delta for m in (mu, 1.0)}
    r_linear = gain[1.0] if tyre == 1.0 else gain[mu]
    # 0.5 %: the Magic Formula's curvature and load sensitivity under the small
    # load transfer cost < 0.2 % at these slips; Dugoff agrees to about 1e-4
    assert end["r"] == pytest.approx(r_linear, rel=0.005)
    if mu != 1.0:
        other = gain[mu] if tyre == 1.0 else gain[1.0]
        assert abs(end["r"] / other - 1.0) > 0.05, "the two tyre laws must differ here"
    # steady state reached: yaw rate no longer moving over the last second
    assert abs(res["r"][-1] - res["r"][-101]) < 0.01 * abs(r_linear)


def test_friction_limit_shows_at_saturation_not_in_the_linear_range(fmu_dir):
    """Magic Formula on mu = 0.5: the small steer of the test above gives the
    mu = 1 response, a steer 20 times larger saturates at 0.9-1.0 mu g (the
    friction limit) where mu = 1 still grips, so the two roads differ only there."""
    ay = {}
    for mu in (1.0, 0.5):
        for delta in (0.005, 0.1):
            res = simulate(fmu_dir, 4.0, {"vx0": 15.0, **STEADY}, {"delta": delta, "mu": mu})
            ay[mu, delta] = np.max(np.abs(res["ay"]))
    assert ay[0.5, 0.005] == pytest.approx(ay[1.0, 0.005], rel=0.01)
    assert 0.9 * 0.5 * G < ay[0.5, 0.1] <= 1.02 * 0.5 * G
    assert ay[1.0, 0.1] > 1.3 * 0.5 * G


@pytest.mark.parametrize("tyre, mu, bicycle_mu", [(1.0, 1.0, 1.0), (1.0, 0.5, 1.0),
                                                  (0.0, 1.0, 1.0), (0.0, 0.5, 0.5)])
def test_agrees_with_bicycle_model_in_linear_range(fmu_dir, bicycle_dir, tyre, mu, bicycle_mu):
    """Cross-check against the paper's linear model (the other built-in FMU),
    without rolling resistance (the Bicycle has none). The Bicycle scales its
    stiffness by mu; the Magic Formula tyre does not, so on mu = 0.5 the 8-DOF
    follows the Bicycle at mu = 1 (in the linear range mu only caps the peak),
    and the Bicycle at mu = 0.5 is > 10 % off; the Dugoff tyre follows the
    Bicycle at the same mu."""
    times = np.arange(0.0, 8.01, 0.5)
    inputs = {"delta": 0.02 * np.sin(0.8 * times), "torque": np.full(times.shape, 200.0),
              "wind_fy": 500.0 * np.cos(times), "mu": mu}
    ref = simulate(bicycle_dir, 8.0, {"vx0": 12.0}, {**inputs, "mu": bicycle_mu}, times)
    res = simulate(fmu_dir, 8.0, {"vx0": 12.0, "tyre_model": tyre, "f_rr": 0.0}, inputs, times)
    assert np.max(np.abs(res["ay"])) < 2.0
    # yaw and path within a few percent of their range (Magic Formula: relaxation
    # lag sigma_y / vx = 33 ms and load sensitivity, ~1.5-2 %); speed closer (the
    # front lateral force's drag component, absent from eq. 5, is the main difference)
    for name, tol in (("r", 0.04), ("psi", 0.04), ("y", 0.04), ("vx", 0.015)):
        scale = np.max(np.abs(ref[name]))
        assert np.max(np.abs(res[name] - ref[name])) < tol * scale, name
    if tyre == 1.0 and mu != 1.0:
        scaled = simulate(bicycle_dir, 8.0, {"vx0": 12.0}, inputs, times)
        assert np.max(np.abs(res["r"] - scaled["r"])) > 0.1 * np.max(np.abs(scaled["r"]))


def test_lateral_acceleration_limited_by_low_friction(fmu_dir):
    mu = 0.3
    res = simulate(fmu_dir, 5.0, {"vx0": 15.0}, {"delta": 0.3, "mu": mu})
    ay_max = np.max(np.abs(res["ay"]))
    assert ay_max <= 1.02 * mu * G
    assert ay_max >= 0.85 * mu * G, "a large steer should use most of the friction"


def test_wheel_lift_never_creates_extra_grip(fmu_dir):
    # high CG on a narrow track: the inner wheels lift long before mu g
    mu = 1.2
    params = {"vx0": 20.0, "h_cg": 1.2, "track_f": 1.2, "track_r": 1.2, "cx": 0.0}
    res = simulate(fmu_dir, 4.0, params, {"delta": 0.25, "mu": mu})
    total = np.hypot(res["ax"], res["ay"])
    assert np.max(total) <= 1.005 * mu * G
    assert np.max(np.abs(res["ay"])) > 0.5 * G


def roll_gradient_analytic(m=M):
    """phi / ay = ms e / (k_roll - ms g e) with the default suspension, rad per m/s2."""
    ms = m - M_UNSPRUNG
    e = (m * H_CG - (m - ms) * R_W) / ms - H_RC
    return ms * e / (K_ROLL - ms * G * e)


@pytest.mark.parametrize("delta", [0.015, -0.015])
def test_roll_sign_and_gradient(fmu_dir, delta):
    end = simulate(fmu_dir, 5.0, {"vx0": 15.0, "cx": 0.0}, {"delta": delta})[-1]
    assert math.copysign(1.0, end["phi"]) == math.copysign(1.0, delta)  # right side down in a left turn
    assert math.copysign(1.0, end["ay"]) == math.copysign(1.0, delta)
    gradient = end["phi"] / end["ay"]
    assert gradient == pytest.approx(roll_gradient_analytic(), rel=0.005)
    deg_per_g = math.degrees(gradient * G)
    assert 2.0 <= deg_per_g <= 8.0


def test_left_and_right_steer_are_exact_mirrors(fmu_dir):
    times = np.arange(0.0, 6.01, 0.5)
    steer = 0.06 * np.sin(times)
    torque = 400.0 * np.cos(times)
    left = simulate(fmu_dir, 6.0, {"vx0": 12.0}, {"delta": steer, "torque": torque}, times)
    right = simulate(fmu_dir, 6.0, {"vx0": 12.0}, {"delta": -steer, "torque": torque}, times)
    assert np.max(np.abs(left["y"])) > 1.0
    for name in ("x", "vx", "ax"):
        np.testing.assert_array_equal(left[name], right[name], err_msg=name)
    for name in ("y", "psi", "vy", "r", "ay", "phi"):
        np.testing.assert_array_equal(left[name], -right[name], err_msg=name)
    np.testing.assert_array_equal(left["omega_fl"], right["omega_fr"])
    np.testing.assert_array_equal(left["omega_rl"], right["omega_rr"])


def locked_wheel_friction(fz_nom, mu=1.0):
    """Magic Formula force / load of a locked wheel (kappa = -1, alpha = 0) with
    mu_load = 0: D = mu Fz (pDx = 1), B = Kx / (C D) = Ck / (C mu Fz_nom) since Kx
    is Ck Fz / Fz_nom, so the ratio does not depend on the actual load."""
    c, e, ck = PAC_X
    b = ck / (c * mu * fz_nom)
    return mu * math.sin(c * math.atan(b - e * (b - math.atan(b))))


@pytest.mark.parametrize("tyre", [1.0, 0.0])
def test_hard_braking_locks_wheels_and_stops(fmu_dir, tyre):
    """-8000 N.m locks every wheel. Magic Formula: the car slides at the
    locked-wheel friction of the tyre curve (fall-off after the peak), between
    the rear axle's 0.78 and the front's 0.81 (weighted by the loads under
    braking), so the distance lies between v0^2 / (2 g s_front) and
    v0^2 / (2 g s_rear) within 2 % (the lock-up transient through the peak and
    the regularised slip below v_eps shorten it slightly); mu_load = 0 for a
    closed-form friction. Dugoff has no fall-off: it slides at mu g (distance
    within 5 % of v0^2 / (2 g), never shorter)."""
    v0 = 15.0
    res = simulate(fmu_dir, 3.0, {"vx0": v0, "tyre_model": tyre, "mu_load": 0.0, "cx": 0.0},
                   {"torque": -8000.0})
    sliding = res["vx"] > 1.0
    slip_front = R_W * res["omega_fl"][sliding] / res["vx"][sliding] - 1.0
    assert np.min(slip_front) < -0.9, "front wheels should lock"
    assert res["vx"][-1] == 0.0 and np.all(res["vx"] >= 0.0), "stops, never reverses"
    assert np.all(np.diff(res["vx"]) <= 0.0), "no oscillation while stopping"
    distance = res["x"][-1]
    if tyre == 0.0:
        assert v0**2 / (2.0 * G) <= distance <= 1.05 * v0**2 / (2.0 * G)
        return
    fz_f, fz_r = 0.5 * M * G * L_R / WHEELBASE, 0.5 * M * G * L_F / WHEELBASE
    s_f, s_r = locked_wheel_friction(fz_f), locked_wheel_friction(fz_r)
    assert 0.75 < s_r < s_f < 0.85, "well below the peak friction 1"
    assert 0.98 * v0**2 / (2.0 * G * s_f) <= distance <= v0**2 / (2.0 * G * s_r)


def test_accelerating_from_standstill_follows_equivalent_wheel_law(fmu_dir):
    torque, cx = 1500.0, 0.42
    res = simulate(fmu_dir, 12.0, {"vx0": 0.0, "cx": cx}, {"torque": torque})
    assert np.max(res["vx"]) > 50.0 / 3.6
    assert np.all(np.diff(res["vx"]) > 0.0)
    # smooth: the acceleration changes by less than 0.01 m/s2 per 10 ms step
    assert np.max(np.abs(np.diff(res["ax"][1:]))) < 0.01
    # me vx_dot = tau / Rw - f_rr m g - cx vx^2 (eq. 5 with the default rolling
    # resistance): v = sqrt(F/cx) tanh(t sqrt(F cx) / me)
    force = torque / R_W - F_RR * M * G
    v_law = math.sqrt(force / cx) * np.tanh(res["time"] * math.sqrt(force * cx) / M_E)
    np.testing.assert_allclose(res["vx"][100:], v_law[100:], rtol=0.003)
    slip = R_W * res["omega_rl"][100:] / res["vx"][100:] - 1.0
    assert np.all((slip > 0.0) & (slip < 0.05)), "driven wheels slip a little, forward"


@pytest.mark.parametrize("f_rr", [0.0, 0.012])
def test_coast_down_follows_drag_law(fmu_dir, f_rr):
    v0, cx = 20.0, 0.42
    res = simulate(fmu_dir, 20.0, {"vx0": v0, "cx": cx, "f_rr": f_rr})
    t = res["time"]
    b = cx / M_E
    if f_rr == 0.0:
        v_law = v0 / (1.0 + b * v0 * t)
    else:  # me v' = -cx v^2 - f_rr m g  =>  v = sqrt(a/b) tan(atan(v0 sqrt(b/a)) - sqrt(ab) t)
        a = f_rr * M * G / M_E
        v_law = math.sqrt(a / b) * np.tan(math.atan(v0 * math.sqrt(b / a)) - math.sqrt(a * b) * t)
    np.testing.assert_allclose(res["vx"], v_law, rtol=1e-4)
    assert res["vx"][-1] < 0.95 * v0, "drag must have slowed the car"


def test_initial_accelerations_are_the_external_forces(fmu_dir):
    v0, cx, fx, fy = 12.0, 0.42, 300.0, 900.0
    res = simulate(fmu_dir, 0.5, {"vx0": v0, "cx": cx}, {"wind_fx": fx, "wind_fy": fy})
    assert res["ax"][0] == pytest.approx((fx - cx * v0**2) / M, rel=1e-12)
    assert res["ay"][0] == pytest.approx(fy / M, rel=1e-12)
    # wind 0.3 m ahead of the CG pushes the nose to the left first
    assert res["r"][5] > 0.0


def test_standstill_without_torque_stays_exactly_still(fmu_dir):
    res = simulate(fmu_dir, 2.0, {"vx0": 0.0}, {"delta": 0.3})
    for name in ("x", "y", "psi", "vx", "vy", "r", "ax", "ay", "phi", "omega_fl", "omega_rr"):
        assert np.all(res[name] == 0.0), name


def test_same_inputs_give_bit_identical_outputs(fmu_dir):
    runs = [simulate(fmu_dir, 3.0, {"vx0": 8.0}, {"delta": 0.1, "torque": 800.0})
            for _ in range(2)]
    assert runs[0].tobytes() == runs[1].tobytes()


def run_with_log(fmu_dir, params):
    """Simulate with `params` expecting failure; return the logged messages."""
    messages = []

    def logger(_env, _instance, _status, _category, message):
        messages.append(message.decode())

    with pytest.raises(FMICallException):
        fmpy.simulate_fmu(fmu_dir, stop_time=0.1, step_size=0.01,
                          start_values=params, logger=logger)
    return messages


@pytest.mark.parametrize("params, words", [
    ({"m": -1.0}, ["parameter m = -1", "valid range"]),
    ({"m_unsprung": 1600.0}, ["m_unsprung = 1600", "m = 1500"]),
    ({"k_roll": 1000.0}, ["k_roll = 1000"]),
    ({"h_cg": 0.12}, ["h_cg = 0.12", "roll centre"]),
])
def test_invalid_parameters_fail_with_a_logged_message(fmu_dir, params, words):
    text = "\n".join(run_with_log(fmu_dir, params))
    for word in words:
        assert word in text


def test_mass_uncertainty_scales_the_sprung_body(fmu_dir):
    """Scaling m by 0.7 (the paper's 30 % case) stays a valid vehicle: the body is m - m_unsprung.

    Steady cornering then follows the analytic roll gradient and yaw gain of the
    lighter car (the default car's roll gradient is 50 % larger, its yaw gain 6 % lower).
    """
    m = 0.7 * M
    res = simulate(fmu_dir, 6.0, {"m": m, "vx0": 15.0, "cx": 0.0}, {"delta": 0.015})
    end = res[-1]
    assert end["phi"] / end["ay"] == pytest.approx(roll_gradient_analytic(m), rel=0.005)
    r_linear = end["vx"] / (WHEELBASE + understeer_gradient(1.0, m) * end["vx"]**2) * 0.015
    assert end["r"] == pytest.approx(r_linear, rel=0.005)
    assert abs(end["ay"]) < 2.0, "test must stay in the linear range"
