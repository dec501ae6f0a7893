"""Signals the figures plot, found by role with fallbacks.

Each function returns what a panel draws for one run, or None when the run did
not record it (the panel then says so instead of failing). Signals are read
through the run's roles (cosim.scenario.roles): `vehicle.vx` below is the vx of
the component that plays the vehicle (`metrics.vehicle`, default the component
named `vehicle`), `controller.*` and `planner.*` likewise.
"""

from __future__ import annotations

import numpy as np

from cosim.analysis.metrics import lateral_error_cg, true_mu
from cosim.analysis.rundata import ArraySignal, RunData

Series = tuple[np.ndarray, np.ndarray]


def column(run: RunData, *names: str) -> Series | None:
    """(time, values) of the first of `names` the run recorded, else None."""
    for name in names:
        values = run.signal(name)
        if values is not None:
            return run.time, values
    return None


def role_series(run: RunData, role: str, *signals: str) -> Series | None:
    """(time, values) of the first of a role's `signals` the run recorded, else None.

    Args:
        run: the run.
        role: "vehicle", "controller" or "planner".
        signals: signal names of that role's component ("vx_ref", ...).
    """
    for signal in signals:
        values = run.role_signal(role, signal)
        if values is not None:
            return run.time, values
    return None


def curvature(run: RunData) -> Series | None:
    """Path curvature: controller.rho, else the planner window's first-point kappa."""
    found = role_series(run, "controller", "rho")
    if found is not None:
        return found
    kappa = run.array(run.role_column("planner", "ref_kappa"))
    return None if kappa is None else (kappa.times, kappa.column(0))


def speed_reference(run: RunData) -> Series | None:
    """Reference speed: controller.vx_ref, else planner.v_ref."""
    return role_series(run, "controller", "vx_ref") or role_series(run, "planner", "v_ref")


def lateral_cg(run: RunData) -> Series | None:
    """yc, the paper's lateral error at the CG, yL - ls psiL (see metrics.lateral_error_cg)."""
    yc = lateral_error_cg(run)
    return None if yc is None else (run.time, yc)


def offset_cg(run: RunData) -> Series | None:
    """yc_cg, the CG's geometric offset from the path; the paper's yc when not recorded."""
    yc_cg = run.role_signal("controller", "yc_cg")
    return lateral_cg(run) if yc_cg is None else (run.time, yc_cg)


def friction(run: RunData) -> tuple[Series, str]:
    """The true friction fed to the vehicle and its source's name."""
    mu, source = true_mu(run)
    return (run.time, mu), source


def window(run: RunData, prefix: str) -> tuple[ArraySignal, ArraySignal] | None:
    """The planner's recorded windows `<prefix>_x` and `<prefix>_y`, or None."""
    xs, ys = (run.array(run.role_column("planner", f"{prefix}_{axis}")) for axis in ("x", "y"))
    if xs is None or ys is None or xs.shape != ys.shape:
        return None
    return xs, ys


def path_trace(run: RunData, prefix: str) -> Series | None:
    """The planned path as one line: each window's first point, then the last window."""
    found = window(run, prefix)
    if found is None:
        return None
    xs, ys = found
    return (np.concatenate([xs.column(0)[:-1], xs.row(-1)]),
            np.concatenate([ys.column(0)[:-1], ys.row(-1)]))


def vehicle_mass(run: RunData) -> float:
    """Mass for m * a_ref: the controller's nominal m, else the plant's, else 1500 kg."""
    for where in (run.role_path("controller", "parameters.m"), run.role_path("vehicle", "parameters.m")):
        if run.lookup(where) is not None:
            return run.number(where, 1500.0)
    return 1500.0


def reference_acceleration(run: RunData) -> Series | None:
    """a_ref over time: a scalar output if recorded, else the planner's window.

    From the window `planner.ref_a`, each recorded window gives the value at
    its point nearest to the vehicle's position at that window's time.
    """
    found = role_series(run, "controller", "a_ref", "ax_ref") or role_series(run, "planner", "a_ref")
    if found is not None:
        return found
    a_ref, win = run.array(run.role_column("planner", "ref_a")), window(run, "ref")
    px, py = run.role_signal("vehicle", "x"), run.role_signal("vehicle", "y")  # position, not speed
    if a_ref is None or win is None or px is None or py is None or len(run.time) == 0:
        return None
    xs, ys = win
    if xs.values.shape != a_ref.values.shape:
        return None
    tick = np.clip(np.searchsorted(run.time, xs.times), 0, len(run.time) - 1)
    dist2 = (xs.values - px[tick, None]) ** 2 + (ys.values - py[tick, None]) ** 2
    nearest = np.argmin(dist2, axis=1)
    return a_ref.times, a_ref.values[np.arange(len(nearest)), nearest]
