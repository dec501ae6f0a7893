"""Ctrl-C while the `cosim` command loads: one line and the failed-run status, no traceback.

typer and rich take about 0.2 s to import; a Ctrl-C in that time would print a
KeyboardInterrupt traceback. `quiet_until_started` installs a handler that
prints one line and exits 1 (for `run`, the line of a run interrupted before
tick 0); `restore` gives Ctrl-C back to Python once the command has started.
Standard library only, so that it is cheap to import first.
"""

from __future__ import annotations

import signal
import sys


def _early_interrupt(signum: int, frame: object) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # exiting: a second Ctrl-C prints nothing more
    running = sys.argv[1:2] == ["run"]
    sys.stderr.write("run failed: interrupted before tick 0\n" if running else "cosim: interrupted\n")
    raise SystemExit(1)


def is_cosim_program(module_name: str) -> bool:
    """True when this process is the `cosim` command: not a test importing the CLI, nor a
    child that multiprocessing's spawn started from the command's script (a sweep's Dask
    workers), which imports the CLI again as `__mp_main__` but never runs it."""
    # `import multiprocessing` makes __mp_main__ an alias of __main__; a spawned child that
    # re-runs the parent's script runs it as a module of its own under that name
    mp_main = sys.modules.get("__mp_main__")
    if mp_main is not None and mp_main is not sys.modules.get("__main__"):
        return False
    path = sys.argv[0].replace("\\", "/") if sys.argv else ""
    return (path.rsplit("/", 1)[-1] == "cosim" or path.endswith("cosim/cli/app.py")
            or module_name == "__main__")


def is_cosim_command() -> bool:
    """True when this process is the `cosim` command itself (not a test calling `main`)."""
    main = sys.modules.get("__main__")
    spec = getattr(main, "__spec__", None)
    return is_cosim_program("") or getattr(spec, "name", None) == "cosim.cli.app"


def quiet_until_started(module_name: str) -> None:
    """Install the one-line Ctrl-C handler when this process is the `cosim` command.

    Args:
        module_name: `__name__` of the entry module ("__main__" under `python -m`).
    """
    if is_cosim_program(module_name) and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        try:
            signal.signal(signal.SIGINT, _early_interrupt)
        except ValueError:  # not the main thread: leave signals alone
            pass


_seen = False  # a Ctrl-C arrived since `restore`


def _interrupt(signum: int, frame: object) -> None:
    global _seen
    _seen = True
    raise KeyboardInterrupt


def restore() -> None:
    """Give Ctrl-C back to Python (KeyboardInterrupt) once the command has started.

    The handler also notes the interrupt, so that one swallowed by a library
    (an import that catches every exception, as some optional-dependency probes
    do) is still acted on: see `raise_if_swallowed`.
    """
    if signal.getsignal(signal.SIGINT) in (_early_interrupt, signal.default_int_handler):
        signal.signal(signal.SIGINT, _interrupt)


def seen() -> bool:
    """Whether a Ctrl-C arrived since `restore` (a library may have turned it into its own
    error: pydantic-core raises a SchemaError when it lands while a model is being built)."""
    return _seen


def raise_if_swallowed() -> None:
    """Raise KeyboardInterrupt if a Ctrl-C arrived and nothing acted on it yet."""
    if _seen:
        raise KeyboardInterrupt
