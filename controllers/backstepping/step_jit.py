"""The backstepping step compiled by numba (the `jit` extra): the same bits as step_kernel interpreted.

Imported only by controllers.backstepping.component, through controllers.jit's
gate (COSIM_JIT, a bit-for-bit check at first use). step_kernel's functions
and controllers.tracking.errors_at_feet are compiled from their own source
(controllers.jit.compile_together), cached on disk by numba beside the sources.
"""

from __future__ import annotations

import numba  # noqa: F401  (ImportError without numba: the component keeps the interpreted step)
import numpy as np

from controllers import jit, tracking
from controllers.backstepping import step_kernel

_TWINS = jit.compile_together([tracking.errors_at_feet, step_kernel.unit, step_kernel.reference,
                               step_kernel.lateral_command, step_kernel.step])
step = _TWINS["step"]


def constants(values: tuple[float, ...]) -> np.ndarray:
    """The compiled step's constants: step_kernel's tuple as the one float64 array signature."""
    return np.array(values, dtype=np.float64)


def recompile() -> None:
    """Compile every twin afresh (and replace their cache entries), callees first."""
    for twin in _TWINS.values():
        twin.recompile()
