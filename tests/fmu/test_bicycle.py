"""Physics of the Bicycle FMU against analytic results (EQUATIONS.md):
steady-state yaw gain of the linear bicycle (with the factor 2 of A1),
the steady state of the state-space form x_dot = A x + mu B delta + D Fwy,
constant-torque acceleration (eq. 5), aero coast-down, mirror symmetry,
world kinematics, and the low-speed handling (no NaN, no creep at standstill).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.fmu.build import FMUS_DIR
from tests.helpers.fmus import Plant, built_fmu, parse_variables_def

M, IZ, CF, CR, LF, LR, IY, RW = 1500.0, 2454.0, 57500.0, 57500.0, 1.006, 1.462, 1.2, 0.3
L = LF + LR
ME = M + IY / RW**2
H = 0.01


def test_the_expectations_use_the_models_defaults():
    """The constants above are the defaults of fmus/Bicycle/variables.def."""
    table = {row["name"]: row["start"] for row in parse_variables_def(FMUS_DIR / "Bicycle" / "variables.def")}
    constants = {"m": M, "Iz": IZ, "Cf": CF, "Cr": CR, "lf": LF, "lr": LR, "iy": IY, "Rw": RW}
    assert {name: table[name] for name in constants} == constants


@pytest.fixture
def plant(fmu_dir):
    p = Plant(*built_fmu(fmu_dir, "Bicycle", 2))
    yield p
    p.free()


def understeer_gradient(mu: float) -> float:
    """K of r/delta = vx / (L + K vx^2), tyre stiffness 2 mu C per axle."""
    return M * (LR * CR - LF * CF) / (2.0 * mu * CF * CR * L)


def lateral_matrices(vx: float, mu: float):
    """A = mu A1 + A2, B, D exactly as written in EQUATIONS.md."""
    a1 = np.array([[-2 * (CF + CR) / (M * vx), 2 * (CR * LR - CF * LF) / (M * vx)],
                   [2 * (CR * LR - CF * LF) / (IZ * vx), -2 * (CF * LF**2 + CR * LR**2) / (IZ * vx)]])
    a2 = np.array([[0.0, -vx], [0.0, 0.0]])
    b = np.array([2 * CF / M, 2 * CF * LF / IZ])
    return mu * a1 + a2, b


@pytest.mark.parametrize("vx0,mu", [(10.0, 1.0), (20.0, 1.0), (15.0, 0.5)])
def test_steady_state_yaw_rate_matches_linear_bicycle_gain(plant, vx0, mu):
    delta = 0.005
    plant.init({"vx0": vx0, "cx": 0.0})
    out = plant.run({"delta": delta, "mu": mu}, 800)
    vx, r, vy, ay = (plant.column(out, n)[-1] for n in ("vx", "r", "vy", "ay"))
    k = understeer_gradient(mu)
    assert r == pytest.approx(vx * delta / (L + k * vx**2), rel=1e-5)
    assert vy == pytest.approx(r * (LR - M * vx**2 * LF / (2 * mu * CR * L)), rel=1e-4)
    assert ay == pytest.approx(vx * r, rel=1e-5)
    assert r > 0  # positive steer turns left (ISO 8855)


def test_steady_state_with_side_wind_matches_state_space_form(plant):
    delta, fwy, mu, lw = 0.01, 800.0, 0.7, 0.3
    plant.init({"vx0": 12.0, "cx": 0.0, "lw": lw})
    out = plant.run({"delta": delta, "wind_fy": fwy, "mu": mu}, 800)
    vx = plant.column(out, "vx")[-1]
    a, b = lateral_matrices(vx, mu)
    d = np.array([1.0 / M, lw / IZ])
    expected = -np.linalg.solve(a, mu * b * delta + d * fwy)
    got = [plant.column(out, "vy")[-1], plant.column(out, "r")[-1]]
    np.testing.assert_allclose(got, expected, rtol=1e-4)


def test_constant_torque_follows_equivalent_wheel_law(plant):
    vx0, tau = 5.0, 500.0
    plant.init({"vx0": vx0, "cx": 0.0, "x0": 3.0})
    out = plant.run({"torque": tau}, 500)
    t = np.arange(501) * H
    acc = tau / (RW * ME)
    np.testing.assert_allclose(plant.column(out, "vx"), vx0 + acc * t, rtol=1e-12)
    np.testing.assert_allclose(plant.column(out, "x"), 3.0 + vx0 * t + 0.5 * acc * t**2, rtol=1e-11)
    np.testing.assert_allclose(plant.column(out, "ax")[1:], acc, rtol=1e-12)
    np.testing.assert_allclose(plant.column(out, "omega_rl"), plant.column(out, "vx") / RW)
    assert not plant.column(out, "y").any() and not plant.column(out, "phi").any()


def test_coast_down_follows_aero_drag_law(plant):
    vx0, cx = 30.0, 0.42
    plant.init({"vx0": vx0, "cx": cx})
    out = plant.run({}, 2000)
    t = np.arange(2001) * H
    np.testing.assert_allclose(plant.column(out, "vx"), vx0 / (1 + cx * vx0 * t / ME), rtol=1e-10)
    np.testing.assert_allclose(plant.column(out, "x"), ME / cx * np.log1p(cx * vx0 * t / ME),
                               rtol=1e-10)


def test_longitudinal_wind_force_adds_to_drive(plant):
    plant.init({"vx0": 10.0, "cx": 0.0})
    out = plant.run({"torque": 150.0, "wind_fx": -500.0}, 100)
    assert plant.column(out, "vx")[-1] == pytest.approx(10.0 + (150.0 / RW - 500.0) / ME, rel=1e-12)


def _maneuver(sign: float):
    def inputs(k: int) -> dict[str, float]:
        return {"delta": sign * 0.04 * math.sin(0.02 * k), "torque": 200.0 * math.cos(0.01 * k),
                "wind_fy": sign * (300.0 if k > 100 else 0.0)}
    return inputs


def test_left_and_right_steer_give_mirrored_trajectories(fmu_dir):
    runs = []
    for sign in (1.0, -1.0):
        p = Plant(*built_fmu(fmu_dir, "Bicycle", 2))
        p.init({"vx0": 12.0})
        runs.append(p.run(_maneuver(sign), 400))
        names = p.outputs
        p.free()
    left, right = runs
    assert np.abs(left[:, names.index("y")]).max() > 1.0
    for i, name in enumerate(names):
        flip = -1.0 if name in ("y", "psi", "vy", "r", "ay") else 1.0
        assert np.array_equal(left[:, i], flip * right[:, i]), name


def test_world_kinematics_follow_heading(plant):
    psi0 = 0.7
    plant.init({"vx0": 8.0, "cx": 0.0, "psi0": psi0, "x0": 100.0, "y0": -50.0})
    out = plant.run({}, 300)
    s = 8.0 * np.arange(301) * H
    np.testing.assert_allclose(plant.column(out, "x"), 100.0 + math.cos(psi0) * s, rtol=1e-12)
    np.testing.assert_allclose(plant.column(out, "y"), -50.0 + math.sin(psi0) * s, rtol=1e-12)
    assert np.all(plant.column(out, "psi") == psi0)


def test_steered_car_at_standstill_does_not_move(plant):
    plant.init({"vx0": 0.0})
    out = plant.run({"delta": 0.3, "wind_fy": 0.0}, 200)
    assert not out.any()


def test_low_speed_start_and_reverse_stay_finite(plant):
    plant.init({"vx0": 0.0})
    out = plant.run(lambda k: {"delta": 0.3, "torque": 400.0 if k < 300 else -600.0}, 600)
    assert np.isfinite(out).all()
    vx = plant.column(out, "vx")
    assert vx[300] > 0.5 and vx[-1] < vx[300]
    r = plant.column(out, "r")
    assert r[300] > 0 and np.abs(r).max() < 2.0  # turns left, no blow-up
