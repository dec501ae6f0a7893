"""The backstepping step's per-tick arithmetic as plain functions of floats: one source, two paths.

`lateral_command` is lateral_law (eq. 9-13, the numpy form kept as the
readable reference in controllers.backstepping.lateral) written out for the
2x2 matrices and 2-vectors; `step` is the rest of the controller's tick
after the window projection: the friction estimate's Euler step and
projection, the path errors (controllers.tracking.errors_at_feet), eq. 7 with
the torque clip, the nominal vx_dot, the lateral law and the steering angle
and rate limits. BacksteppingController's docstring says what each part does.

Both run interpreted, or compiled by numba from this same source
(controllers.backstepping.step_jit, COSIM_JIT): plain float arithmetic, the
constants in one indexed sequence (a tuple interpreted, a float64 array
compiled; the index names below are module-level numbers, which numba takes
as constants), flags as 0.0 / 1.0. Kept out of here because the compiled
path would change their bits or cannot hold them: the robust adaptation
rate (math.hypot: CPython's algorithm is not libm's), V3 (`** 2` is libm's
pow interpreted and a product compiled) and the error messages (a singular
model raises SingularSteer with the speed; the component words it).
"""

from __future__ import annotations

from controllers.tracking import errors_at_feet

# the lateral law's constants (ScalarLateralLaw.constants)
C00, C01, C10, C11 = 0, 1, 2, 3      # A1(vx) = c / vx, entry by entry
B0, B1, BB = 4, 5, 6                 # B and B^T B
G00, G01, G11 = 7, 8, 9              # kz I + gz D D^T
LS, K1, K2, V_MIN = 10, 11, 12, 13
FEEDFORWARD, AT_CG, ROBUST = 14, 15, 16
LATERAL_SIZE = 17
# then the step's (BacksteppingController.constants)
M, ME, RW, KXGX = 17, 18, 19, 20
MAX_TORQUE, MIN_TORQUE, MAX_DELTA, MAX_DELTA_RATE = 21, 22, 23, 24
MU_MIN, MU_MAX, G_MU = 25, 26, 27
STEP_SIZE = 28


class SingularSteer(ArithmeticError):
    """No steady-state steer at this speed: the feedforward law's model matrix is singular (args: vx)."""


def unit(mc00: float, mc01: float, mc10: float, mc11: float, b1: float, b2: float, ls: float,
         v: float) -> tuple[float, float, float]:
    """steady_state_per_curvature's [psiL, vy, r] per unit curvature at speed v; mc = mu c, b = mu B."""
    a00, a01 = mc00 / v, mc01 / v - v           # mu * c00 / v, mu * c01 / v - v
    a10, a11 = mc10 / v, mc11 / v
    det = a00 * b2 - a10 * b1
    if abs(det) < 1e-12 * max(abs(a00 * b2), abs(a10 * b1)):
        raise SingularSteer(v)
    rhs1, rhs2 = -a01 * v, -a11 * v
    vy = (rhs1 * b2 - rhs2 * b1) / det
    return -(vy + ls * v) / v, vy, v


def reference(c, vx: float, vx_dot: float, rho: float, rho_dot: float, mu_hat: float, rho_cg: float,
              rho_cg_dot: float, turn: float, bend: float) -> tuple[float, ...]:
    """path_reference as (yr, psir, yr_dot, psir_dot, vyr, rr, vyr_dot, rr_dot); vx already floored."""
    ls = c[LS]
    if c[FEEDFORWARD] == 0.0:
        kin, kin_dot = vx * rho, vx_dot * rho + vx * rho_dot
        return 0.0, 0.0, 0.0, 0.0, -ls * kin, kin, -ls * kin_dot, kin_dot
    step = 1e-4 * vx
    # the three points share the products of mu (mu * c / v is (mu * c) / v: the same values)
    mc00, mc01, mc10, mc11 = mu_hat * c[C00], mu_hat * c[C01], mu_hat * c[C10], mu_hat * c[C11]
    b1, b2 = mu_hat * c[B0], mu_hat * c[B1]
    u0, u1, u2 = unit(mc00, mc01, mc10, mc11, b1, b2, ls, vx)
    p0, p1, p2 = unit(mc00, mc01, mc10, mc11, b1, b2, ls, vx + step)
    n0, n1, n2 = unit(mc00, mc01, mc10, mc11, b1, b2, ls, vx - step)
    two = 2.0 * step
    if c[AT_CG] != 0.0:      # _cg_reference, written out
        f = rho_cg * vx_dot
        vy_r, r_r = u1 * rho_cg, u2 * rho_cg
        vy_r_dot = u1 * rho_cg_dot + (p1 - n1) / two * f
        r_r_dot = u2 * rho_cg_dot + (p2 - n2) / two * f
        beta = vy_r / vx
        beta_dot = (vy_r_dot - beta * vx_dot) / vx
        psi_r, psi_r_dot = -beta - turn, -beta_dot - vx * (rho - rho_cg)
        y_r, y_r_dot = -ls * beta - bend, -ls * beta_dot - vx * (turn - ls * rho_cg)
        return y_r, psi_r, y_r_dot, psi_r_dot, vy_r, r_r, vy_r_dot, r_r_dot
    f = rho * vx_dot
    dot0 = u0 * rho_dot + (p0 - n0) / two * f
    dot1 = u1 * rho_dot + (p1 - n1) / two * f
    dot2 = u2 * rho_dot + (p2 - n2) / two * f
    return 0.0, u0 * rho, 0.0, dot0, u1 * rho, u2 * rho, dot1, dot2


