"""Python binding of the FMU stepping shim (fmus/stepper): one C call per co-simulation step.

The platform steps an in-process FMU with three ctypes calls per tick (set
inputs, doStep, get outputs; see `cosim.fmu.host.FmuComponent.step`).
The shim makes the same three FMI calls, in the same order with the same
arguments, from C, so Python pays for one foreign call instead of three.
It drives an FMU that fmpy has loaded and instantiated: it is given the
addresses of the FMU's own FMI functions (from fmpy's loaded library) and
the instance, and keeps every call's status so a failure is reported as
today ("fmi2DoStep failed with status 3", FMI 3's terminateSimulation).

Standalone for now (it will move next to the FMU hosts, cosim/fmu/, once the
layout refactor has landed):

- `compile_stepper(cache_dir)`: gcc with the project's strict flags into a
  cache folder keyed by a hash of the sources, the FMI headers, the flags and
  the compiler; returns the .so (built once, atomically, safe to race);
- `Stepper(fmu, in_vrs, out_vrs)`: the shim bound to one fmpy FMU2Slave /
  FMU3Slave instance; `in_values` / `out_values` are its ctypes arrays,
  `step(t, h)` one step (returns the COSIM_STEP_* code), `check(...)` raises
  FMICallException naming the call that failed and its status;
- `ShimFmuComponent`: `FmuComponent` whose step goes through the shim, for the
  benchmarks (same constructor, same outputs bit for bit, same errors).
"""

from __future__ import annotations

import ctypes
import hashlib
import operator
import os
import shutil
import subprocess
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

REPO_DIR = Path(__file__).resolve().parent.parent
SOURCE_DIR = REPO_DIR / "fmus" / "stepper"
SOURCES = ("cosim_stepper.c", "cosim_stepper.h")
CFLAGS = ("-std=c99", "-O2", "-fPIC", "-fvisibility=hidden", "-Wall", "-Wextra", "-Wpedantic", "-Werror")
LIBRARY = "libcosim_stepper.so"
ABI = 2                       # COSIM_STEPPER_ABI in cosim_stepper.h

STEP_DONE, STEP_SET, STEP_DO_STEP, STEP_GET, STEP_TERMINATE = range(5)
CALL_NAMES = {2: ("fmi2SetReal", "fmi2DoStep", "fmi2GetReal"),
              3: ("fmi3SetFloat64", "fmi3DoStep", "fmi3GetFloat64")}


class StepperBuildError(RuntimeError):
    """The shim could not be compiled or loaded (the message has gcc's output)."""


class CosimStepper(ctypes.Structure):
    """Mirror of struct CosimStepper (cosim_stepper.h); checked against the library's sizeof."""

    _fields_ = [("fmi_version", ctypes.c_int), ("instance", ctypes.c_void_p),
                ("fmi2_set_real", ctypes.c_void_p), ("fmi2_do_step", ctypes.c_void_p),
                ("fmi2_get_real", ctypes.c_void_p), ("fmi3_set_float64", ctypes.c_void_p),
                ("fmi3_do_step", ctypes.c_void_p), ("fmi3_get_float64", ctypes.c_void_p),
                ("n_in", ctypes.c_size_t), ("in_vr", ctypes.c_void_p), ("in_values", ctypes.c_void_p),
                ("n_out", ctypes.c_size_t), ("out_vr", ctypes.c_void_p), ("out_values", ctypes.c_void_p),
                ("status", ctypes.c_int * 3), ("stopped_by", ctypes.c_int),
                ("event_handling_needed", ctypes.c_int), ("terminate_simulation", ctypes.c_int),
                ("early_return", ctypes.c_int), ("last_successful_time", ctypes.c_double)]


def fmi_include_dir() -> Path:
    """The FMI 2.0 / 3.0 headers shipped with the installed fmpy (as the FMU build uses)."""
    import fmpy
    return Path(fmpy.__file__).resolve().parent / "c-code"


