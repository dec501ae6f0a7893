"""cosim: a co-simulation master for closed-loop vehicle control (FMU plants, Zenoh components).

The Python API (`docs/python-api.md`), loaded on first use so that `import cosim`
stays cheap (every component process imports it at start-up):

    cosim.run(scenario, *, set=None, transport="inproc", out=None, progress=False) -> cosim.Run
    cosim.load_run(path), cosim.load_scenario(scenario), cosim.validate(scenario), cosim.scenarios()

and the errors they raise: cosim.UserError and its subclasses (ScenarioError,
WiringError, FmuInterfaceError, ComponentFailure, ProblemsError).
"""

import importlib as _importlib
import time as _time

__version__ = "0.1.0"

# When the package was first imported (perf_counter, CPU seconds): the start-up clock's
# fallback zero for a process that was forked long before it exec'd Python (cosim.engine.startup).
IMPORTED_AT = (_time.perf_counter(), _time.process_time())

_API = ("Run", "load_run", "load_scenario", "run", "scenarios", "validate")
_ERRORS = ("UserError", "ProblemsError", "ScenarioError", "WiringError", "FmuInterfaceError",
           "ComponentFailure")
__all__ = [*_API, *_ERRORS, "__version__"]


def __getattr__(name: str):
    """Load the API (cosim.api) or the error classes (cosim.errors) on first access.

    Imported by name, not by an import statement: the modules of every layer read
    `cosim.__version__`, and must not look (to import-linter) as if they imported the API.
    """
    if name in _API:
        return getattr(_importlib.import_module("cosim.api"), name)
    if name in _ERRORS:
        return getattr(_importlib.import_module("cosim.errors"), name)
    raise AttributeError(f"module 'cosim' has no attribute {name!r}")


def __dir__() -> list:
    return sorted([*globals(), *_API, *_ERRORS])
