"""Straightforward reference implementations of the controllers' per-tick path, for cross-checks.

The production code (window_projection, control_common, backstepping) is
written for speed: an exact nearest-chord search that skips chords, a window
prepared once per change, the lateral law in scalar arithmetic. This module
redoes the same computations the plain way: every chord measured with numpy,
the window rebuilt and checked at every step, the numpy lateral_law and the
longitudinal_law functions, a dataclass-free but literal transcription of the
controller's step. Tests run both and compare.
"""

from __future__ import annotations

import math

import numpy as np

from controllers.backstepping.lateral import LateralMeasurement, lateral_law, project_mu
from controllers.backstepping.longitudinal import longitudinal_law, nominal_vx_dot
from controllers.trajectory import TrajectoryWindow
from controllers.road.projection import _hermite, is_empty, validate_window, wrap_angle


def nearest_chord_brute(window: TrajectoryWindow, px: float, py: float) -> tuple[int, float]:
    """Nearest chord by measuring all of them (numpy argmin: the first one on ties)."""
    x0, y0 = window.x[:-1], window.y[:-1]
    dx, dy = np.diff(window.x), np.diff(window.y)
    length2 = np.maximum(dx * dx + dy * dy, 1e-300)
    t = np.clip(((px - x0) * dx + (py - y0) * dy) / length2, 0.0, 1.0)
    dist2 = (x0 + t * dx - px) ** 2 + (y0 + t * dy - py) ** 2
    i = int(np.argmin(dist2))
    return i, float(t[i])


def project_reference(window: TrajectoryWindow, px: float, py: float) -> dict[str, float]:
    """Projection fields (as project() documents them) by brute force and plain Newton on the Hermite curve."""
    i, t = nearest_chord_brute(window, px, py)
    last = len(window.s) - 2
    for end, at_end in ((0, i == 0 and t == 0.0), (-1, i == last and t == 1.0)):
        if not at_end:
            continue
        heading = float(window.psi[end])
        tx, ty = math.cos(heading), math.sin(heading)
        along = (px - window.x[end]) * tx + (py - window.y[end]) * ty
        if (end == 0 and along < 0.0) or (end == -1 and along > 0.0):
            return {"offset": -(px - window.x[end]) * ty + (py - window.y[end]) * tx, "psi_path": heading,
                    "kappa": float(window.kappa[end]), "dkappa_ds": 0.0, "v": float(window.v[end]),
                    "a": float(window.a[end]), "x": float(window.x[end] + along * tx),
                    "y": float(window.y[end] + along * ty)}
    step = window.s[i + 1] - window.s[i]
    seg = (window.x[i], window.y[i], step * math.cos(window.psi[i]), step * math.sin(window.psi[i]),
           window.x[i + 1], window.y[i + 1], step * math.cos(window.psi[i + 1]),
           step * math.sin(window.psi[i + 1]))
    for _ in range(4):
        (x, y), (dx, dy), (ddx, ddy) = _hermite(seg, t)
        slope = dx * dx + dy * dy + (x - px) * ddx + (y - py) * ddy
        if slope <= 0.0:
            break
        new_t = min(1.0, max(0.0, t - ((x - px) * dx + (y - py) * dy) / slope))
        done, t = abs(new_t - t) < 1e-13, new_t
        if done:
            break
    (x, y), (dx, dy) = _hermite(seg, t, order=1)

    def lerp(values: np.ndarray) -> float:
        return float(values[i] + t * (values[i + 1] - values[i]))

    return {"offset": (dx * (py - y) - dy * (px - x)) / max(math.hypot(dx, dy), 1e-300),
            "psi_path": lerp(window.psi), "kappa": lerp(window.kappa),
            "dkappa_ds": float((window.kappa[i + 1] - window.kappa[i]) / step),
            "v": lerp(window.v), "a": lerp(window.a), "x": float(x), "y": float(y)}


class ReferenceBackstepping:
    """The BacksteppingController's step written plainly (reads the controller's own settings).

    Args:
        twin: a BacksteppingController whose parameters (not state) this reference uses.
    """

    def __init__(self, twin) -> None:
        self.c = twin
        self.mu_hat = twin.mu_hat
        self.mu_hat_dot = 0.0
        self.delta = 0.0
        self.last_t = None

    def step(self, t: float, inputs) -> dict[str, float]:
        """One step; returns every output of the controller."""
        c, gains, params = self.c, self.c.gains, self.c.params
        dt = c.clock.period if self.last_t is None else t - self.last_t
        self.last_t = t
        x, y, psi, vx, vy, r = (float(inputs[n]) for n in ("x", "y", "psi", "vx", "vy", "r"))
        window = TrajectoryWindow.from_signals(inputs, "ref")
        assert not is_empty(window)
        validate_window(window)
        self.mu_hat = project_mu(self.mu_hat + dt * self.mu_hat_dot, c.mu_min, c.mu_max)
        preview = project_reference(window, x + gains.ls * math.cos(psi), y + gains.ls * math.sin(psi))
        at_cg = project_reference(window, x, y)
        psi_l = wrap_angle(psi - preview["psi_path"])
        lon = longitudinal_law(vx, at_cg["v"], at_cg["a"], vy, r, params, c.kx, c.gx)
        torque = min(c.limits.max_torque, max(c.limits.min_torque, lon.torque))
        meas = LateralMeasurement(y_l=preview["offset"], psi_l=psi_l, vy=vy, r=r, vx=vx,
                                  vx_dot=nominal_vx_dot(torque, vy, r, params), rho=preview["kappa"],
                                  rho_dot=preview["dkappa_ds"] * vx, rho_cg=at_cg["kappa"],
                                  rho_cg_dot=at_cg["dkappa_ds"] * vx,
                                  turn=wrap_angle(preview["psi_path"] - at_cg["psi_path"]),
                                  bend=math.cos(at_cg["psi_path"]) * (preview["y"] - at_cg["y"])
                                  - math.sin(at_cg["psi_path"]) * (preview["x"] - at_cg["x"]))
        lat = lateral_law(meas, self.mu_hat, params, gains, c.g_mu, c.adaptation)
        rate = c.limits.max_delta_rate * dt
        delta = min(self.delta + rate, max(self.delta - rate, lat.delta))
        delta = self.delta = min(c.limits.max_delta, max(-c.limits.max_delta, delta))
        limited = abs(delta - lat.delta) > 1e-12
        self.mu_hat_dot = 0.0 if limited or vx < gains.v_min else lat.mu_hat_dot
        v3 = lat.V2 + ((c.mu_true - self.mu_hat) ** 2 / (2.0 * c.g_mu) if c.g_mu > 0.0 else 0.0)
        return {"delta": delta, "torque": torque, "yL": preview["offset"], "psiL": psi_l,
                "yc": preview["offset"] - gains.ls * psi_l, "yc_cg": at_cg["offset"], "ex": lon.ex, "vx_ref": at_cg["v"], "rho": preview["kappa"],
                "mu_hat": self.mu_hat, "alpha_vy": float(lat.alpha[0]), "alpha_r": float(lat.alpha[1]),
                "z_vy": float(lat.z[0]), "z_r": float(lat.z[1]), "V": lon.V, "V2": lat.V2, "V3": v3}
