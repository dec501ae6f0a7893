"""Which backstepping step a controller runs: step_kernel compiled by numba, or interpreted.

`compiled_step()` is controllers.jit's gate for controllers.backstepping.step_jit
(COSIM_JIT; numba missing or broken), with a check at first use in each
process: the compiled step against the interpreted one, compared by repr
(which tells -0.0 from 0.0 and an int from a float), on built-in cases that
reach every branch (each lateral law and target, both adaptation laws, the
torque and steering limits, a foot beyond the window's end).
"""

from __future__ import annotations

import functools

from controllers import jit
from controllers.backstepping import step_kernel

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
                     uniform(-0.05, 0.05), uniform(-0.01, 0.01), uniform(2, 20), uniform(-2, 2), 0)
            preview = (uniform(0, 50), uniform(-50, 50), uniform(-50, 50), uniform(-2, 2), uniform(-4, 4),
                       uniform(-0.05, 0.05), uniform(-0.01, 0.01), uniform(2, 20), uniform(-2, 2), extrapolated)
            yield constants, (uniform(0.005, 0.02), uniform(0.1, 1.2), uniform(-1, 1), uniform(-0.6, 0.6),
                              uniform(-4, 4), uniform(0.0, 25.0), uniform(-1, 1), uniform(-0.5, 0.5),
                              at_cg, preview)


def _disagreement(kernel) -> str:
    """'' if kernel.step gives step_kernel.step's tuples bit for bit on _cases(), else the first case that does not."""
    for constants, arguments in _cases():
        expected = step_kernel.step(constants, *arguments)
        got = kernel.step(kernel.constants(constants), *arguments)
        if repr(got) != repr(expected):
            return f"on {arguments} it gives {got}, the interpreted step {expected}"
    return ""

