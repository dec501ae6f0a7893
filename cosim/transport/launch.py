"""`PythonComponentLaunch`: which Python component to host, with what, how often.

The same description serves every transport (in-process, a local Zenoh
process, a worker on another host). It needs only the standard library, so
the master can spawn component processes before loading numpy or fmpy.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any


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
    """

    name: str
    class_path: str
    parameters: Mapping[str, Any] = field(default_factory=dict)
    period_ticks: int = 1
    import_path: tuple[str, ...] = ()
