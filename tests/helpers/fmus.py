"""Shared helpers for the FMU tests: build the built-in FMUs once per session
into a temporary folder and drive them through fmpy with a captured log.

`Plant` hides the FMI 2.0 / 3.0 call differences so a test can run the same
sequence on both and compare the trajectories bit for bit.
"""
from __future__ import annotations

import ctypes
from pathlib import Path

import fmpy
import numpy as np
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
from fmpy.fmi3 import FMU3Slave

from cosim.fmu import build as fmu_build
from tests.helpers.paths import TEST_FMUS_DIR

_CACHE: dict[tuple[str, int], tuple[Path, str]] = {}


def built_fmu(out_dir: Path, model: str, version: int) -> tuple[Path, str]:
    """Build (once per session) and extract a model; return (fmu path, unzip dir).

    The cache is per (model, version) for the whole session: a later call with
    another `out_dir` gets the FMU built first.

    Args:
        out_dir: folder for the .fmu files.
        model: model folder name under fmus/.
        version: 2 or 3.
    """
    key = (model, version)
    if key not in _CACHE:
        path = fmu_build.build_fmu(model, version, out_dir)
        unzip = fmpy.extract(str(path), unzipdir=str(out_dir / f"{path.stem}-unzipped"))
        _CACHE[key] = (path, unzip)
    return _CACHE[key]


class Plant:
    """One instance of an FMU (FMI 2.0 or 3.0), with captured log messages.

    Args:
        path: the .fmu file.
        unzip_dir: where it was extracted.
        logging_on: FMI loggingOn (debug messages).
    """

    def __init__(self, path: Path, unzip_dir: str, logging_on: bool = False):
        self.md = fmpy.read_model_description(str(path))
        self.version = int(self.md.fmiVersion[0])
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.outputs = [v.name for v in self.md.modelVariables if v.causality == "output"]
        self.messages: list[str] = []
        args = dict(guid=self.md.guid, unzipDirectory=unzip_dir, instanceName="test",
                    modelIdentifier=self.md.coSimulation.modelIdentifier)
        if self.version == 2:
            self.fmu = FMU2Slave(**args)
            self._callbacks = self._fmi2_callbacks()
            self.fmu.instantiate(callbacks=self._callbacks, loggingOn=logging_on)
        else:
            self.fmu = FMU3Slave(**args)
            self.fmu.instantiate(logMessage=self._log3, loggingOn=logging_on)
        self.t = 0.0

    def _fmi2_callbacks(self):
        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(
            lambda env, name, status, cat, msg: self.messages.append(msg.decode()))
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
        from fmpy.logging import addLoggerProxy
        addLoggerProxy(ctypes.byref(cb))
        return cb

    def _log3(self, env, status, category, message):
        self.messages.append(message.decode())

    def set(self, values: dict[str, float]) -> None:
        vrs = [self.vr[k] for k in values]
        vals = [float(v) for v in values.values()]
        if self.version == 2:
            self.fmu.setReal(vrs, vals)
        else:
            self.fmu.setFloat64(vrs, vals)

    def get(self, names: list[str]) -> list[float]:
        vrs = [self.vr[k] for k in names]
        return self.fmu.getReal(vrs) if self.version == 2 else self.fmu.getFloat64(vrs)

    def init(self, params: dict[str, float] | None = None, t0: float = 0.0) -> None:
        self.set(params or {})
        if self.version == 2:
            self.fmu.setupExperiment(startTime=t0)
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=t0)
        self.fmu.exitInitializationMode()
        self.t = t0

    def do_step(self, t: float, h: float) -> None:
        self.fmu.doStep(t, h)

    def get_state(self):
        return self.fmu.getFMUState()

    def set_state(self, state) -> None:
        self.fmu.setFMUState(state)

    def serialize(self, state) -> bytes:
        return (self.fmu.serializeFMUstate(state) if self.version == 2
                else self.fmu.serializeFMUState(state))

    def deserialize(self, data: bytes):
        return (self.fmu.deSerializeFMUstate(data) if self.version == 2
                else self.fmu.deserializeFMUState(data))

    def run(self, inputs, n_steps: int, h: float = 0.01, k0: int = 0) -> np.ndarray:
        """Step n_steps from tick k0 (t = k h); return outputs, one row per tick.

        Args:
            inputs: dict of constant inputs, or a function k -> dict.
            n_steps: steps to take; h: step size, s; k0: first tick.
        Returns:
            array (n_steps + 1, len(outputs)); row 0 is before the first step.
        """
        rows = [self.get(self.outputs)]
        for k in range(k0, k0 + n_steps):
            self.set(inputs(k) if callable(inputs) else inputs)
            self.do_step(k * h, h)
            rows.append(self.get(self.outputs))
        return np.array(rows)

    def column(self, data: np.ndarray, name: str) -> np.ndarray:
        return data[:, self.outputs.index(name)]

    def free(self) -> None:
        try:
            self.fmu.terminate()
        except Exception:
            pass
        self.fmu.freeInstance()