def lateral_command(c, y_l: float, psi_l: float, vy: float, r: float, vx: float, vx_dot: float,
                    rho: float, rho_dot: float, mu_hat: float, g_mu: float, rho_cg: float,
                    rho_cg_dot: float, turn: float, bend: float) -> tuple[float, ...]:
    """lateral_law as (delta, alpha_vy, alpha_r, z_vy, z_r, mu_hat_dot, V2, v0, v1, a1x0, a1x1).

    mu_hat_dot is the paper's adaptation rate, 0.0 when c[ROBUST] (the caller
    computes the robust one from v and A1 x). vx is the measured speed, floored here.
    """
    vx = max(vx, c[V_MIN])
    ls, k1, k2 = c[LS], c[K1], c[K2]
    y_r, psi_r, y_r_dot, psi_r_dot, vy_r, r_r, vy_r_dot, r_r_dot = reference(
        c, vx, vx_dot, rho, rho_dot, mu_hat, rho_cg, rho_cg_dot, turn, bend)
    e0, e1 = y_l - y_r, psi_l - psi_r
    ed0, ed1 = vx * psi_l + vy + ls * r - y_r_dot, r - vx * rho - psi_r_dot
    u0, u1 = -k1 * e0 - vx * e1, -k2 * e1                  # g^-1 = [[1, -ls], [0, 1]]
    alpha0, alpha1 = vy_r + (u0 - ls * u1), r_r + u1
    u0, u1 = -k1 * ed0 - (vx_dot * e1 + vx * ed1), -k2 * ed1
    alpha_dot0, alpha_dot1 = vy_r_dot + (u0 - ls * u1), r_r_dot + u1
    z0, z1 = vy - alpha0, r - alpha1
    a00, a01, a10, a11 = c[C00] / vx, c[C01] / vx, c[C10] / vx, c[C11] / vx
    a1x0, a1x1 = a00 * vy + a01 * r, a10 * vy + a11 * r
    # v = -G z - (mu A1 + A2) x + alpha_dot - g^T e,  A2 x = [-vx r, 0],  g^T = [[1, 0], [ls, 1]]
    v0 = (-(c[G00] * z0 + c[G01] * z1) - (mu_hat * a1x0 - vx * r) + alpha_dot0 - e0)
    v1 = (-(c[G01] * z0 + c[G11] * z1) - mu_hat * a1x1 + alpha_dot1 - (ls * e0 + e1))
    delta = (c[B0] * v0 + c[B1] * v1) / (mu_hat * c[BB])
    mu_hat_dot = 0.0
    if c[ROBUST] == 0.0:
        mu_hat_dot = (g_mu / mu_hat) * (z0 * (v0 + mu_hat * a1x0) + z1 * (v1 + mu_hat * a1x1))
    v1_lyap = 0.5 * (e0 * e0 + e1 * e1)
    return (delta, alpha0, alpha1, z0, z1, mu_hat_dot, v1_lyap + 0.5 * (z0 * z0 + z1 * z1),
            v0, v1, a1x0, a1x1)


def step(c, dt: float, mu_hat: float, mu_hat_dot: float, last_delta: float, psi: float, vx: float,
         vy: float, r: float, at_cg: tuple, preview: tuple) -> tuple[float, ...]:
    """The tick after the projection (module docstring), from the feet of the CG and the preview point.

    Args:
        c: the step's constants (STEP_SIZE of them); dt: the step's length;
        mu_hat, mu_hat_dot: the estimate and its rate after the previous step;
        last_delta: the steering angle applied at the previous step;
        psi, vx, vy, r: measured yaw angle, body velocities and yaw rate;
        at_cg, preview: projection.foot()'s tuples of the CG and the preview point.
    Returns:
        the outputs delta, torque, yL, psiL, yc, yc_cg, ex, vx_ref, rho, mu_hat, alpha_vy,
        alpha_r, z_vy, z_r, V, V2 (V3 is the caller's), then the steer command before the
        limits, mu_hat_dot (paper law; 0.0 robust) and whether it is kept (1.0: the steer
        was not limited and vx >= v_min), then v0, v1, a1x0, a1x1 for the robust rate.
    """
    mu_hat = min(c[MU_MAX], max(c[MU_MIN], mu_hat + dt * mu_hat_dot))
    (y_l, psi_l, y_c, y_cg, rho, rho_dot, vx_ref, vx_ref_dot, rho_cg, rho_cg_dot, turn,
     bend) = errors_at_feet(at_cg, preview, psi, vx, c[LS])
    # eq. 7 (longitudinal_law), then the nominal model's vx_dot with the applied torque
    m, me, rw = c[M], c[ME], c[RW]
    ex = vx - vx_ref
    torque = min(c[MAX_TORQUE], max(c[MIN_TORQUE], rw * (-c[KXGX] * ex - m * vy * r + me * vx_ref_dot)))
    vx_dot = (torque / rw + m * vy * r) / me
    command, alpha_vy, alpha_r, z_vy, z_r, rate, v2, v0, v1, a1x0, a1x1 = lateral_command(
        c, y_l, psi_l, vy, r, vx, vx_dot, rho, rho_dot, mu_hat, c[G_MU], rho_cg, rho_cg_dot, turn, bend)
    # SteeringLimiter.apply: the rate limit, then the angle limit
    reach = c[MAX_DELTA_RATE] * dt
    delta = min(last_delta + reach, max(last_delta - reach, command))
    delta = min(c[MAX_DELTA], max(-c[MAX_DELTA], delta))
    keep = 0.0 if abs(delta - command) > 1e-12 or vx < c[V_MIN] else 1.0
    return (delta, torque, y_l, psi_l, y_c, y_cg, ex, vx_ref, rho, mu_hat, alpha_vy, alpha_r, z_vy, z_r,
            0.5 * me * ex * ex, v2, command, rate, keep, v0, v1, a1x0, a1x1)
