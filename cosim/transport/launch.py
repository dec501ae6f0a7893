"""`PythonComponentLaunch`: which Python component to host, with what, how often.

The same description serves every transport (in-process, a local Zenoh
process, a worker on another host). It needs only the standard library, so
the master can spawn component processes before loading numpy or fmpy.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

# The longest a component may take to start, unless the run says otherwise (`cosim run
# --startup-timeout`): its process's start and handshake, or its constructor in the master.
STARTUP_TIMEOUT_S = 20.0


@dataclass(frozen=True)
class PythonComponentLaunch:
    """How to launch one Python component, whatever the transport.

    Args:
        name: component name in the scenario.
        class_path: "package.module:ClassName" of a `cosim.component.Component`.
        parameters: keyword arguments for the class constructor.
        period_ticks: master ticks between two steps (>= 1).
        import_path: folders in front of the import path of the process that hosts it
            (`cosim.scenario.imports.import_roots`); () means the working directory.
        steps: the steps the run asks of it (its ticks over its period), when known; the
            host offers them to the constructor (`cosim.component.expected_steps`), times
            the runs its process hosts when it knows them (`run_scenario(runs_in_process=)`).
    """

    name: str
    class_path: str
    parameters: Mapping[str, Any] = field(default_factory=dict)
    period_ticks: int = 1
    import_path: tuple[str, ...] = ()
    steps: int | None = None


def steps_from_json(value: Any) -> int | None:
    """A launch's `steps` as a spec or a start request carries it: None when absent or not a count."""
    return value if isinstance(value, int) and not isinstance(value, bool) and value >= 0 else None