def parse_variables_def(path: Path) -> list[dict]:
    """Read a variables.def with a regex, independently of the C compiler."""
    import re

    text = re.sub(r"/\*.*?\*/", "", path.read_text(), flags=re.S)
    pattern = re.compile(r'VAR\(\s*(\w+)\s*,\s*(\w+)\s*,\s*(\w+)\s*,\s*"([^"]*)"\s*,'
                         r'\s*([^,]+?)\s*,\s*([^,]+?)\s*,\s*([^,]+?)\s*,\s*"([^"]*)"\s*\)')
    def num(s: str) -> float:
        return float(s.replace("INFINITY", "inf").replace(" ", ""))
    rows = []
    for m in pattern.finditer(text):
        name, caus, var, unit, start, lo, hi, desc = m.groups()
        rows.append(dict(name=name, causality=caus.lower(), variability=var.lower(),
                         unit=unit, start=num(start), min=num(lo), max=num(hi),
                         description=desc))
    assert rows, f"no VAR(...) lines parsed in {path}"
    assert len(rows) == text.count("VAR("), f"some VAR lines of {path} did not parse"
    return rows


def build_lag(out_dir: Path) -> dict[int, Path]:
    """Build tests/fmus/Lag as FMI 2.0 and 3.0 FMUs with the project's FMU framework."""
    return {v: fmu_build.build_fmu_from(TEST_FMUS_DIR / "Lag", v, out_dir) for v in (2, 3)}


class FaultyFmus(dict):
    """tests/fmus/Faulty and FaultyOnce, each built on first use: [(model, version)] -> path.

    Args:
        out_dir: folder for the .fmu files.
    """

    def __init__(self, out_dir: Path) -> None:
        super().__init__()
        self.out_dir = out_dir

    def __missing__(self, key: tuple[str, int]) -> Path:
        model, version = key
        path = self[key] = fmu_build.build_fmu_from(TEST_FMUS_DIR / model, version, self.out_dir)
        return path


LAG_SCENARIO = """\
name: lag_loop
duration: 1.0
tick: 0.01
components:
  plant:
    fmu: {fmu}
    variables: {{u: u_cmd, y: y_out}}
    parameters: {{tau: 0.4, gain: 1.5}}
    uncertainty: {{tau: {{scale: 0.5}}}}
  controller:
    python: tests.helpers.components:PController
    parameters: {{kp: 3.0}}
    period: 0.02
sources:
  ref:
    kind: step
    initial: 0.0
    final: 1.0
    at: 0.1
connections:
  - plant -> controller
  - {{from: ref.value, to: controller.ref}}
  - controller.u -> plant.u
"""


def build_handwritten_fmu(model_dir: Path, out_dir: Path) -> Path:
    """Build an FMI 3 test FMU written without the framework (e.g. tests/fmus/Arrays):
    its *.c compiled against fmpy's FMI headers, zipped with its modelDescription.xml.

    Args:
        model_dir: the folder (C files and modelDescription.xml); its name is the
            model identifier.
        out_dir: where `<name>-fmi3.fmu` goes.
    """
    import subprocess
    import tempfile
    import zipfile

    name = model_dir.name
    headers = Path(fmpy.__file__).parent / "c-code"
    target = out_dir / f"{name}-fmi3.fmu"
    with tempfile.TemporaryDirectory() as work:
        library = Path(work) / f"{name}.so"
        subprocess.run(["gcc", "-std=c99", "-O2", "-fPIC", "-shared", "-Wall", "-Werror",
                        f"-I{headers}", *map(str, sorted(model_dir.glob("*.c"))), "-lm",
                        "-o", str(library)], check=True, capture_output=True)
        with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.write(model_dir / "modelDescription.xml", "modelDescription.xml")
            archive.write(library, f"binaries/{fmpy.platform_tuple}/{name}.so")
    return target
