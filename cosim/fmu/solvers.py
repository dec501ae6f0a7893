"""Integrators of Model Exchange FMUs: fmpy's CVode, or a fixed-step RK4 / forward Euler.

`make_solver` returns an object with fmpy's solver interface:
`step(t, t_next) -> (state_event, roots, t_reached)` and `reset(t)` (after an
event changed the states). CVode (`fmpy.sundials.CVodeSolver`, BDF) integrates
to t_next or to the first root of the event indicators, as in
`fmpy.simulate_fmu`; its absolute tolerance is rtol times each state's nominal
unless `atol` is given. `FixedStep` takes one step of at most `max_step` per
call; RK4 locates a zero crossing by bisection on the step length (to
`EVENT_TOL` s), Euler reports it at the end of the step, as fmpy's Euler does.

CVode calls the FMU back from C (derivatives, event indicators, states, time):
an FMI error raised there cannot cross CVode's frames (ctypes would print a
traceback and let CVode go on), so `CallGuard` keeps the first one, makes every
later callback call nothing (after Fatal, FMI forbids any call), and the
solver's `step` and `reset` raise it when CVode returns.
"""

from __future__ import annotations

import math
from ctypes import POINTER, c_double
from typing import Any

import numpy as np

EVENT_TOL = 1e-12  # s, RK4 event location (relative to max(1, |t|))


class _NoInput:
    """fmpy's CVodeSolver sets inputs in its root function: the host holds them itself."""

    def apply(self, time: float, **kwargs: Any) -> None:
        """Nothing to do: inputs are held over the step."""


def make_solver(settings: dict[str, Any], fmu: Any, md: Any, fmi3: bool, t0: float) -> Any:
    """The integrator for one instance, started at t0 from the FMU's current states.

    Args:
        settings: {"method": "cvode"|"rk4"|"euler", "rtol", "atol" (or None), "max_step"}.
        fmu: fmpy's FMU2Model / FMU3Model, in continuous-time mode.
        md: its model description (numbers of states and event indicators).
        fmi3: FMI 3 (the derivatives getter's name differs).
        t0: the start time.
    """
    names = [unknown.variable.name for unknown in md.derivatives]
    args = dict(nx=md.numberOfContinuousStates, nz=md.numberOfEventIndicators,
                get_x=fmu.getContinuousStates, set_x=fmu.setContinuousStates,
                get_dx=finite_derivatives(
                    fmu.getContinuousStateDerivatives if fmi3 else fmu.getDerivatives, names),
                get_z=fmu.getEventIndicators)
    if settings["method"] != "cvode":
        return FixedStep(settings["method"], settings["max_step"], set_time=fmu.setTime, **args)
    from fmpy.sundials import CVodeSolver

    guard = CallGuard()
    args = {name: guard.wrap(function) if callable(function) else function
            for name, function in args.items()}
    solver = CVodeSolver(get_nominals=guard.wrap(fmu.getNominalsOfContinuousStates),
                         set_time=guard.wrap(fmu.setTime), input=_NoInput(), startTime=t0,
                         maxStep=settings["max_step"], relativeTolerance=settings["rtol"],
                         **args)
    guard.check()
    solver.step, solver.reset = guard.checked(solver.step), guard.checked(solver.reset)
    if settings.get("atol") is not None:
        from fmpy.sundials.cvode import CVodeSVtolerances

        solver.npabstol[:] = settings["atol"]  # CVode copies the vector: set it again
        CVodeSVtolerances(solver.cvode_mem, settings["rtol"], solver.abstol)
        solver.reset = _keep_atol(solver, settings["atol"])
    return solver


class NonFiniteDerivative(ValueError):
    """The FMU gave a derivative that is not a finite number (the message names it;
    `details` is the manifest's cause)."""

    def __init__(self, name: str, value: float) -> None:
        super().__init__(f"the FMU's {name} is {value!r}")
        self.details = {"kind": "non_finite_derivative", "derivative": name, "value": repr(value)}


def finite_derivatives(get_dx: Any, names: list[str]) -> Any:
    """`get_dx(pointer, n)` that raises NonFiniteDerivative naming the first derivative
    the FMU returned as NaN or infinite: the integrator would otherwise go on with it
    (CVode until it gives up, without saying which state)."""
    def checked(pointer: Any, count: int) -> Any:
        result = get_dx(pointer, count)
        values = pointer[:count]
        if not all(map(math.isfinite, values)):
            index = next(i for i, v in enumerate(values) if not math.isfinite(v))
            name = names[index] if index < len(names) else f"derivative {index}"
            raise NonFiniteDerivative(name, values[index])
        return result
    return checked


