"""Probes of the test FMUs of tests/fmus/ through fmpy, for tests/fmu/.

`Instance` is one fmpy instance (FMI 2.0 or 3.0, CS or ME) whose log messages
are captured as (status, category, message) tuples; `run_isolated` runs
fmpy.simulate_fmu in a child process for FMUs that crash or hang and streams
back each completed communication point, the log and the result, so what
happened before a crash is kept. The fixtures that use them are in
tests/fmu/conftest.py.
"""
from __future__ import annotations

import ctypes
import json
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import fmpy
from fmpy.fmi2 import (FMU2Model, FMU2Slave, fmi2CallbackAllocateMemoryTYPE,
                       fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
from fmpy.fmi3 import FMU3Model, FMU3Slave


class InstantiationFailed(Exception):
    """fmpy could not instantiate; `messages` holds what the FMU logged meanwhile."""

    def __init__(self, text: str, messages: list):
        super().__init__(f"{text}: {messages}")
        self.messages = messages


class Instance:
    """One fmpy instance of a test FMU with its log captured.

    Attributes:
        fmu: the fmpy FMU2Slave/FMU2Model/FMU3Slave/FMU3Model.
        md: the model description; vr: name -> value reference;
        messages: (status, category, message) of every logged message.
    """

    _count = 0

    def __init__(self, path: Path, interface: str, unzip_root: Path, logging_on: bool,
                 unzip: str | None = None):
        self.md = fmpy.read_model_description(str(path))
        self.version = int(self.md.fmiVersion[0])
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.types = {v.name: v.type for v in self.md.modelVariables}
        self.messages: list[tuple[int, str, str]] = []
        self.freed = False
        if unzip is None:  # a folder per instance: extracting over a loaded binary corrupts it
            Instance._count += 1
            unzip = fmpy.extract(str(path), unzipdir=str(
                unzip_root / f"{path.stem}-{interface}-{Instance._count}"))
        self.unzip = unzip
        desc = self.md.coSimulation if interface == "CoSimulation" else self.md.modelExchange
        desc = desc or self.md.modelExchange or self.md.coSimulation  # to try the missing one
        args = dict(guid=self.md.guid, unzipDirectory=unzip, instanceName="test",
                    modelIdentifier=desc.modelIdentifier)
        try:
            if self.version == 2:
                cls = FMU2Slave if interface == "CoSimulation" else FMU2Model
                self.fmu = cls(**args)
                self._callbacks = self._fmi2_callbacks()
                self.fmu.instantiate(callbacks=self._callbacks, loggingOn=logging_on)
            else:
                cls = FMU3Slave if interface == "CoSimulation" else FMU3Model
                self.fmu = cls(**args)
                self.fmu.instantiate(logMessage=self._log3, loggingOn=logging_on)
        except Exception as exc:
            raise InstantiationFailed(str(exc), self.messages) from exc

    def _fmi2_callbacks(self):
        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(
            lambda env, name, status, cat, msg: self.messages.append(
                (status, cat.decode(), msg.decode())))
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
        from fmpy.logging import addLoggerProxy
        addLoggerProxy(ctypes.byref(cb))
        return cb

    def _log3(self, env, status, category, message):
        self.messages.append((status, category.decode(), message.decode()))

    def texts(self) -> list[str]:
        return [m for _, _, m in self.messages]

    def set(self, values: dict) -> None:
        """Set variables by name with the function of their type (setInteger, setInt16, ...)."""
        for name, value in values.items():
            getattr(self.fmu, "set" + self.types[name])([self.vr[name]], [value])

    def get(self, name: str):
        """Get a variable by name with the function of its type."""
        return getattr(self.fmu, "get" + self.types[name])([self.vr[name]])[0]

    def init(self, values: dict | None = None, t0: float = 0.0) -> None:
        self.set(values or {})
        if self.version == 2:
            self.fmu.setupExperiment(startTime=t0)
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=t0)
        self.fmu.exitInitializationMode()

    def free(self) -> None:
        if not self.freed:
            self.freed = True
            self.fmu.freeInstance()


# The child: simulate_fmu with a logger and a step callback, one JSON object per
# line on stdout (flushed), so the lines written before a crash survive it.
_CHILD = r"""
import json, sys
import fmpy
from fmpy.fmi1 import FMICallException

args = json.loads(sys.argv[1])

def emit(**kw):
    sys.stdout.write(json.dumps(kw) + "\n")
    sys.stdout.flush()

def log2(env, name, status, category, message):
    emit(log=[status, category.decode(), message.decode()])

def log3(env, status, category, message):
    emit(log=[status, category.decode(), message.decode()])

version = fmpy.read_model_description(args["fmu"]).fmiVersion
try:
    res = fmpy.simulate_fmu(args["fmu"], stop_time=args["stop_time"],
                            output_interval=args["output_interval"],
                            start_values=args["start_values"],
                            logger=log2 if version == "2.0" else log3,
                            step_finished=lambda t, recorder: emit(t=t) or True)
    emit(result={name: [v.item() for v in res[name]] for name in res.dtype.names})
except FMICallException as e:
    emit(exception=str(e), status=e.status)
"""


@dataclass
class IsolatedRun:
    """What a child simulation did: returncode None means it was killed after the timeout."""
    returncode: int | None
    times: list[float] = field(default_factory=list)
    messages: list[tuple[int, str, str]] = field(default_factory=list)
    result: dict | None = None
    exception: str | None = None
    status: int | None = None
    stderr: str = ""


def run_isolated(fmu: Path, start_values: dict, stop_time: float = 1.0,
        output_interval: float = 0.1, timeout: float = 60.0) -> IsolatedRun:
    args = json.dumps({"fmu": str(fmu), "start_values": start_values,
                       "stop_time": stop_time, "output_interval": output_interval})
    proc = subprocess.Popen([sys.executable, "-c", _CHILD, args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        out, err = proc.communicate(timeout=timeout)
        code = proc.returncode
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        code = None
    run_ = IsolatedRun(returncode=code, stderr=err)
    for line in out.splitlines():
        item = json.loads(line)
        if "t" in item:
            run_.times.append(item["t"])
        elif "log" in item:
            run_.messages.append(tuple(item["log"]))
        elif "result" in item:
            run_.result = item["result"]
        elif "exception" in item:
            run_.exception, run_.status = item["exception"], item["status"]
    return run_
