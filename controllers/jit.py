"""COSIM_JIT: whether the controllers' per-tick arithmetic runs compiled by numba, and the gate it passes.

Three parts of the controllers' tick have a compiled twin made by numba (the
`jit` extra): the window projection (controllers.road.projection_jit) and the
backstepping step (controllers.backstepping.step_jit), from their own Python
source, and the planner's road search (controllers.road.geometry_jit, Path's
Newton iteration written out with the same operations). The interpreted path runs
when numba is absent or COSIM_JIT says off, and both paths give the same bits.

COSIM_JIT = auto (default): compiled when numba is installed, except for a
component built for a short run (`for_this_component`); off: never; on:
compiled, or an error. `load_compiled` is the gate every compiled part
goes through at its first use in a process: it imports it (which imports
numba), checks it bit for bit against the interpreted path on built-in
cases, compiles it afresh once if they disagree (numba's disk cache does not
see an edit of a module whose functions were inlined), and otherwise falls
back to the interpreted path with a warning (an error with `on`).

In a component process (`cosim.component.may_load_beside`) under auto, the
controllers' projection and backstepping step, when they would be compiled, are
loaded on a thread beside the run instead (`beside_the_run`): the component steps
interpreted until they are ready, then takes them between two steps, with the same
bits, so tick 0 does not wait for numba's 0.3-0.6 s. (The planner's road search,
compiled only for runs of 30,000 planner steps or more, still loads before tick 0.)
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import os
import sys
import threading
import types
import warnings
from collections.abc import Callable, Iterable
from typing import Any

from cosim.component import expected_steps, may_load_beside, start_beside

JIT_VARIABLE = "COSIM_JIT"
# COSIM_JIT=auto leaves numba out of a component built for fewer steps than this, unless its
# compiled parts are loaded in the process already: numba's import and the first load of the
# cached code delay tick 0 by 0.3-0.5 s, and the compiled paths save about 28 us per
# backstepping step (benchmarks/issue14_plan.md, "Session 9" and "Session 15"): a shorter run
# ends sooner without. The planner's road search has its own (controllers.road.compiled_path).
SHORT_RUN_STEPS = 15_000
JIT_MODES = {"auto": "auto", "": "auto", "on": "on", "1": "on", "yes": "on", "true": "on",
             "off": "off", "0": "off", "no": "off", "false": "off"}


def jit_mode() -> tuple[str, str]:
    """(mode, the variable's text): mode is auto, on or off; ValueError naming the variable and value."""
    value = os.environ.get(JIT_VARIABLE, "auto")
    mode = JIT_MODES.get(value.strip().lower())
    if mode is None:
        raise ValueError(f"{JIT_VARIABLE}={value!r}: expected auto, on or off")
    return mode, value


def load_compiled(what: str, load: Callable[[], Any], disagreement: Callable[[Any], str]) -> Any | None:
    """The compiled part `load()` returns, or None for the interpreted path (see the module docstring).

    Args:
        what: the part, for messages ("the compiled projection").
        load: imports and returns the compiled module (ImportError when numba is missing); the
            module has `recompile()`.
        disagreement: '' when the module gives the interpreted path's bits on built-in cases,
            else where it does not.
    """
    mode, value = jit_mode()
    if mode == "off":
        return None
    try:
        kernel = load()
    except ImportError as error:     # no numba
        if mode == "on":
            raise ImportError(f"{JIT_VARIABLE}={value}: {what} needs numba "
                              f"(pip install 'cosim[jit]'): {error}") from None
        return None
    except Exception as error:       # a numba that is installed but does not load or compile
        if mode == "on":
            raise RuntimeError(f"{JIT_VARIABLE}={value}: numba does not load: {error!r}") from None
        warnings.warn(f"{what} is not used: numba does not load: {error!r}", RuntimeWarning, stacklevel=3)
        return None
    _load_numpy_support_without_scipy_linalg()
    found = disagreement(kernel)
    if found:      # numba's cache can predate an edit of an inlined module: compile afresh once
        kernel.recompile()
        found = disagreement(kernel)
    if found:
        if mode == "on":
            raise RuntimeError(f"{JIT_VARIABLE}={value}: {what} disagrees with the interpreted one: {found}")
        warnings.warn(f"{what} is not used: {found}", RuntimeWarning, stacklevel=3)
        return None
    return kernel


def _load_numpy_support_without_scipy_linalg() -> None:
    """Import numba's NumPy support (numba.np.arraymath) without the scipy.linalg it imports
    only to learn whether BLAS is there, then tell it the answer.

    numba loads that module at the first compile or cache load in a process. Its import asks
    for scipy.linalg.cython_blas, which imports all of scipy.linalg: 0.2 s here, on the path
    to tick 0, for a flag (`_HAVE_BLAS`) that only picks how a compiled np.correlate or
    np.convolve takes inner products; the compiled parts of the controllers use no BLAS. The
    flag is set afterwards to whether scipy.linalg's cython_blas module is installed, what
    numba finds on a working scipy (its own test imports that module, which a broken scipy
    could fail, and numba 0.68 then also compares LAPACK's integer width, which is not
    repeated here), so a user's own compiled code in the same process gets what it would
    have had; np.dot and np.linalg import scipy.linalg themselves when a function that uses
    them is compiled. The import is hidden from this thread only (`_HiddenOnThisThread`):
    another thread importing scipy.linalg meanwhile gets it.
    """
    if "numba.np.arraymath" in sys.modules or "scipy.linalg" in sys.modules:
        return  # loaded already, or scipy.linalg is: nothing to save
    hidden = _HiddenOnThisThread("scipy.linalg")
    # new lists, not the list changed in place: another thread's import may be going over it
    # (this runs on the thread that loads beside the run too)
    sys.meta_path = [hidden, *sys.meta_path]
    try:
        import numba.np.arraymath as arraymath
    except Exception:  # noqa: BLE001 - numba's own first compile reports a broken numba
        return
    finally:
        sys.meta_path = [finder for finder in sys.meta_path if finder is not hidden]
    arraymath._HAVE_BLAS = _has_extension("scipy.linalg", "cython_blas")


class _HiddenOnThisThread(importlib.abc.MetaPathFinder):
    """An import finder for which package `name` and its submodules do not exist, for the
    thread that made it only (the others go on to the next finders)."""

    def __init__(self, name: str) -> None:
        self.name, self.thread = name, threading.get_ident()

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> None:
        if threading.get_ident() == self.thread and (fullname == self.name
                                                     or fullname.startswith(self.name + ".")):
            raise ModuleNotFoundError(f"No module named {fullname!r}", name=fullname)
        return None


def _has_extension(package: str, module: str) -> bool:
    """Whether compiled module `module` of `package` is installed, without importing the
    package (its parent is imported)."""
    try:
        spec = importlib.util.find_spec(package)
    except (ImportError, ValueError):
        return False
    folders = [] if spec is None else list(spec.submodule_search_locations or ())
    suffixes = tuple(importlib.machinery.EXTENSION_SUFFIXES)
    return any(entry.name.startswith(module + ".") and entry.name.endswith(suffixes)
               for folder in folders if os.path.isdir(folder) for entry in os.scandir(folder))


def is_loaded(gate: Callable[[], Any]) -> bool:
    """Whether this process has asked `gate` (a compiled part's loader, cached by functools)
    already: numba's cost is paid, or the answer (None) is known."""
    return gate.cache_info().currsize > 0  # type: ignore[attr-defined]


def for_this_component(gate: Callable[[], Any], short_run_steps: int = SHORT_RUN_STEPS) -> Any | None:
    """`gate()` (a compiled part's loader, cached by functools, which calls `load_compiled`),
    or None for the interpreted path when COSIM_JIT is auto, the part is not loaded in this
    process yet and the component being built will step fewer than `short_run_steps` times
    (`cosim.component.expected_steps`; unknown: compiled). The default suits the
    controllers' parts; a part that saves less per step passes a larger number."""
    if not is_loaded(gate) and jit_mode()[0] == "auto" and _too_short(short_run_steps):
        return None
    return gate()


def _too_short(short_run_steps: int) -> bool:
    """Whether the component being built will step fewer than `short_run_steps` times (unknown: no)."""
    steps = expected_steps()
    return steps is not None and steps < short_run_steps


class Later:
    """A compiled part loading beside the run: `ready` turns True once its gate has answered,
    and `kernel` is then the answer (None: the interpreted path stays)."""

    __slots__ = ("gate", "ready", "kernel")

    def __init__(self, gate: Callable[[], Any]) -> None:
        self.gate, self.ready, self.kernel = gate, False, None


_waiting: list[Later] = []   # loads not started yet, in the order they were asked for
_waiting_lock = threading.Lock()
_loading = False   # a thread beside the run is taking loads from _waiting


def beside_the_run(gate: Callable[[], Any], short_run_steps: int = SHORT_RUN_STEPS) -> Later | None:
    """Start loading `gate()` (a compiled part's loader, as in `for_this_component`) on a thread
    beside the run and return its `Later`; or None, when the component should call
    `for_this_component` instead: its host does not allow it (`may_load_beside`), COSIM_JIT is not
    auto (on: the part before tick 0, or an error; off: never), this process has loaded the part
    already, or the run is shorter than `short_run_steps`."""
    if not may_load_beside() or is_loaded(gate) or jit_mode()[0] != "auto" or _too_short(short_run_steps):
        return None
    global _loading
    later = Later(gate)
    with _waiting_lock:
        _waiting.append(later)
        start, _loading = not _loading, True
    if start:
        try:
            start_beside(_load_waiting, "jit", loads=True)
        except RuntimeError:   # no thread to be had: the component loads the part now instead
            with _waiting_lock:
                _waiting.remove(later)
                _loading = False
            return None
    return later


def _load_waiting() -> None:
    """The thread beside the run: every waiting load, one after the other, then it ends."""
    global _loading
    while True:
        with _waiting_lock:   # an empty queue and the end in one step: a later load starts a thread
            if not _waiting:
                _loading = False
                return
            later = _waiting.pop(0)
        try:
            later.kernel = later.gate()
        except Exception as error:   # noqa: BLE001 - auto never fails a run for its compiled parts
            _warn(f"a compiled part is not used: {error!r}")
        finally:
            later.ready = True


def now_or_beside(gate: Callable[[], Any],
                  short_run_steps: int = SHORT_RUN_STEPS) -> tuple[Any | None, Later | None]:
    """(the compiled part now, or None for the interpreted path; its load beside the run, or None):
    `beside_the_run` when it applies, else `for_this_component`."""
    later = beside_the_run(gate, short_run_steps)
    return (None, later) if later is not None else (for_this_component(gate, short_run_steps), None)


def _warn(message: str) -> None:
    """A RuntimeWarning from the thread beside the run, which an error filter cannot end."""
    try:
        warnings.warn(message, RuntimeWarning, stacklevel=1)
    except Warning:   # -W error: the component stays interpreted all the same
        pass


def njit_cached(function: Callable) -> Any:
    """numba.njit with the on-disk cache, or without it when no cache folder is writable (a warning)."""
    import numba

    try:
        return numba.njit(cache=True, nogil=True)(function)
    except RuntimeError as error:     # "cannot cache function ...: no locator available"
        warnings.warn(f"{function.__name__} is compiled in each process: {error} "
                      f"(set NUMBA_CACHE_DIR to a writable folder to keep it)", RuntimeWarning, stacklevel=2)
        return numba.njit(nogil=True)(function)


def compile_together(functions: Iterable[Callable]) -> dict[str, Any]:
    """njit_cached twins of plain functions that call one another's twins, not the originals.

    Each twin is the function's own code over a copy of its module's globals
    in which every global bound to one of `functions` (under any name) is
    bound to that function's twin instead, so the modules themselves (the
    interpreted path) are left as they are. numba reads those globals when it
    first compiles a twin; module-level numbers are taken as constants.
    Returns the twins by function name.
    """
    functions = list(functions)
    namespaces: dict[str, dict[str, Any]] = {}
    twins: dict[int, Any] = {}
    for original in functions:
        namespace = namespaces.setdefault(original.__module__, dict(original.__globals__))
        rebound = types.FunctionType(original.__code__, namespace, original.__name__, original.__defaults__)
        rebound.__qualname__, rebound.__module__ = original.__qualname__, original.__module__
        twins[id(original)] = njit_cached(rebound)
    for namespace in namespaces.values():
        for name, value in namespace.items():
            if id(value) in twins:      # the originals are alive in `functions`: an id is theirs
                namespace[name] = twins[id(value)]
    return {original.__name__: twins[id(original)] for original in functions}
