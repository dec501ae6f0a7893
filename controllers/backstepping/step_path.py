"""Which backstepping step a controller runs: step_kernel compiled by numba, or interpreted.

`compiled_step()` is controllers.jit's gate for controllers.backstepping.step_jit
(COSIM_JIT; numba missing or broken), with a check at first use in each
process: the compiled step against the interpreted one, compared by repr
(which tells -0.0 from 0.0 and an int from a float), on built-in cases that
reach every branch (each lateral law and target, both adaptation laws, the
torque and steering limits, a foot beyond the window's end), for `step` and
for `step_on_feet` (the step on the compiled projection's buffer of the feet).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from controllers import jit
from controllers.backstepping import step_kernel
from controllers.road.projection import FEET_SIZE, finish

# (feedforward, at_cg, robust) of the built-in cases
_LAWS = ((0.0, 1.0, 0.0), (1.0, 1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 1.0), (1.0, 1.0, 1.0))


@functools.cache
def compiled_step():
    """controllers.backstepping.step_jit (its `step` and `constants`), or None for the interpreted step."""
    return jit.load_compiled("the compiled backstepping step", _import_step_jit, _disagreement)


def _import_step_jit():
    from controllers.backstepping import step_jit
    return step_jit


def _cases():
    """(constants, step arguments after them) covering every branch, from a fixed pseudo-random walk."""
    state = 12345

    def uniform(lo: float, hi: float) -> float:
        nonlocal state
        state = (state * 6364136223846793005 + 1442695040888963407) % 2**64
        return lo + (hi - lo) * (state >> 11) / 2**53

    for feedforward, at_cg, robust in _LAWS:
        lateral = (-76.7, -5.37, -3.66, -99.7, 76.7, 47.1, 8100.0, 44.4, 81.5, 5.4, 5.0, 1.0, 0.8, 1.0,
                   feedforward, at_cg, robust)
        constants = lateral + (1500.0, 1524.0, 0.3, 3000.0, 3000.0, -6000.0, 0.5, 1.0, 0.1, 1.2, 0.5)
        for _ in range(60):
            extrapolated = 1 if uniform(0.0, 1.0) < 0.1 else 0
            at_cg = (uniform(0, 50), uniform(-50, 50), uniform(-50, 50), uniform(-1, 1), uniform(-4, 4),
                     uniform(-0.05, 0.05), uniform(-0.01, 0.01), uniform(2, 20), uniform(-2, 2),
                     -1 if uniform(0.0, 1.0) < 0.05 else 0)
            preview = (uniform(0, 50), uniform(-50, 50), uniform(-50, 50), uniform(-2, 2), uniform(-4, 4),
                       uniform(-0.05, 0.05), uniform(-0.01, 0.01), uniform(2, 20), uniform(-2, 2), extrapolated)
            yield constants, (uniform(0.005, 0.02), uniform(0.1, 1.2), uniform(-1, 1), uniform(-0.6, 0.6),
                              uniform(-4, 4), uniform(0.0, 25.0), uniform(-1, 1), uniform(-0.5, 0.5),
                              at_cg, preview)


def _disagreement(kernel) -> str:
    """'' if kernel.step gives step_kernel.step's tuples bit for bit on _cases(), else the first case
    that does not; likewise kernel.step_on_feet on those feet before projection.finish."""
    feet = np.zeros(FEET_SIZE)
    for number, (constants, arguments) in enumerate(_cases()):
        expected = step_kernel.step(constants, *arguments)
        got = kernel.step(kernel.constants(constants), *arguments)
        if repr(got) != repr(expected):
            return f"on {arguments} it gives {got}, the interpreted step {expected}"
        x, y, at_cg, preview, norms = _unfinished(feet, arguments[8], arguments[9], number)
        dt, mu_hat, mu_hat_dot, last_delta, psi, vx, vy, r = arguments[:8]
        px, py = feet[24:26].tolist()
        expected = step_kernel.step(constants, *arguments[:8], finish(at_cg, x, y), finish(preview, px, py))
        got = kernel.step_on_feet(kernel.constants(constants), feet, *norms, x, y, dt, mu_hat, mu_hat_dot,
                                  last_delta, psi, vx, vy, r)
        if repr(got) != repr(expected):
            return f"on the feet {at_cg}, {preview} step_on_feet gives {got}, the interpreted step {expected}"
    return ""


def _unfinished(feet: np.ndarray, at_cg: tuple, preview: tuple, number: int) -> tuple:
    """A case's two feet as hermite's foot fields in `feet` (projection.FEET_SIZE's layout), tangents and
    points made from their fields: (x, y, CG fields, preview fields, math.hypot of both tangents)."""
    x, y = at_cg[1] + 0.1 * at_cg[3], at_cg[2] - 0.3 * at_cg[4]
    fields = []
    for start, foot in ((0, at_cg), (12, preview)):
        tangent = (math.cos(foot[4]) * (1.0 + 0.01 * number), math.sin(foot[4]) * (1.0 + 0.01 * number))
        fields.append(foot[:3] + (foot[3] if foot[9] else 0.0,) + foot[4:10] + tangent)   # evaluate's offset: 0.0
        feet[start:start + 12] = fields[-1]
    feet[24], feet[25] = preview[1] + 0.2 * preview[3], preview[2] - 0.1 * preview[4]
    return x, y, fields[0], fields[1], (math.hypot(*fields[0][10:]), math.hypot(*fields[1][10:]))

