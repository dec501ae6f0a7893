"""The import path of a scenario's Python components, the same for every way of running it.

A scenario's `python: module:Class` is imported with two folders in front of
the import path: the scenario file's folder, then the working directory (a
scenario built in memory has only the working directory). `cosim validate`,
`--transport inproc`, the Zenoh component processes (through their
PYTHONPATH), `cosim sweep` tasks and `cosim.run` all use `import_roots`, so a
controller in the user's own module imports everywhere or nowhere. A worker
on another host has its own files: components placed there import from the
worker's working directory (and only from the module prefixes it allows).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from pathlib import Path


def import_roots(scenario_file: str | Path | None) -> tuple[str, ...]:
    """The folders put in front of the import path: the scenario's folder, then the cwd.

    Args:
        scenario_file: the scenario YAML, or None for a scenario built in memory.
    """
    roots = []
    if scenario_file is not None:
        roots.append(str(Path(scenario_file).resolve().parent))
    roots.append(os.getcwd())
    return tuple(dict.fromkeys(roots))  # the scenario's folder may be the cwd


def add_import_roots(roots: Sequence[str]) -> None:
    """Put `roots` in front of sys.path, in order (a root already there is left where it is).

    Args:
        roots: folders from `import_roots`.
    """
    missing = [r for r in roots if r not in sys.path]
    sys.path[:0] = missing


def pythonpath(roots: Sequence[str], existing: str | None) -> str:
    """A PYTHONPATH value: `roots`, then what was there before.

    Args:
        roots: folders from `import_roots`.
        existing: the current PYTHONPATH (None or "" when unset).
    """
    return os.pathsep.join([*roots, *([existing] if existing else [])])