def default_cache_dir() -> Path:
    """$COSIM_CACHE_DIR, else $XDG_CACHE_HOME/cosim, else ~/.cache/cosim; plus /stepper."""
    base = os.environ.get("COSIM_CACHE_DIR") or os.environ.get("XDG_CACHE_HOME")
    root = Path(base) if base else Path.home() / ".cache"
    return (root if os.environ.get("COSIM_CACHE_DIR") else root / "cosim") / "stepper"


def source_key(gcc: str) -> str:
    """Hash of what the library depends on: sources, FMI headers, flags, compiler version."""
    digest = hashlib.sha256()
    for name in SOURCES:
        digest.update(name.encode() + b"\0" + (SOURCE_DIR / name).read_bytes() + b"\0")
    for header in ("fmi2FunctionTypes.h", "fmi2TypesPlatform.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h"):
        digest.update((fmi_include_dir() / header).read_bytes())
    digest.update("\0".join(CFLAGS).encode())
    version = subprocess.run([gcc, "--version"], capture_output=True, text=True).stdout
    digest.update(version.encode())
    return digest.hexdigest()[:16]


def compile_stepper(cache_dir: Path | None = None) -> Path:
    """The shim's shared library, compiled on first use into `cache_dir`/<source hash>/.

    Args:
        cache_dir: where compiled libraries are kept (default: default_cache_dir()).
    Returns:
        Path of the .so (compiled now, or found from an earlier identical build).
    Raises:
        StepperBuildError: gcc missing or failing (its message included).
    """
    gcc = shutil.which("gcc")
    if gcc is None:
        raise StepperBuildError("compiling the FMU stepping shim: gcc not found on PATH")
    folder = (cache_dir or default_cache_dir()) / source_key(gcc)
    library = folder / LIBRARY
    if library.is_file():
        return library
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder, prefix=".build-") as tmp:   # same filesystem: atomic rename
        built = Path(tmp) / LIBRARY
        proc = subprocess.run([gcc, *CFLAGS, "-shared", f"-I{SOURCE_DIR}", f"-I{fmi_include_dir()}",
                               str(SOURCE_DIR / "cosim_stepper.c"), "-o", str(built)],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            raise StepperBuildError(f"compiling the FMU stepping shim failed:\n{proc.stderr.strip()}")
        os.replace(built, library)
    return library


_LOADED: dict[Path, ctypes.CDLL] = {}


def load_stepper(cache_dir: Path | None = None) -> ctypes.CDLL:
    """The shim library loaded (compiled if needed), with its prototypes; checks ABI and struct size."""
    path = compile_stepper(cache_dir)
    lib = _LOADED.get(path)
    if lib is None:
        lib = ctypes.CDLL(str(path))
        lib.cosim_stepper_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double]
        lib.cosim_stepper_step.restype = ctypes.c_int
        lib.cosim_stepper_abi.restype = ctypes.c_int
        lib.cosim_stepper_size.restype = ctypes.c_size_t
        lib.cosim_stepper_fmi2_logger.restype = None
        if lib.cosim_stepper_abi() != ABI or lib.cosim_stepper_size() != ctypes.sizeof(CosimStepper):
            raise StepperBuildError(f"{path}: ABI {lib.cosim_stepper_abi()} / struct size "
                                    f"{lib.cosim_stepper_size()}, the binding expects ABI {ABI} / "
                                    f"{ctypes.sizeof(CosimStepper)}")
        _LOADED[path] = lib
    return lib


def function_address(fmu: Any, name: str) -> int:
    """Address of FMI function `name` in the library fmpy loaded for `fmu` (FMU2Slave / FMU3Slave)."""
    function = getattr(fmu, "_functions", {}).get(name) or getattr(fmu.dll, name)
    address = ctypes.cast(function, ctypes.c_void_p).value
    if not address:
        raise StepperBuildError(f"{name}: no address in the FMU's library")
    return address


