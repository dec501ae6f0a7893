"""Nominal vehicle parameters (Table I of the paper) and the model matrices built from them.

The controllers hold their own nominal copy of these parameters, separate from
the plant's, so that scenarios with model uncertainty (30 % error on mass,
inertia, tyre stiffness) mean something. The matrices follow EQUATIONS.md:

    x_dot = (mu A1 + A2) x + mu B delta + D Fwy,   x = [vy, r]
    me vx_dot = tau_w / Rw + m vy r + Fwx,         me = m + iy / Rw^2

lw (side-wind lever arm) has no value in the paper: the default 0.3 m is the
one fmus/Bicycle/variables.def chose (keep both in step).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from cosim.component import ComponentError


@dataclass(frozen=True)
class VehicleParams:
    """Bicycle + equivalent-wheel parameters, SI units.

    Args:
        m: vehicle mass [kg].
        Iz: yaw inertia [kg m^2].
        Cf, Cr: cornering stiffness per tyre, front and rear [N/rad].
        lf, lr: distance from the CG to the front / rear axle [m].
        iy: equivalent wheel spin inertia [kg m^2].
        Rw: wheel radius [m].
        lw: lever arm of the side-wind force ahead of the CG [m] (may be 0 or negative).
    """

    m: float = 1500.0
    Iz: float = 2454.0
    Cf: float = 57500.0
    Cr: float = 57500.0
    lf: float = 1.006
    lr: float = 1.462
    iy: float = 1.2
    Rw: float = 0.3
    lw: float = 0.3

    def __post_init__(self) -> None:
        for field in fields(self):
            value = getattr(self, field.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ComponentError(f"vehicle parameter {field.name!r} must be a finite number, got {value!r}")
            if field.name != "lw" and value <= 0.0:
                raise ComponentError(f"vehicle parameter {field.name!r} must be > 0, got {value!r}")

    @property
    def me(self) -> float:
        """Equivalent longitudinal mass m + iy / Rw^2 [kg]."""
        return self.m + self.iy / self.Rw**2

    @property
    def wheelbase(self) -> float:
        """lf + lr [m]."""
        return self.lf + self.lr

    def a1(self, vx: float) -> np.ndarray:
        """The friction-scaled part A1 of the lateral state matrix at speed vx (> 0)."""
        m, iz, cf, cr, lf, lr = self.m, self.Iz, self.Cf, self.Cr, self.lf, self.lr
        return np.array([
            [-2.0 * (cf + cr) / (m * vx), 2.0 * (cr * lr - cf * lf) / (m * vx)],
            [2.0 * (cr * lr - cf * lf) / (iz * vx), -2.0 * (cf * lf**2 + cr * lr**2) / (iz * vx)],
        ])

    @staticmethod
    def a2(vx: float) -> np.ndarray:
        """The friction-free part A2 of the lateral state matrix at speed vx."""
        return np.array([[0.0, -vx], [0.0, 0.0]])

    def a(self, vx: float, mu: float) -> np.ndarray:
        """Lateral state matrix A = mu A1 + A2."""
        return mu * self.a1(vx) + self.a2(vx)

    def b(self) -> np.ndarray:
        """Steering input vector B (to be scaled by mu)."""
        return np.array([2.0 * self.Cf / self.m, 2.0 * self.Cf * self.lf / self.Iz])

    def d(self) -> np.ndarray:
        """Side-wind input vector D."""
        return np.array([1.0 / self.m, self.lw / self.Iz])
