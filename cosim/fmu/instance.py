"""An FMU instance in the master's process: instantiation, its log, and FMI's call-sequence rules.

What the two in-process hosts share (`cosim.fmu.host.FmuComponent`,
co-simulation, and `cosim.fmu.model_exchange.ModelExchangeComponent`; the
isolated host runs either of them in its own process):

- `instantiate`: extract the FMU and instantiate it through fmpy with logging
  on, every message going to an `FmuLog` (kept for error reports; with a
  run.log, written there, warnings and errors also on the terminal);
- `FmuInstance`, their base: every FMI error becomes a `ComponentFailure`
  quoting the FMU's last logged problems; after a Fatal status no FMI
  function is called any more (not even freeInstance, which FMI forbids
  then), after an Error only freeInstance; a termination request becomes
  `StopRequested` with the outputs of the step that asked, which the master
  records before it ends the run normally.
"""

from __future__ import annotations

import ctypes
import os
import shutil
import sys
import tempfile
from collections import deque
from pathlib import Path
from typing import Any

import fmpy
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Model, FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
from fmpy.fmi3 import FMU3Model, FMU3Slave
from fmpy.logging import addLoggerProxy

from cosim.component import Value
from cosim.errors import ComponentFailure, StopRequested
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


class FmuInstance:
    """One FMU instance in this process, under FMI's call-sequence rules: the base of
    both in-process hosts (`cosim.fmu.host.FmuComponent`, co-simulation, and
    `cosim.fmu.model_exchange.ModelExchangeComponent`).

    A subclass sets `name`, `path` and `interface`, then calls this __init__.

    Args:
        log_file: run.log of the run, to append the FMU's messages to (and show
            its warnings and errors); None: kept only for error reports.
    """

    name: str
    path: Path
    interface: Any
    _model_exchange = False  # which interface of the FMU `_instantiate` instantiates
    use_shim = True  # the stepping shim's per-instance FMI 2 logger (and step) when it builds
    unzip_dir: str | None = None  # an empty folder to extract into (an isolated FMU's process
    # sets it: its parent was told the folder, to remove it if this process dies); None: a new one

    def __init__(self, log_file: str | Path | None) -> None:
        sink = open(log_file, "a", encoding="utf-8") if log_file is not None else None
        self.log = FmuLog(self.name, sink)
        self._fmu: Any = None
        self._callbacks: Any = None
        self._shim: Any = None  # the stepping shim library, None: fmpy's per-call path and proxy
        self._unzipped: str | None = None
        self._t_prev = 0.0
        self._tick = 0  # the last tick completed (0: after the start), named by a stop's failure
        self._initialized = False
        self._fatal = False  # after Fatal, FMI allows no call at all

    def _instantiate(self) -> None:
        self._shim = stepper.library() if self.use_shim else None
        self._unzipped, self._fmu, self._callbacks = instantiate(
            self.path, self.interface, self.name, self.log, self._model_exchange,
            logging_on=True, shim=self._shim, unzip_dir=self.unzip_dir)

    def _release(self) -> None:
        """Terminate (when initialized), free the instance, remove its files, close the log.

        After a Fatal status nothing is called: the instance and its library
        stay as they are until the process ends. A failure names the last tick
        completed and its time (the stop comes after it).
        """
        failure: ComponentFailure | None = None
        try:
            if self._fmu is not None and not self._fatal and self._initialized:
                try:
                    self._fmu.terminate()
                except Exception as exc:  # after Error still freeInstance, after Fatal nothing
                    failure = self._failure(self._tick, self._t_prev, exc, " in its stop after "
                                            f"tick {self._tick}")
                    failure.__cause__ = exc
            if self._fmu is not None and not self._fatal:
                self._fmu.freeInstance()
        except Exception as exc:
            raise failure or self._failure(self._tick, self._t_prev, exc, " in its stop after "
                                           f"tick {self._tick}") from exc
        finally:
            if self._fatal and self._fmu is not None:
                _keep_alive.append((self._fmu, self._callbacks))
            self._fmu = None
            self._initialized = False
            self.log.close()
            if self._unzipped:
                shutil.rmtree(self._unzipped, ignore_errors=True)
                self._unzipped = None
        if failure is not None:
            raise failure

    def _failure(self, tick: int | None, t: float, exc: Exception,
                 where: str = "") -> ComponentFailure:
        """The ComponentFailure for an FMI error, quoting the FMU's log; after it only
        freeInstance is called (nothing at all after Fatal). `where`: words after the
        failed call (" in its stop after tick 100")."""
        self._initialized = False
        status = getattr(exc, "status", None)
        if status == FATAL:
            self._fatal = True
        details = ({"kind": "fmi_status", "status": _STATUS.get(status, status)} if status
                   else dict(getattr(exc, "details", {}))  # a solver's finding, if it says one
                   or {"kind": "fmu_error", "exception": type(exc).__name__})
        return ComponentFailure(self.name, tick, t, f"{_call_text(exc, where)} (FMU "
                                f"{self.path.name}: {self.log.text()})", details)

    def _stop_request(self, tick: int, t: float, outputs: dict[str, Value],
                      where: str = "") -> StopRequested:
        """The FMU asked to terminate the simulation in the step of `tick`: end the run
        normally once that tick, with these outputs, is recorded."""
        return StopRequested(self.name, tick, t, outputs, f"the FMU asked to terminate the "
                             f"simulation{where} ({self.log.text()})")