class Stepper:
    """The shim bound to one instantiated fmpy FMU.

    Args:
        fmu: an fmpy FMU2Slave or FMU3Slave, instantiated (its `component` set).
        in_vrs: value references of the Float64 / Real inputs set before every step.
        out_vrs: value references of the outputs read after every step.
        in_values, out_values: ctypes double arrays to use (e.g. the host's own), else new ones;
            in_vrs / out_vrs may be ctypes c_uint arrays too (used as they are).
        cache_dir: where the compiled shim is kept (compile_stepper).
    Attributes:
        in_values: ctypes double array the step sends (write it before `step`).
        out_values: ctypes double array the step fills.
        names: FMI names of the set, doStep and get calls (for messages).
    """

    def __init__(self, fmu: Any, in_vrs: Sequence[int], out_vrs: Sequence[int], *,
                 in_values: Any = None, out_values: Any = None, cache_dir: Path | None = None) -> None:
        self.version = 3 if type(fmu).__name__.startswith("FMU3") else 2
        self.names = CALL_NAMES[self.version]
        self.in_vr = _array(ctypes.c_uint, in_vrs)
        self.out_vr = _array(ctypes.c_uint, out_vrs)
        self.in_values = _array(ctypes.c_double, in_values, len(self.in_vr))
        self.out_values = _array(ctypes.c_double, out_values, len(self.out_vr))
        s = self.struct = CosimStepper()
        s.fmi_version, s.instance = self.version, fmu.component
        addresses = [function_address(fmu, name) for name in self.names]
        if self.version == 2:
            s.fmi2_set_real, s.fmi2_do_step, s.fmi2_get_real = addresses
        else:
            s.fmi3_set_float64, s.fmi3_do_step, s.fmi3_get_float64 = addresses
        s.n_in, s.in_vr, s.in_values = len(self.in_vr), _address(self.in_vr), _address(self.in_values)
        s.n_out, s.out_vr, s.out_values = len(self.out_vr), _address(self.out_vr), _address(self.out_values)
        self.library = load_stepper(cache_dir)
        self.address = ctypes.addressof(s)
        self.fmu = fmu                  # keeps the library and instance alive as long as the stepper
        self._call = self.library.cosim_stepper_step

    def step(self, t: float, h: float) -> int:
        """One step from t over h with `in_values`; returns the COSIM_STEP_* code (0: done)."""
        return self._call(self.address, t, h)

    def failure(self, code: int) -> tuple[str, int] | None:
        """(FMI call name, status) of the call that stopped the step, None if code is not a call failure."""
        if code in (STEP_SET, STEP_DO_STEP, STEP_GET):
            return self.names[code - 1], self.struct.status[code - 1]
        return None

    def check(self, code: int) -> None:
        """Raise fmpy's FMICallException for a failed call, as the platform's per-call path does."""
        failure = self.failure(code)
        if failure is not None:
            from fmpy.fmi1 import FMICallException
            raise FMICallException(*failure)


LOG_SINK = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p)


class CosimFmi2Log(ctypes.Structure):
    """Mirror of struct CosimFmi2Log: where cosim_stepper_fmi2_logger sends one instance's messages."""

    _fields_ = [("sink", ctypes.c_void_p), ("context", ctypes.c_void_p)]


