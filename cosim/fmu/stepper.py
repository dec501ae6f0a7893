"""The FMU stepping shim (fmus/stepper): one C call per co-simulation step, and an FMI 2 logger.

Stepping an FMU from Python through ctypes costs one foreign call each for
set inputs, doStep and get outputs. The shim makes the same three FMI calls,
in the same order with the same arguments, from C, so the host pays for one
call; the results are bit-identical. It drives an FMU fmpy has loaded and
instantiated: it is given the addresses of the FMU's own FMI functions and
the instance, and keeps every call's status so a failure is reported as
after the host's own call ("fmi2DoStep failed with status 3").

The library is compiled with the FMUs' strict flags (`cosim.fmu.build.CFLAGS`)
on first use into the per-user cache (`cosim.fmu.cache`), under a key hashing
its sources, the FMI headers, the flags, the compiler and the machine; the
build is atomic, so concurrent processes may race safely. `library()` returns
None when it cannot be built (no gcc, a failed build): the host then keeps
fmpy's per-call path.

Public API: `library`, `Stepper` (the shim bound to one instance),
`fmi2_callbacks` (FMI 2 callbacks whose logger routes each instance's
messages to its own log), the `STEP_*` codes.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import platform
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from cosim.fmu import build, cache

SOURCES = ("cosim_stepper.c", "cosim_stepper.h")
LIBRARY = "libcosim_stepper.so"
ABI = 3  # COSIM_STEPPER_ABI in cosim_stepper.h

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
                ("t", ctypes.c_double), ("h", ctypes.c_double),
                ("status", ctypes.c_int * 3), ("stopped_by", ctypes.c_int),
                ("event_handling_needed", ctypes.c_int), ("terminate_simulation", ctypes.c_int),
                ("early_return", ctypes.c_int), ("last_successful_time", ctypes.c_double)]


def source_dir() -> Path:
    """The shim's C sources: fmus/stepper (the checkout's, or the copy a wheel carries)."""
    return build.FMUS_DIR / "stepper"


def source_key() -> str:
    """Hash of what the library depends on: sources, FMI headers, flags, compiler, machine."""
    digest = hashlib.sha256()
    for name in SOURCES:
        digest.update(name.encode() + b"\0" + (source_dir() / name).read_bytes() + b"\0")
    for header in sorted(build.fmi_include_dir().glob("fmi*.h")):
        digest.update(header.name.encode() + b"\0" + header.read_bytes())
    for part in (*build.CFLAGS, cache.compiler_identity(), platform.machine()):
        digest.update(f"{part}\0".encode())
    return digest.hexdigest()[:cache.KEY_CHARS]


def compile_stepper(cache_dir: Path | None = None) -> Path:
    """The shim's shared library, compiled on first use into `cache_dir`/<source key>/.

    Args:
        cache_dir: where compiled shims are kept (default: <cosim cache>/stepper).
    Returns:
        Path of the .so (compiled now, or found from an earlier identical build).
    Raises:
        StepperBuildError: gcc missing or failing (its message included), or no sources.
    """
    gcc = shutil.which("gcc")
    if gcc is None:
        raise StepperBuildError("compiling the FMU stepping shim: gcc not found on PATH")
    if not (source_dir() / SOURCES[0]).is_file():
        raise StepperBuildError(f"the FMU stepping shim's sources are missing in {source_dir()}")
    folder = (cache_dir or cache.cache_root() / "stepper") / source_key()
    target = folder / LIBRARY
    if target.is_file():
        return target
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder, prefix=".build-") as tmp:  # same filesystem: atomic
        built = Path(tmp) / LIBRARY
        proc = subprocess.run([gcc, *build.CFLAGS, "-shared", f"-I{source_dir()}",
                               f"-I{build.fmi_include_dir()}", str(source_dir() / SOURCES[0]),
                               "-o", str(built)], capture_output=True, text=True)
        if proc.returncode != 0:
            raise StepperBuildError(f"compiling the FMU stepping shim failed:\n{proc.stderr.strip()}")
        os.replace(built, target)
    return target


def load_stepper(cache_dir: Path | None = None) -> ctypes.CDLL:
    """The shim library loaded (compiled if needed), with its prototypes; checks ABI and struct size."""
    return _load(compile_stepper(cache_dir))


@functools.lru_cache(maxsize=None)
def _load(path: Path) -> ctypes.CDLL:
    lib = ctypes.CDLL(str(path))
    lib.cosim_stepper_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double]
    lib.cosim_stepper_step.restype = ctypes.c_int
    lib.cosim_stepper_step_at.argtypes = [ctypes.c_void_p]
    lib.cosim_stepper_step_at.restype = ctypes.c_int
    lib.cosim_stepper_abi.restype = ctypes.c_int
    lib.cosim_stepper_size.restype = ctypes.c_size_t
    lib.cosim_stepper_time_offset.restype = ctypes.c_size_t
    lib.cosim_stepper_fmi2_logger.restype = None
    found = (lib.cosim_stepper_abi(), lib.cosim_stepper_size(), lib.cosim_stepper_time_offset())
    expected = (ABI, ctypes.sizeof(CosimStepper), CosimStepper.t.offset)
    if found != expected:
        raise StepperBuildError(f"{path}: ABI / struct size / offset of t {found}, the binding "
                                f"expects {expected}")
    return lib


def library() -> ctypes.CDLL | None:
    """The shim for this process's cache, or None when it cannot be built (the host then uses fmpy).

    Looked up once per cache folder and compiler (hashing the sources and headers takes
    milliseconds: not once per FMU instance).
    """
    return _library(cache.cache_root(), shutil.which("gcc"))


@functools.lru_cache(maxsize=None)
def _library(root: Path, gcc: str | None) -> ctypes.CDLL | None:
    try:
        return load_stepper(root / "stepper")
    except (StepperBuildError, OSError, build.FmuBuildError):
        return None


def function_address(fmu: Any, name: str) -> int:
    """Address of FMI function `name` in the library fmpy loaded for `fmu` (FMU2Slave / FMU3Slave)."""
    function = getattr(fmu, "_functions", {}).get(name) or getattr(fmu.dll, name)
    address = ctypes.cast(function, ctypes.c_void_p).value
    if not address:
        raise StepperBuildError(f"{name}: no address in the FMU's library")
    return address


class Stepper:
    """The shim bound to one instantiated fmpy FMU (its Real / Float64 variables).

    Args:
        lib: the shim library (`library()`).
        fmu: an fmpy FMU2Slave or FMU3Slave, instantiated (its `component` set).
        in_vr, out_vr: ctypes c_uint arrays of the inputs set before, the outputs read after each step.
        in_values, out_values: ctypes double arrays of the same lengths (the host's own):
            the step sends `in_values` and fills `out_values`.
    Attributes:
        call, address, times: the C function, the struct's address and a memoryview of the
            struct's (t, h): `times[0], times[1] = t, h` then `call(address)` is one step,
            returning a STEP_* code (0: done). Item writes of a memoryview and a call with
            one argument cost about half of `cosim_stepper_step(address, t, h)`, whose two
            doubles ctypes converts.
        struct: the CosimStepper (statuses, FMI 3's terminate_simulation flag).
    """

    def __init__(self, lib: ctypes.CDLL, fmu: Any, in_vr: Any, in_values: Any,
                 out_vr: Any, out_values: Any) -> None:
        self.version = 3 if type(fmu).__name__.startswith("FMU3") else 2
        self.names = CALL_NAMES[self.version]
        s = self.struct = CosimStepper()
        s.fmi_version, s.instance = self.version, fmu.component
        addresses = [function_address(fmu, name) for name in self.names]
        if self.version == 2:
            s.fmi2_set_real, s.fmi2_do_step, s.fmi2_get_real = addresses
        else:
            s.fmi3_set_float64, s.fmi3_do_step, s.fmi3_get_float64 = addresses
        s.n_in, s.in_vr, s.in_values = len(in_vr), _address(in_vr), _address(in_values)
        s.n_out, s.out_vr, s.out_values = len(out_vr), _address(out_vr), _address(out_values)
        self._arrays = (in_vr, in_values, out_vr, out_values)  # the C side points into them
        self.fmu = fmu  # keeps the FMU's library and instance alive as long as the stepper
        self.call, self.address = lib.cosim_stepper_step_at, ctypes.addressof(s)
        pair = (ctypes.c_double * 2).from_buffer(s, CosimStepper.t.offset)  # h follows t
        self.times = memoryview(pair).cast("B").cast("d")

    def failure(self, code: int) -> tuple[str, int] | None:
        """(FMI call name, status) of the call that stopped the step; None if `code` is no call failure."""
        if code in (STEP_SET, STEP_DO_STEP, STEP_GET):
            return self.names[code - 1], self.struct.status[code - 1]
        return None


LOG_SINK = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p)


class CosimFmi2Log(ctypes.Structure):
    """Mirror of struct CosimFmi2Log: where cosim_stepper_fmi2_logger sends one instance's messages."""

    _fields_ = [("sink", ctypes.c_void_p), ("context", ctypes.c_void_p)]


def fmi2_callbacks(lib: ctypes.CDLL, add: Any) -> Any:
    """FMI 2 callbacks whose logger sends this instance's messages, formatted, to `add` only.

    fmpy's addLoggerProxy keeps one callback for the whole process (the last
    instance set up receives every FMI 2 instance's messages); the shim's
    logger formats the variadic message in C and routes it by the instance's
    componentEnvironment. Keep the returned object alive as long as the instance.

    Args:
        lib: the shim library (`library()`).
        add: called as add(status, category bytes, message bytes) (e.g. FmuLog.add).
    """
    import fmpy
    from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                           fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

    callbacks = fmi2CallbackFunctions()
    callbacks._sink = LOG_SINK(lambda _context, status, category, message: add(status, category, message))
    callbacks._route = CosimFmi2Log(ctypes.cast(callbacks._sink, ctypes.c_void_p).value, None)
    callbacks.logger = ctypes.cast(lib.cosim_stepper_fmi2_logger, fmi2CallbackLoggerTYPE)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
    callbacks.componentEnvironment = ctypes.addressof(callbacks._route)
    return callbacks


def _address(array: Sequence[Any]) -> int | None:
    """Address of a ctypes array's data (None, i.e. NULL, for an empty one)."""
    return ctypes.addressof(array) if len(array) else None