_keep_alive: list[Any] = []  # FMU instances (and their callbacks) after a Fatal status


def _call_text(exc: Exception, where: str = "") -> str:
    """What failed (fmpy's words, except that it calls Pending, status 5, an "illegal return
    code"), then `where` before the final period."""
    if isinstance(exc, FMICallException) and exc.status == 5:
        text = (f"{exc.function} failed with status 5 (pending: this host does not run "
                f"asynchronous steps).")
    else:
        text = str(exc)
    if not where:
        return text
    return f"{text[:-1]}{where}." if text.endswith(".") else f"{text}{where}"


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
                logging_on: bool, shim: Any = None,
                unzip_dir: str | None = None) -> tuple[str, Any, Any]:
    """Extract an FMU and instantiate it through fmpy, its messages going to `log`.

    Args:
        path: the .fmu file.
        interface: its FmuInterface (model description, FMI version).
        name: the instance name (the component's).
        log: the FmuLog that receives the FMU's messages.
        model_exchange: instantiate the Model Exchange interface (else co-simulation).
        logging_on: ask the FMU to log its debug categories too.
        shim: the stepping shim library, whose FMI 2 logger is per instance; None: fmpy's proxy.
        unzip_dir: an empty folder to extract into; None: a new temporary folder.
    Returns:
        (extraction folder, the fmpy FMU object, the FMI 2 callbacks to keep alive or None).
        When anything fails (the archive, loading the library, a missing function,
        instantiate returning NULL), the folder is removed before the exception goes on.
    """
    unzipped = unzip_dir if unzip_dir is not None else tempfile.mkdtemp()
    working_dir = os.getcwd()
    try:
        return _instantiate_in(unzipped, path, interface, name, log, model_exchange,
                               logging_on, shim)
    except BaseException:
        # fmpy changes into the library's folder to load it and stays there when the load
        # fails: this process would go on in the folder removed below
        os.chdir(working_dir)
        shutil.rmtree(unzipped, ignore_errors=True)
        raise


def _instantiate_in(unzipped: str, path: Path, interface: Any, name: str, log: Any,
                    model_exchange: bool, logging_on: bool, shim: Any) -> tuple[str, Any, Any]:
    """`instantiate` into the folder `unzipped`."""
    md = interface.model_description
    unzipped = str(fmpy.extract(str(path), unzipdir=unzipped))
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
