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
arguments, so the outputs are the same bits. The shim also gives each FMI 2
instance a logger of its own (fmpy's proxy has one for the whole process).
`step_values` is the same step on plain floats, the master's values lane
(`cosim.engine.hosting`). Every FMI error becomes a `ComponentFailure` carrying
the last messages the FMU logged (logging is always on; with `log_file` every
message also goes to the run's run.log, warnings and errors to the terminal too).

FMI call sequence: after a Fatal status no FMI function is called any more
(not even freeInstance, which FMI forbids then); after an Error only
freeInstance. A termination request (FMI 2: Discard with fmi2Terminated, FMI 3:
terminateSimulation) raises `StopRequested` with the outputs of that step, which
the master records before it ends the run normally.
"""

from __future__ import annotations

import ctypes
import shutil
import sys
from collections import deque
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import fmpy
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Model, FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2Terminated)
from fmpy.fmi3 import FMU3Model, FMU3Slave
from fmpy.logging import addLoggerProxy

from cosim.component import Port, Value
from cosim.engine.values import picker
from cosim.errors import ComponentFailure, FmuInterfaceError, StopRequested
from cosim.fmu import stepper

_STATUS = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal", 5: "Pending"}
FATAL = 4
LOG_KEEP = 8  # last FMU log messages kept for error reports
ECHO_LIMIT = 20  # warnings and errors shown on the terminal; the rest only in run.log


class FmuLog:
    """Keeps the last messages an FMU logged (FMI 2 logger / FMI 3 logMessage).

    Args:
        component: the component's name, for the lines of run.log and the terminal.
        sink: a text file (run.log, opened for appending) that gets every
            message; None: messages are only kept for error reports.
    """

    def __init__(self, component: str = "", sink: Any = None) -> None:
        self.messages: deque[str] = deque(maxlen=LOG_KEEP)
        self.problems: deque[str] = deque(maxlen=LOG_KEEP)  # warnings, errors and fatals
        self.component, self.sink, self.echoed = component, sink, 0
        self.time = 0.0  # the time of the call under way, for the lines of run.log

    def add(self, status: int, category: bytes | None, message: bytes | None) -> None:
        """Record one message (bytes from the C side)."""
        text = (message or b"").decode("utf-8", "replace").strip()
        cat = (category or b"").decode("utf-8", "replace")
        entry = f"[{_STATUS.get(status, status)}{'/' + cat if cat else ''}] {text}"
        self.messages.append(entry)
        if status in (1, 3, 4):
            self.problems.append(entry)
        if self.sink is not None:
            self._write(status, entry)

    def _write(self, status: int, entry: str) -> None:
        line = f"t={self.time:.10g} {self.component}: {entry}\n"
        self.sink.write(line)
        self.sink.flush()
        if status in (1, 3, 4) and self.echoed < ECHO_LIMIT:  # warning, error, fatal
            self.echoed += 1
            more = " (further messages only in run.log)" if self.echoed == ECHO_LIMIT else ""
            sys.stderr.write(f"FMU {line.rstrip()}{more}\n")

    def close(self) -> None:
        """Close the sink (run.log) if there is one."""
        if self.sink is not None:
            self.sink.close()
            self.sink = None

    def fmi2(self, env, instance, status, category, message) -> None:  # noqa: ANN001
        """FMI 2 logger callback (message already formatted by fmpy's proxy)."""
        self.add(status, category, message)

    def fmi3(self, env, status, category, message) -> None:  # noqa: ANN001
        """FMI 3 logMessage callback."""
        self.add(status, category, message)

    def text(self) -> str:
        """The last warnings and errors logged (else the last message), or a note that there were none."""
        if self.problems:
            return "; ".join(self.problems)
        return self.messages[-1] if self.messages else "the FMU logged no message"


class FmuComponent:
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
        unknown = sorted(set(self.parameters) - set(vrs))
        if unknown:
            raise FmuInterfaceError(f"component {name!r}: FMU {self.path.name} has no "
                                    f"parameter {', '.join(map(repr, unknown))}")
        self._param_vrs = [vrs[n] for n in self.parameters]
        sink = open(log_file, "a", encoding="utf-8") if log_file is not None else None
        self.log = FmuLog(name, sink)
        self._fmu: Any = None
        self._shim: Any = None  # the stepping shim library, None: fmpy's per-call path
        self._stepper: stepper.Stepper | None = None  # None: the per-call path
        self._pick_inputs = picker(self._in_names)
        self.value_names = (tuple(self._in_names), tuple(self._out_names))  # the values lane
        self._unzipped: str | None = None
        self._t_prev = 0.0
        self._initialized = False
        self._fatal = False  # after Fatal, FMI allows no call at all

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
            code = self._shim_call(self._shim_address, self._t_prev, t - self._t_prev)
            if code:
                self._shim_problem(tick, t, code)
            self._t_prev = t
            return self._out_val[:]
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
        raise StopRequested(self.name, tick, t, outputs, "the FMU asked to terminate the "
                            f"simulation ({self.log.text()})")

    def stop(self) -> dict[str, float]:
        """Terminate (when initialized), free the instance and the unzipped files.

        After a Fatal status nothing is called: the instance and its library
        stay as they are until the process ends.
        """
        try:
            if self._fmu is not None and not self._fatal:
                if self._initialized:
                    self._fmu.terminate()
                self._fmu.freeInstance()
        except Exception as exc:
            raise self._failure(None, self._t_prev, exc) from exc
        finally:
            if self._fatal and self._fmu is not None:
                _keep_alive.append((self._fmu, getattr(self, "_callbacks", None)))
            self._fmu = self._stepper = None
            self._initialized = False
            self.log.close()
            if self._unzipped:
                shutil.rmtree(self._unzipped, ignore_errors=True)
                self._unzipped = None
        return {}

    def _instantiate(self) -> None:
        self._shim = stepper.library() if self.use_shim else None
        self._unzipped, self._fmu, self._callbacks = instantiate(
            self.path, self.interface, self.name, self.log, model_exchange=False, logging_on=True,
            shim=self._shim)

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
        return dict(zip(self._out_names, self._out_val[:]))

    def _failure(self, tick: int | None, t: float, exc: Exception) -> ComponentFailure:
        self._initialized = False  # after an FMI error only freeInstance is allowed
        status = getattr(exc, "status", None)
        if status == FATAL:
            self._fatal = True
        details = {"kind": "fmi_status", "status": _STATUS.get(status, status)} if status else {}
        return ComponentFailure(self.name, tick, t, f"{exc} (FMU {self.path.name}: "
                                f"{self.log.text()})", details)


_keep_alive: list[Any] = []  # FMU instances (and their callbacks) after a Fatal status


def _fmi2_callbacks(log: FmuLog, shim: Any) -> fmi2CallbackFunctions:
    """FMI 2 callbacks whose logger feeds `log`.

    The shim's logger when there is a shim (one per instance), else fmpy's C
    proxy (one for the whole process: with two FMI 2 instances, the messages
    of both go to the last one set up).

    Args:
        log: where the FMU's messages go.
        shim: the stepping shim library (`cosim.fmu.stepper.library()`), or None.
    """
    if shim is not None:
        return stepper.fmi2_callbacks(shim, log.add)
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(log.fmi2)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
    addLoggerProxy(ctypes.byref(callbacks))
    return callbacks


def instantiate(path: Path, interface: Any, name: str, log: Any, model_exchange: bool,
                logging_on: bool, shim: Any = None) -> tuple[str, Any, Any]:
    """Extract an FMU and instantiate it through fmpy, its messages going to `log`.

    Args:
        path: the .fmu file.
        interface: its FmuInterface (model description, FMI version).
        name: the instance name (the component's).
        log: the FmuLog that receives the FMU's messages.
        model_exchange: instantiate the Model Exchange interface (else co-simulation).
        logging_on: ask the FMU to log its debug categories too.
        shim: the stepping shim library, whose FMI 2 logger is per instance; None: fmpy's proxy.
    Returns:
        (extraction folder, the fmpy FMU object, the FMI 2 callbacks to keep alive or None).
    """
    md = interface.model_description
    unzipped = fmpy.extract(str(path))
    description = md.modelExchange if model_exchange else md.coSimulation
    kwargs = dict(guid=md.guid, unzipDirectory=unzipped,
                  modelIdentifier=description.modelIdentifier, instanceName=name)
    if md.fmiVersion.startswith("3"):
        fmu = (FMU3Model if model_exchange else FMU3Slave)(**kwargs)
        fmu.instantiate(loggingOn=logging_on, logMessage=log.fmi3)
        return unzipped, fmu, None
    fmu = (FMU2Model if model_exchange else FMU2Slave)(**kwargs)
    callbacks = _fmi2_callbacks(log, shim)
    fmu.instantiate(callbacks=callbacks, loggingOn=logging_on)
    return unzipped, fmu, callbacks
