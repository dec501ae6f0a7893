"""An FMI 2.0 / 3.0 co-simulation FMU hosted in the master's process via fmpy.

Value references are resolved once from the FMU's interface (canonical names,
see `cosim.fmu.interface`); each step sets the held inputs, calls doStep from
the previous communication point and reads the outputs through preallocated
ctypes arrays. Every FMI error becomes a `ComponentFailure` carrying the last
messages the FMU logged.
"""

from __future__ import annotations

import ctypes
import shutil
from collections import deque
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import fmpy
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
from fmpy.fmi3 import FMU3Slave
from fmpy.logging import addLoggerProxy

from cosim.component import Port, Value
from cosim.errors import ComponentFailure, FmuInterfaceError

_STATUS = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal", 5: "Pending"}
LOG_KEEP = 8  # last FMU log messages kept for error reports


class FmuLog:
    """Keeps the last messages an FMU logged (FMI 2 logger / FMI 3 logMessage)."""

    def __init__(self) -> None:
        self.messages: deque[str] = deque(maxlen=LOG_KEEP)

    def add(self, status: int, category: bytes | None, message: bytes | None) -> None:
        """Record one message (bytes from the C side)."""
        text = (message or b"").decode("utf-8", "replace").strip()
        cat = (category or b"").decode("utf-8", "replace")
        self.messages.append(f"[{_STATUS.get(status, status)}{'/' + cat if cat else ''}] {text}")

    def fmi2(self, env, instance, status, category, message) -> None:  # noqa: ANN001
        """FMI 2 logger callback (message already formatted by fmpy's proxy)."""
        self.add(status, category, message)

    def fmi3(self, env, status, category, message) -> None:  # noqa: ANN001
        """FMI 3 logMessage callback."""
        self.add(status, category, message)

    def text(self) -> str:
        """The kept messages, newest last, or a note that there were none."""
        return "; ".join(self.messages) if self.messages else "the FMU logged no message"


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
    """

    direct_feedthrough = False  # co-simulation FMUs integrate over [t_prev, t)

    def __init__(self, name: str, path: str | Path, interface: Any,
                 parameters: Mapping[str, float], period_ticks: int) -> None:
        self.name = name
        self.path = Path(path)
        self.interface = interface
        self.period_ticks = int(period_ticks)
        self.inputs: tuple[Port, ...] = tuple(interface.inputs)
        self.outputs: tuple[Port, ...] = tuple(interface.outputs)
        self.parameters = {str(k): float(v) for k, v in parameters.items()}
        arrays = [p.name for p in (*self.inputs, *self.outputs) if p.size != 1]
        if arrays:
            raise FmuInterfaceError(f"component {name!r}: array variables of FMU "
                                    f"{self.path.name} are not supported yet: {', '.join(arrays)}")
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
        self.log = FmuLog()
        self._fmu: Any = None
        self._unzipped: str | None = None
        self._t_prev = 0.0
        self._initialized = False

    def start(self, t0: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Instantiate, set parameters and inputs, initialize at t0, read outputs."""
        self._t_prev = t0
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
        except Exception as exc:  # fmpy raises FMICallException or plain Exception
            raise self._failure(None, t0, exc) from exc

    def step(self, tick: int, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Set the held inputs, doStep(t_prev, t - t_prev), read the outputs.

        The hot path calls the FMU's C functions directly (fmpy's wrappers cost
        several microseconds per call) and checks their status itself.
        """
        try:
            self._set_inputs(inputs)
            status = self._do_step(self._t_prev, t - self._t_prev)
            if status > 1:  # discard, error, fatal: the step did not complete
                raise FMICallException(self._do_step_name, status)
            if self.fmi3 and self._terminate.value:
                raise ComponentFailure(self.name, tick, t, "the FMU asked to terminate "
                                       f"the simulation: {self.log.text()}")
            self._t_prev = t
            return self._get_outputs()
        except ComponentFailure:
            raise
        except Exception as exc:
            raise self._failure(tick, t, exc) from exc

    def stop(self) -> dict[str, float]:
        """Terminate (when initialized), free the instance and the unzipped files."""
        try:
            if self._fmu is not None:
                if self._initialized:
                    self._fmu.terminate()
                self._fmu.freeInstance()
        except Exception as exc:
            raise self._failure(None, self._t_prev, exc) from exc
        finally:
            self._fmu = None
            self._initialized = False
            if self._unzipped:
                shutil.rmtree(self._unzipped, ignore_errors=True)
                self._unzipped = None
        return {}

    def _instantiate(self) -> None:
        md = self.interface.model_description
        self._unzipped = fmpy.extract(str(self.path))
        kwargs = dict(guid=md.guid, unzipDirectory=self._unzipped,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName=self.name)
        if self.fmi3:
            self._fmu = FMU3Slave(**kwargs)
            self._fmu.instantiate(loggingOn=False, logMessage=self.log.fmi3)
            return
        self._fmu = FMU2Slave(**kwargs)
        self._callbacks = _fmi2_callbacks(self.log)
        self._fmu.instantiate(callbacks=self._callbacks, loggingOn=False)

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
        return ComponentFailure(self.name, tick, t, f"{exc} (FMU {self.path.name}: "
                                f"{self.log.text()})")


def _fmi2_callbacks(log: FmuLog) -> fmi2CallbackFunctions:
    """FMI 2 callbacks whose logger feeds `log` (fmpy's C proxy formats varargs).

    Args:
        log: where the FMU's messages go.
    """
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(log.fmi2)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
    addLoggerProxy(ctypes.byref(callbacks))
    return callbacks
