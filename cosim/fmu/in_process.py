"""Which host runs an FMU in this process: the one rule the master and an isolated FMU's process share."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from cosim.fmu.model_exchange import ModelExchangeComponent
from cosim.fmu.typed import hosted_fmu


def in_process_host(name: str, path: Any, interface: Any, parameters: Mapping[str, float],
                    period_ticks: int, log_file: Any, solver: Any) -> Any:
    """Model Exchange integrated by `solver` when one is given, else co-simulation
    (`cosim.fmu.typed.hosted_fmu`: typed I/O when the FMU's ports need it)."""
    if solver is not None:
        return ModelExchangeComponent(name, path, interface, parameters, period_ticks, solver,
                                      log_file)
    return hosted_fmu(name, path, interface, parameters, period_ticks, log_file)
