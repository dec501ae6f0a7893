"""An FMI 2.0 / 3.0 co-simulation FMU hosted in the master's process via fmpy.

Value references are resolved once from the FMU's interface (canonical names,
see `cosim.fmu.interface`); each step sets the held inputs, calls doStep from
the previous communication point and reads the outputs through preallocated
ctypes arrays: Float64/Real scalars only (an FMU with ports of other types or
FMI 3 arrays is hosted by the subclass in `cosim.fmu.typed`, chosen at setup so
that this step path stays as it is). The step is one C call through the
stepping shim (`cosim.fmu.stepper`, compiled into the per-user cache like the
FMUs), or, when the shim cannot be built (no compiler), three calls of the
FMU's functions from Python; both make the same FMI calls with the same
arguments, so the outputs are the same bits. `step_values` is the same step on
plain floats, the master's values lane (`cosim.engine.hosting`). Instantiation, the FMU's log, its errors and FMI's call-sequence
rules are those of every in-process host (`cosim.fmu.instance.FmuInstance`). A
termination request (FMI 2: Discard with fmi2Terminated, FMI 3:
terminateSimulation) raises `StopRequested` with the outputs of that step, which
the master records before it ends the run normally.
"""

from __future__ import annotations

import ctypes
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2Terminated

from cosim.component import Port, Value
from cosim.engine.values import picker
from cosim.errors import ComponentFailure, FmuInterfaceError, StopRequested
from cosim.fmu import stepper
from cosim.fmu.instance import FmuInstance


