"""Steady error on constant curvature: the faithful law (non-zero) versus the feedforward variant (zero).

The faithful law's equilibrium is computed independently of the controller
code: the closed loop of EQUATIONS.md (error model, linear bicycle, eq. 9 and
eq. 12 with the least-squares steer) is affine in u = [yL, psiL, vy, r, delta]
at constant vx and rho, so its equilibrium solves one 5x5 linear system,
written here from the equations.

Measured (rho = 0.01 1/m, vx = 10 m/s, mu = 1, Table I):
- ke = (2, 2), kz = 10, gz = 0: yL = -0.2145 m, psiL = -0.0593 rad, close to
  the yL ~ -0.21 m, psiL ~ -0.058 rad quoted in EQUATIONS.md;
- default gains (ke = 1, kz = 5, gz = 1e5): yL = -0.139 m, psiL = -0.0593 rad,
  CG offset +0.031 m (world frame).
The feedforward variant: yL = 0 (ff_target "preview") or CG offset 0
(ff_target "cg"); psiL = -0.0593 rad in all cases (kinematics: yL_dot = 0).
"""

from __future__ import annotations

import numpy as np
import pytest

from controllers.backstepping.component import BacksteppingController
from controllers.backstepping.lateral import LateralGains
from controllers.linear_plant import LinearPlant
from controllers.vehicle_params import VehicleParams
from tests.helpers.closed_loop import CirclePath, run_closed_loop, run_error_model

PARAMS = VehicleParams()
RHO, VX, LS = 0.01, 10.0, 5.0


def faithful_equilibrium(ke, kz, gz, vx=VX, rho=RHO, mu=1.0, p=PARAMS) -> np.ndarray:
    """Equilibrium [yL, psiL, vy, r, delta] of the faithful closed loop, from the equations."""
    a = mu * p.a1(vx) + p.a2(vx)
    b = np.array([2 * p.Cf / p.m, 2 * p.Cf * p.lf / p.Iz])
    d = np.array([1 / p.m, p.lw / p.Iz])
    g = np.array([[1.0, LS], [0.0, 1.0]])
    h = np.array([0.0, -vx])

    def residual(u):
        e, x, delta = u[:2], u[2:4], u[4]
        f = np.array([vx * e[1], 0.0])
        alpha = np.linalg.solve(g, -np.diag(ke) @ e - f - h * rho)
        z = x - alpha
        v = -(kz * np.eye(2) + gz * np.outer(d, d)) @ z - a @ x - g.T @ e   # alpha_dot = 0
        return np.concatenate([f + g @ x + h * rho, a @ x + mu * b * delta,
                               [delta - b @ v / (mu * b @ b)]])

    offset = residual(np.zeros(5))
    matrix = np.column_stack([residual(col) - offset for col in np.eye(5)])
    return np.linalg.solve(matrix, -offset)


def test_faithful_steady_error_matches_independent_equilibrium():
    gains = LateralGains(ke=(2.0, 2.0), kz=10.0, gz=0.0, ls=LS, law="faithful")
    final = run_error_model(gains, VX, RHO, duration=25.0)["state"][-1]
    expected = faithful_equilibrium((2.0, 2.0), 10.0, 0.0)
    assert final == pytest.approx(expected[:4], abs=1e-7)
    assert final[0] == pytest.approx(-0.21, abs=0.01)       # EQUATIONS.md's quoted figure
    assert final[1] == pytest.approx(-0.058, abs=0.002)
    assert abs(final[0]) > 0.2                                # the faithful law does not remove it


@pytest.mark.parametrize("vx", [5.0, 10.0, 14.0])
def test_feedforward_preview_target_removes_the_steady_yl(vx):
    faithful = LateralGains(ke=(1.0, 1.0), kz=5.0, gz=1e5, ls=LS, law="faithful")
    variant = LateralGains(ke=(1.0, 1.0), kz=5.0, gz=1e5, ls=LS, law="feedforward", ff_target="preview")
    end_faithful = run_error_model(faithful, vx, RHO, duration=20.0)["state"][-1]
    end_variant = run_error_model(variant, vx, RHO, duration=20.0)["state"][-1]
    expected = faithful_equilibrium((1.0, 1.0), 5.0, 1e5, vx=vx)
    assert end_faithful == pytest.approx(expected[:4], abs=1e-7)
    assert abs(end_faithful[0]) > 0.1
    assert abs(end_variant[0]) < 1e-6
    # psiL is fixed by kinematics (yL_dot = 0), the same for both laws
    assert end_variant[1] == pytest.approx(end_faithful[1], abs=1e-7)


def run_circle(lateral_law, ff_target="cg", radius=1.0 / RHO, duration=20.0):
    controller = BacksteppingController(lateral_law=lateral_law, ff_target=ff_target)
    plant = LinearPlant(PARAMS, vx0=VX, r0=VX / radius, substeps=2)
    return run_closed_loop(controller, plant, CirclePath(radius), duration, v_ref=VX)


def test_world_frame_circle_faithful_vs_feedforward_cg():
    faithful = run_circle("faithful")
    variant = run_circle("feedforward", "cg")
    expected = faithful_equilibrium((1.0, 1.0), 5.0, 1e5)
    # the controller's projected yL follows the error model to second order in the geometry
    assert faithful["yL"][-1] == pytest.approx(expected[0], abs=3e-3)
    assert faithful["psiL"][-1] == pytest.approx(expected[1], abs=5e-4)
    cg_offset = CirclePath(1.0 / RHO).offset_of(faithful["plant_x"][-1], faithful["plant_y"][-1])
    assert faithful["yc_cg"][-1] == pytest.approx(cg_offset, abs=1e-9)
    assert abs(faithful["yc_cg"][-1]) > 0.02
    # the paper's yc is yL - ls psiL exactly
    assert faithful["yc"][-1] == faithful["yL"][-1] - 5.0 * faithful["psiL"][-1]
    # the variant puts the CG on the path; the remainder is third order in ls rho
    assert abs(variant["yc_cg"][-1]) < 2e-3
    assert np.all(np.abs(variant["yc_cg"][-300:]) < 2e-3)


def test_adaptation_drifts_at_the_faithful_equilibrium_but_not_the_feedforward_one():
    # With mu_hat = mu exactly, the faithful law's steady state still has z^T q != 0 (the
    # least-squares residual), so the paper's adaptation law moves mu_hat away from the truth;
    # at the feedforward equilibrium z = 0 and the estimate stays put.
    from controllers.backstepping.lateral import LateralMeasurement, lateral_law
    for law, drifts in (("faithful", True), ("feedforward", False)):
        gains = LateralGains(ke=(1.0, 1.0), kz=5.0, gz=1e5, ls=LS, law=law)
        y_l, psi_l, vy, r = run_error_model(gains, VX, RHO, duration=20.0)["state"][-1]
        meas = LateralMeasurement(y_l, psi_l, vy, r, vx=VX, vx_dot=0.0, rho=RHO, rho_dot=0.0)
        mu_hat_dot = lateral_law(meas, 1.0, PARAMS, gains, g_mu=0.5).mu_hat_dot
        if drifts:
            assert mu_hat_dot < -1e-3        # measured -0.0038 /s; it grows as mu_hat leaves mu
        else:
            assert abs(mu_hat_dot) < 1e-8