class CallGuard:
    """The FMU functions CVode calls back: the first FMI error is kept, later calls
    call nothing, `check` raises the error (see the module)."""

    def __init__(self) -> None:
        self.error: Exception | None = None

    def wrap(self, function: Any) -> Any:
        """`function`, called only while no error happened; an error is kept."""
        def guarded(*args: Any) -> Any:
            if self.error is None:
                try:
                    return function(*args)
                except Exception as exc:  # fmpy's FMICallException, from inside CVode
                    self.error = exc
            return None
        return guarded

    def checked(self, method: Any) -> Any:
        """`method` (the solver's step or reset), raising the kept error after it."""
        def call(*args: Any) -> Any:
            try:
                result = method(*args)
            except RuntimeError:  # CVode failed: because of the FMU's error, if there is one
                self.check()
                raise
            self.check()
            return result
        return call

    def check(self) -> None:
        """Raise the kept FMI error, if any."""
        if self.error is not None:
            raise self.error


def _keep_atol(solver: Any, atol: float) -> Any:
    """CVodeSolver.reset refills its tolerance vector from the nominals: keep atol instead."""
    original = solver.reset

    def reset(time: float) -> None:
        original(time)
        solver.npabstol[:] = atol
    return reset


class FixedStep:
    """Fixed-step RK4 or forward Euler over an FMU's continuous states.

    Args:
        method: "rk4" or "euler".
        max_step: the largest step, s (each call takes one step of
            (t_next - t) / ceil((t_next - t) / max_step)).
        nx, nz: numbers of states and event indicators.
        get_x, set_x, get_dx, get_z, set_time: the FMU's functions (fmpy wrappers).
    """

    def __init__(self, method: str, max_step: float, nx: int, nz: int, get_x: Any,
                 set_x: Any, get_dx: Any, get_z: Any, set_time: Any) -> None:
        self.method, self.max_step = method, float(max_step)
        self.set_time, self.get_x, self.set_x, self.get_dx, self.get_z = (
            set_time, get_x, set_x, get_dx, get_z)
        self.x, self.dx = np.zeros(nx), np.zeros(nx)
        self.z, self.z0 = np.zeros(nz), np.zeros(nz)
        self._px = self.x.ctypes.data_as(POINTER(c_double))
        self._pdx = self.dx.ctypes.data_as(POINTER(c_double))
        self._pz = self.z.ctypes.data_as(POINTER(c_double))

    def step(self, t: float, t_next: float) -> tuple[bool, np.ndarray, float]:
        """One step from t towards t_next; stops at a zero crossing of the indicators."""
        span = t_next - t
        n = max(1, math.ceil(span / self.max_step - 1e-9))
        t_end = t_next if n == 1 else t + span / n
        self.get_x(self._px, self.x.size)
        start = self.x.copy()
        self.z0[:] = self._indicators()
        x_end = self._advance(t, start, t_end - t)
        roots = self._crossings()
        if roots.any() and self.method == "rk4":
            t_end, x_end = self._locate(t, start, t_end)
            roots = self._crossings()
        self._set_state(t_end, x_end)
        return bool(roots.any()), roots, t_end

    def reset(self, time: float) -> None:
        """Nothing is carried between steps."""

    def _advance(self, t: float, x: np.ndarray, h: float) -> np.ndarray:
        """The state after one step of length h from (t, x); FMU left at its end."""
        k1 = self._derivatives(t, x)
        if self.method == "euler":
            end = x + h * k1
        else:
            k2 = self._derivatives(t + h / 2, x + h / 2 * k1)
            k3 = self._derivatives(t + h / 2, x + h / 2 * k2)
            k4 = self._derivatives(t + h, x + h * k3)
            end = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        self._set_state(t + h, end)
        self.z[:] = self._indicators()
        return end

    def _locate(self, t: float, start: np.ndarray, t_end: float) -> tuple[float, np.ndarray]:
        """Bisect the step length to the first crossing; the time just past it and its state."""
        lo, hi = 0.0, t_end - t
        while hi - lo > EVENT_TOL * max(1.0, abs(t)):
            mid = (lo + hi) / 2
            self._advance(t, start, mid)
            if self._crossings().any():
                hi = mid
            else:
                lo = mid
        return t + hi, self._advance(t, start, hi)  # leaves the indicators at the crossing

    def _derivatives(self, t: float, x: np.ndarray) -> np.ndarray:
        self._set_state(t, x)
        self.get_dx(self._pdx, self.dx.size)
        return self.dx.copy()

    def _set_state(self, t: float, x: np.ndarray) -> None:
        self.set_time(t)
        self.x[:] = x
        self.set_x(self._px, self.x.size)

    def _indicators(self) -> np.ndarray:
        self.get_z(self._pz, self.z.size)
        return self.z.copy()

    def _crossings(self) -> np.ndarray:
        """fmpy's convention: -1 rising through 0, 1 falling through 0, else 0."""
        rising = (self.z0 < 0) & (self.z >= 0)
        falling = (self.z0 > 0) & (self.z <= 0)
        return np.where(rising, -1, np.where(falling, 1, 0)).astype(np.int32)