class FmuComponent(FmuInstance):
    """HostedComponent around one FMU instance.

    Args:
        name: component name in the scenario.
        path: the .fmu file.
        interface: `cosim.fmu.interface.FmuInterface` of that file (ports with
            canonical names, value references, FMI version, model description).
        parameters: canonical parameter name -> value (uncertainty applied),
            set before initialization.
        period_ticks: master ticks between two steps.
        log_file: run.log of the run, to append the FMU's messages to (and
            show its warnings and errors); None: kept only for error reports.
        use_shim: step through the stepping shim when it can be built; False:
            fmpy's per-call path and logger proxy, as without a compiler (benchmarks).
    """

    direct_feedthrough = False  # co-simulation FMUs integrate over [t_prev, t)

    def __init__(self, name: str, path: str | Path, interface: Any,
                 parameters: Mapping[str, float], period_ticks: int,
                 log_file: str | Path | None = None, use_shim: bool = True) -> None:
        self.name = name
        self.use_shim = use_shim
        self.path = Path(path)
        self.interface = interface
        self.period_ticks = int(period_ticks)
        self.inputs: tuple[Port, ...] = tuple(interface.inputs)
        self.outputs: tuple[Port, ...] = tuple(interface.outputs)
        self.parameters = {str(k): float(v) for k, v in parameters.items()}
        self.fmi3 = str(interface.fmi_version).startswith("3")
        vrs = interface.value_references
        self._in_names = [p.name for p in self.inputs]
        self._out_names = [p.name for p in self.outputs]
        self._in_vr = (ctypes.c_uint * len(self.inputs))(*[vrs[n] for n in self._in_names])
        self._in_val = (ctypes.c_double * len(self.inputs))()
        self._out_vr = (ctypes.c_uint * len(self.outputs))(*[vrs[n] for n in self._out_names])
        self._out_val = (ctypes.c_double * len(self.outputs))()
        self._out_floats = memoryview(self._out_val).cast("B").cast("d")  # tolist(): 0.2 us less than [:]
        unknown = sorted(set(self.parameters) - set(vrs))
        if unknown:
            raise FmuInterfaceError(f"component {name!r}: FMU {self.path.name} has no "
                                    f"parameter {', '.join(map(repr, unknown))}")
        self._param_vrs = [vrs[n] for n in self.parameters]
        super().__init__(log_file)
        self._stepper: stepper.Stepper | None = None  # None: the per-call path
        self._pick_inputs = picker(self._in_names)
        self.value_names = (tuple(self._in_names), tuple(self._out_names))  # the values lane
        self.values_exact = True  # step_values gives a list of len(outputs) Python floats

    def start(self, t0: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Instantiate, set parameters and inputs, initialize at t0, read outputs."""
        self._t_prev = self.log.time = t0
        try:
            self._instantiate()
            fmu = self._fmu
            if self.parameters:
                self._set_real(self._param_vrs, list(self.parameters.values()))
            if self.fmi3:
                fmu.enterInitializationMode(startTime=t0)
            else:
                fmu.setupExperiment(startTime=t0)
                fmu.enterInitializationMode()
            self._bind()
            self._set_inputs(inputs)
            fmu.exitInitializationMode()
            self._initialized = True
            return self._get_outputs()
        except ComponentFailure:  # a value no signal can hold (cosim.fmu.typed): said already
            raise
        except Exception as exc:  # fmpy raises FMICallException or plain Exception
            raise self._failure(None, t0, exc) from exc

    def step(self, tick: int, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Set the held inputs, doStep(t_prev, t - t_prev), read the outputs (see step_values)."""
        try:
            held = self._pick_inputs(inputs)
        except Exception as exc:
            raise self._failure(tick, t, exc) from exc
        return dict(zip(self._out_names, self.step_values(tick, t, held)))

    def step_values(self, tick: int, t: float, inputs: Sequence[float]) -> list[float]:
        """`step` on plain values: inputs in `value_names[0]` order, outputs in `value_names[1]` order.

        The hot path calls the FMU's C functions directly (fmpy's wrappers cost
        several microseconds per call): through the shim in one call, else one
        by one; the statuses are checked here.
        """
        self.log.time = t
        try:
            if self._stepper is None:
                return list(self._step_per_call(tick, t, dict(zip(self._in_names, inputs))).values())
            if self._in_names:
                self._in_val[:] = inputs
            times = self._shim_times
            times[0] = t_prev = self._t_prev
            times[1] = t - t_prev
            code = self._shim_call(self._shim_address)
            if code:
                self._shim_problem(tick, t, code)
            self._t_prev = t
            self._tick = tick
            return self._out_floats.tolist()
        except (ComponentFailure, StopRequested):
            raise
        except Exception as exc:
            raise self._failure(tick, t, exc) from exc

    def _step_per_call(self, tick: int, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """The step without the shim: set, doStep and get as three calls from Python."""
        self._set_inputs(inputs)
        status = self._do_step(self._t_prev, t - self._t_prev)
        if status > 1 or (self.fmi3 and self._terminate.value):
            self._step_problem(tick, t, status)
        self._t_prev = t
        self._tick = tick
        return self._get_outputs()

    def _shim_problem(self, tick: int, t: float, code: int) -> None:
        """A shim step that stopped early: which call, with which status (as after our own call)."""
        if code in (stepper.STEP_DO_STEP, stepper.STEP_TERMINATE):
            self._step_problem(tick, t, self._stepper.struct.status[1])
        raise FMICallException(*self._stepper.failure(code))

    def _terminate_requested(self) -> bool:
        """FMI 3: whether the last doStep set terminateSimulation."""
        if self._stepper is not None:
            return bool(self._stepper.struct.terminate_simulation)
        return bool(self._terminate.value)

    def _step_problem(self, tick: int, t: float, status: int) -> None:
        """A step that did not end OK: a termination request (StopRequested) or an error."""
        if self.fmi3:
            asked = self._terminate_requested() and status <= 2
        else:
            asked = status == 2 and bool(self._fmu.getBooleanStatus(fmi2Terminated))
        if not asked:
            raise FMICallException(self._do_step_name, status)
        outputs = self._get_outputs()  # allowed in FMI 2's stepFailed state and FMI 3
        self._t_prev = t
        self._tick = tick
        raise self._stop_request(tick, t, outputs)

    def stop(self) -> dict[str, float]:
        """Terminate (when initialized), free the instance and the unzipped files
        (nothing after a Fatal status, see `FmuInstance`)."""
        try:
            self._release()
        finally:
            self._stepper = None
        return {}

    def _set_real(self, vrs: list[int], values: list[float]) -> None:
        if self.fmi3:
            self._fmu.setFloat64(vrs, values)
        else:
            self._fmu.setReal(vrs, values)

    def _bind(self) -> None:
        """Bind the raw C functions used every step (after instantiation)."""
        fmu, functions = self._fmu, self._fmu._functions
        comp = fmu.component
        n_in, n_out = len(self._in_names), len(self._out_names)
        in_vr, in_val, out_vr, out_val = self._in_vr, self._in_val, self._out_vr, self._out_val
        if self.fmi3:
            set_f, get_f, do_f = (functions["fmi3SetFloat64"], functions["fmi3GetFloat64"],
                                  functions["fmi3DoStep"])
            flags = [ctypes.c_bool(), ctypes.c_bool(), ctypes.c_bool()]
            self._terminate = flags[1]
            last = ctypes.c_double()
            refs = [ctypes.byref(f) for f in flags] + [ctypes.byref(last)]
            self._raw_set = lambda: set_f(comp, in_vr, n_in, in_val, n_in)
            self._raw_get = lambda: get_f(comp, out_vr, n_out, out_val, n_out)
            self._do_step = lambda t, h: do_f(comp, t, h, True, *refs)
            self._do_step_name = "fmi3DoStep"
        else:
            set_f, get_f, do_f = (functions["fmi2SetReal"], functions["fmi2GetReal"],
                                  functions["fmi2DoStep"])
            self._raw_set = lambda: set_f(comp, in_vr, n_in, in_val)
            self._raw_get = lambda: get_f(comp, out_vr, n_out, out_val)
            self._do_step = lambda t, h: do_f(comp, t, h, 1)
            self._do_step_name = "fmi2DoStep"
        self._bind_shim()

    def _bind_shim(self) -> None:
        """Step through the shim when it can be built (else `_step_per_call`).

        The shim sets and gets the Real (FMI 3: Float64) variables only, the
        hot path; variables of other types go through fmpy's calls around it.
        """
        if self._shim is None:
            return
        self._stepper = stepper.Stepper(self._shim, self._fmu, self._in_vr, self._in_val,
                                        self._out_vr, self._out_val)
        self._shim_call, self._shim_address = self._stepper.call, self._stepper.address
        self._shim_times = self._stepper.times

    def _set_inputs(self, inputs: Mapping[str, Value]) -> None:
        if not self._in_names:
            return
        self._in_val[:] = [inputs[name] for name in self._in_names]
        status = self._raw_set()
        if status > 1:
            raise FMICallException("fmi3SetFloat64" if self.fmi3 else "fmi2SetReal", status)

    def _get_outputs(self) -> dict[str, Value]:
        if self._out_names:
            status = self._raw_get()
            if status > 1:
                raise FMICallException("fmi3GetFloat64" if self.fmi3 else "fmi2GetReal", status)
        return dict(zip(self._out_names, self._out_floats.tolist()))