def fmi2_callbacks(add: Any, cache_dir: Path | None = None) -> Any:
    """FMI 2 callbacks whose logger sends this instance's messages, formatted, to `add` only.

    fmpy's addLoggerProxy keeps one callback for the whole process (the last
    instance set up receives every FMI 2 instance's messages); the shim's
    logger formats the variadic message in C and routes it by the instance's
    componentEnvironment. Keep the returned object alive as long as the instance.

    Args:
        add: called as add(status, category bytes, message bytes) (e.g. FmuLog.add).
        cache_dir: where the compiled shim is kept (compile_stepper).
    """
    import fmpy
    from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                           fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

    lib = load_stepper(cache_dir)
    callbacks = fmi2CallbackFunctions()
    callbacks._sink = LOG_SINK(lambda _context, status, category, message: add(status, category, message))
    callbacks._route = CosimFmi2Log(ctypes.cast(callbacks._sink, ctypes.c_void_p).value, None)
    callbacks.logger = ctypes.cast(lib.cosim_stepper_fmi2_logger, fmi2CallbackLoggerTYPE)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
    callbacks.componentEnvironment = ctypes.addressof(callbacks._route)
    return callbacks


def _array(ctype: Any, values: Any, size: int | None = None) -> Any:
    """`values` if it is already a ctypes array of `ctype`, else a new one (from values, or `size` zeros)."""
    if isinstance(values, ctypes.Array) and values._type_ is ctype:
        return values
    if values is None:
        return (ctype * int(size or 0))()
    values = list(values)
    return (ctype * len(values))(*values)


def _address(array: Any) -> int | None:
    """Address of a ctypes array's data (None, i.e. NULL, for an empty one)."""
    return ctypes.addressof(array) if len(array) else None


def _shim_component_class():
    """ShimFmuComponent, built lazily so this module imports without the platform on sys.path."""
    from cosim.errors import ComponentFailure
    from cosim.fmu.host import FmuComponent

    class ShimFmuComponent(FmuComponent):
        """FmuComponent whose per-tick step is one shim call (same values, same errors).

        start() and stop() keep FmuComponent's per-call path; the shim uses the
        component's own value-reference and value arrays. An FMI 2 instance logs
        through the shim's per-instance logger (fmi2_callbacks), so its failures
        carry its own messages even with other FMI 2 instances in the process.
        """

        def _instantiate(self) -> None:
            if self.fmi3:
                super()._instantiate()
                return
            import fmpy
            from fmpy.fmi2 import FMU2Slave
            md = self.interface.model_description
            self._unzipped = fmpy.extract(str(self.path))
            self._fmu = FMU2Slave(guid=md.guid, unzipDirectory=self._unzipped,
                                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName=self.name)
            self._callbacks = fmi2_callbacks(self.log.add)
            self._fmu.instantiate(callbacks=self._callbacks, loggingOn=False)

        def _bind(self) -> None:
            super()._bind()
            self._stepper = Stepper(self._fmu, self._in_vr, self._out_vr,
                                    in_values=self._in_val, out_values=self._out_val)
            self._shim_step, self._shim_address = self._stepper._call, self._stepper.address
            # the inputs in value-reference order: one C-level call instead of a comprehension
            names = self._in_names
            self._pick_inputs = (operator.itemgetter(*names) if len(names) > 1
                                 else (lambda inputs: [inputs[names[0]]]))

        def step(self, tick: int, t: float, inputs: Mapping[str, Any]) -> dict[str, Any]:
            """FmuComponent.step in one C call: same inputs, same doStep(t_prev, t - t_prev), same outputs."""
            try:
                if self._in_names:
                    self._in_val[:] = self._pick_inputs(inputs)
                code = self._shim_step(self._shim_address, self._t_prev, t - self._t_prev)
                if code:
                    if code == STEP_TERMINATE:
                        raise ComponentFailure(self.name, tick, t, "the FMU asked to terminate "
                                               f"the simulation: {self.log.text()}")
                    self._stepper.check(code)
                self._t_prev = t
                return dict(zip(self._out_names, self._out_val[:]))
            except ComponentFailure:
                raise
            except Exception as exc:
                raise self._failure(tick, t, exc) from exc

    return ShimFmuComponent


def shim_fmu_component(*args: Any, **kwargs: Any):
    """A ShimFmuComponent (FmuComponent's arguments)."""
    return _shim_component_class()(*args, **kwargs)
