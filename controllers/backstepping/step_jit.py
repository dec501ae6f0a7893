"""The backstepping step compiled by numba (the `jit` extra): the same bits as step_kernel interpreted.

Imported only by controllers.backstepping.step_path, through controllers.jit's
gate (COSIM_JIT, a bit-for-bit check at first use). step_kernel's functions
and controllers.tracking.errors_at_feet are compiled from their own source
(controllers.jit.compile_together), cached on disk by numba beside the sources.
`step_on_feet` is the step on the compiled projection's buffer of the two feet
(BacksteppingController's path when both are compiled).
"""

from __future__ import annotations

import numba  # noqa: F401  (ImportError without numba: the component keeps the interpreted step)
import numpy as np

from controllers import jit, tracking
from controllers.backstepping import step_kernel
from controllers.road import projection_jit

_TWINS = jit.compile_together([tracking.errors_at_feet, step_kernel.unit, step_kernel.reference,
                               step_kernel.lateral_command, step_kernel.step])
step = _TWINS["step"]


@jit.njit_cached
def step_on_feet(c, feet, norm_cg, norm_preview, x, y, dt, mu_hat, mu_hat_dot, last_delta, psi, vx, vy, r):
    """step on the feet the compiled projection wrote (projection_jit.cg_and_preview_into), finished
    here with the norms of their tangents (math.hypot, taken by the caller): the window
    projection's tuples never cross into the interpreter and back.

    Args:
        c, dt, mu_hat, mu_hat_dot, last_delta, psi, vx, vy, r: as step's;
        feet: the buffer cg_and_preview_into filled for the CG (x, y);
        norm_cg, norm_preview: math.hypot of the tangents cg_and_preview_into returned.
    """
    at_cg = projection_jit.finished(feet, 0, x, y, norm_cg)
    preview = projection_jit.finished(feet, 12, feet[24], feet[25], norm_preview)
    return step(c, dt, mu_hat, mu_hat_dot, last_delta, psi, vx, vy, r, at_cg, preview)


def constants(values: tuple[float, ...]) -> np.ndarray:
    """The compiled step's constants: step_kernel's tuple as the one float64 array signature."""
    return np.array(values, dtype=np.float64)


def recompile() -> None:
    """Compile every twin afresh (and replace their cache entries), callees first."""
    for twin in _TWINS.values():
        twin.recompile()
    step_on_feet.recompile()     # numba's cache does not see an edit of projection_jit.finished
