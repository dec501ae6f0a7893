"""An FMI 2.0 / 3.0 Model Exchange FMU hosted in the master's process, integrated by the master.

The same `HostedComponent` protocol as the co-simulation host
(`cosim.fmu.host.FmuComponent`): inputs set at the start of a step are held
over [t_prev, t) and the outputs are read at t. Between two ticks the
integrator (`cosim.fmu.solvers`: fmpy's CVode, RK4 or Euler) advances the
continuous states; the host handles the three kinds of event the way
`fmpy.simulate_fmu(fmi_type="ModelExchange")` does:

- time events: the integrator stops at the FMU's next event time;
- state events: a zero crossing of the event indicators ends an integrator step;
- step events: `completedIntegratorStep` after every integrator step asks for one;

each followed by event mode, the discrete-state iteration
(newDiscreteStates / updateDiscreteStates) and a solver reset. An input that
changes at a tick is an input event (event mode, then a reset), as a step in
fmpy's input table is.

Errors, the FMU's log and FMI's call-sequence rules (nothing after Fatal, only
freeInstance after an Error) are those of every in-process host
(`cosim.fmu.instance.FmuInstance`). A termination request (`terminateSimulation`
out of newDiscreteStates / updateDiscreteStates or completedIntegratorStep)
raises `StopRequested` with the outputs the FMU has when it asks, which the
master records as the tick's row before it ends the run normally (fmpy's
`simulate_fmu` stops there too; with `record_events=True` its last row is the
same point).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from cosim.component import Port, Value
from cosim.errors import ComponentFailure, FmuInterfaceError, StopRequested
from cosim.fmu.instance import FmuInstance
from cosim.fmu.solvers import make_solver
from cosim.fmu.typed import TypedIO, needs_typed_io


class ModelExchangeComponent(FmuInstance):
    """HostedComponent around one Model Exchange FMU instance.

    Args:
        name: component name in the scenario.
        path: the .fmu file.
        interface: its `cosim.fmu.interface.FmuInterface` (fmi_type "ModelExchange").
        parameters: canonical parameter name -> value, set before initialization.
        period_ticks: master ticks between two steps.
        solver: {"method": "cvode"|"rk4"|"euler", "rtol", "atol", "max_step"}, resolved
            (see `cosim.execution.prepare`).
        log_file: run.log, or None (see `FmuInstance`).
    """

    direct_feedthrough = False  # inputs held over [t_prev, t), as for co-simulation
    _model_exchange = True

    def __init__(self, name: str, path: str | Path, interface: Any,
                 parameters: Mapping[str, float], period_ticks: int,
                 solver: Mapping[str, Any], log_file: str | Path | None = None) -> None:
        self.name, self.path, self.interface = name, Path(path), interface
        self.period_ticks = int(period_ticks)
        self.inputs: tuple[Port, ...] = tuple(interface.inputs)
        self.outputs: tuple[Port, ...] = tuple(interface.outputs)
        self.parameters = {str(k): float(v) for k, v in parameters.items()}
        self.settings = dict(solver)
        if self.settings["method"] == "cvode":  # loaded now, not in start (under its deadline)
            import fmpy.sundials  # noqa: F401
        self.fmi3 = str(interface.fmi_version).startswith("3")
        vrs = interface.value_references
        missing = sorted(set(self.parameters) - set(vrs))
        if missing:
            raise FmuInterfaceError(f"component {name!r}: FMU {self.path.name} has no "
                                    f"parameter {', '.join(map(repr, missing))}")
        self._in_vr = [vrs[p.name] for p in self.inputs]
        self._out_vr = [vrs[p.name] for p in self.outputs]
        self._held: list[Any] | None = None
        self._io: TypedIO | None = None  # ports of other types than Float64, or arrays
        super().__init__(log_file)
        self._solver: Any = None
        self._next_event: float | None = None
        self.events = {"time": 0, "state": 0, "step": 0, "input": 0}

    def start(self, t0: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Instantiate, set parameters and inputs, initialize, settle the initial event."""
        self._t_prev = self.log.time = t0
        try:
            self._instantiate()
            fmu = self._fmu
            if self.parameters:
                self._set(list(self.interface.value_references[n] for n in self.parameters),
                          list(self.parameters.values()))
            if self.fmi3:
                fmu.enterInitializationMode(startTime=t0)
            else:
                fmu.setupExperiment(startTime=t0)
                fmu.enterInitializationMode()
            self._set_inputs(inputs)
            fmu.exitInitializationMode()
            self._initialized = True
            self._update_discrete_states(t0)
            fmu.enterContinuousTimeMode()
            self._solver = make_solver(self.settings, fmu, self.interface.model_description,
                                       self.fmi3, t0)
            return self._get_outputs()
        except ComponentFailure:
            raise
        except Exception as exc:  # fmpy raises FMICallException or plain Exception
            raise self._failure(None, t0, exc) from exc

    def step(self, tick: int, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Hold the inputs (an input event if they changed), integrate to t, read the outputs."""
        self.log.time = t
        if self._io is not None:
            self._io.tick = tick
        try:
            if self._inputs_changed(inputs):
                self.events["input"] += 1
                self._fmu.enterEventMode()
                self._set_inputs(inputs)
                self._update_discrete_states(self._t_prev, tick, t)
                self._fmu.enterContinuousTimeMode()
                self._solver.reset(self._t_prev)
            self._integrate(tick, t)
            self._t_prev = t
            self._tick = tick
            return self._get_outputs()
        except (ComponentFailure, StopRequested):
            raise
        except Exception as exc:
            raise self._failure(tick, t, exc) from exc

    def stop(self) -> dict[str, float]:
        """Terminate (when initialized), free the instance and the unzipped files
        (nothing after a Fatal status, see `FmuInstance`); the event counts."""
        self._solver = None
        self._release()
        return {f"{kind}_events": float(n) for kind, n in self.events.items()}

    def _integrate(self, tick: int, t_end: float) -> None:
        """Integrate from t_prev to t_end, handling every event on the way (as fmpy does)."""
        fmu, time = self._fmu, self._t_prev
        needs_step_call = self.interface.model_description.modelExchange.needsCompletedIntegratorStep
        while not (time > t_end or math.isclose(time, t_end)):
            target = t_end
            if self._next_event is not None and self._next_event < target \
                    and not math.isclose(self._next_event, target):
                target = self._next_event
            time_event = self._next_event is not None and math.isclose(target, self._next_event)
            state_event, _, time = self._solver.step(time, target)
            time_event = time_event and math.isclose(time, target)  # a fixed step may stop short
            fmu.setTime(time)
            step_event = False
            if needs_step_call:
                step_event, terminate = fmu.completedIntegratorStep()
                if terminate:
                    self._terminated(time, tick, t_end)
            if time_event or state_event or step_event:
                for kind, happened in (("time", time_event), ("state", state_event),
                                       ("step", step_event)):
                    self.events[kind] += int(bool(happened))
                fmu.enterEventMode()
                self._update_discrete_states(time, tick, t_end)
                fmu.enterContinuousTimeMode()
                self._solver.reset(time)

    def _update_discrete_states(self, time: float, tick: int | None = None,
                                t_tick: float | None = None) -> None:
        """The event iteration at `time` (in the step of `tick`, to `t_tick`; None: at
        the start); remembers the next time event."""
        update = self._fmu.updateDiscreteStates if self.fmi3 else self._fmu.newDiscreteStates
        needed = True
        while needed:
            needed, terminate, _, _, defined, next_time = update()
            if terminate:
                self._terminated(time, tick, t_tick)
        self._next_event = next_time if defined else None

    def _instantiate(self) -> None:
        super()._instantiate()
        if needs_typed_io(self.interface):
            self._io = TypedIO(self.name, self._fmu, self.fmi3, self.inputs, self.outputs,
                               self.interface.value_references)

    def _terminated(self, time: float, tick: int | None, t_tick: float | None) -> None:
        """The FMU asked to terminate at `time`: StopRequested in a step (the tick's
        row gets the outputs it has now), a failure during initialization."""
        if tick is None or t_tick is None:
            raise ComponentFailure(self.name, None, time, "the FMU asked to terminate the "
                                   f"simulation during initialization ({self.log.text()})")
        where = "" if math.isclose(time, t_tick) else f" at t={time:.10g} s"
        self._t_prev, self._tick = t_tick, tick  # a failing stop names this tick
        raise self._stop_request(tick, t_tick, self._get_outputs(), where)

    def _set(self, vrs: list[int], values: list[float]) -> None:
        if vrs:
            (self._fmu.setFloat64 if self.fmi3 else self._fmu.setReal)(vrs, values)

    def _inputs_changed(self, inputs: Mapping[str, Value]) -> bool:
        return self._held_values(inputs) != self._held

    def _held_values(self, inputs: Mapping[str, Value]) -> list[Any]:
        if self._io is None:
            return [float(inputs[p.name]) for p in self.inputs]
        return [np.ravel(inputs[p.name]).tolist() for p in self.inputs]

    def _set_inputs(self, inputs: Mapping[str, Value]) -> None:
        self._held = self._held_values(inputs)
        if self._io is not None:
            self._io.set(inputs, self._t_prev)
        else:
            self._set(self._in_vr, self._held)

    def _get_outputs(self) -> dict[str, Value]:
        if self._io is not None:
            return self._io.get(self._t_prev)
        if not self._out_vr:
            return {}
        values = (self._fmu.getFloat64 if self.fmi3 else self._fmu.getReal)(self._out_vr)
        return {p.name: float(v) for p, v in zip(self.outputs, values)}
