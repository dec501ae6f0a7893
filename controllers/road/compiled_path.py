"""Which foot-point search a Path runs: controllers.road.geometry_jit compiled by numba, or interpreted.

`compiled_geometry()` is controllers.jit's gate for geometry_jit (COSIM_JIT;
numba missing or broken), with a check at first use in each process: the
compiled Path._point and Path._newton against the interpreted ones, compared by
repr (which tells -0.0 from 0.0 and None from a float), on an open and a closed
path: points inside, on the knots, beyond both ends and around the lap, and
Newton solves from near and far guesses, at the centre of curvature (the plain
step) and clamped at an end. `for_this_component(road)` is how a component (the
planner) opts its road in.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import TYPE_CHECKING

import numpy as np

from controllers import jit
from controllers.road.geometry import Path

if TYPE_CHECKING:
    from controllers.road.builders import Road


# COSIM_JIT=auto leaves a road's compiled search out of a component that steps fewer times than
# this: in a process without numba its import and this part's first load take 0.37-0.53 s, and
# the search saves about 14 us per planner step (benchmarks/issue14_plan.md, "Session 15").
SHORT_RUN_STEPS = 30_000


@functools.cache
def compiled_geometry():
    """controllers.road.geometry_jit (its `newton` and `point`), or None for the interpreted search."""
    return jit.load_compiled("the compiled road projection", _import_kernel, _disagreement)


def for_this_component(road: Road) -> Road:
    """`road`, or a copy whose reference line projects with the compiled search when a component
    built now takes it (jit.for_this_component: not for a short run under COSIM_JIT=auto). A copy,
    not the road itself: roads are shared (the builders cache them) by components that decide apart."""
    kernel = jit.for_this_component(compiled_geometry, SHORT_RUN_STEPS)
    if kernel is None:
        return road
    return dataclasses.replace(road, reference=road.reference.with_compiled_search(kernel))


def _import_kernel():
    from controllers.road import geometry_jit
    return geometry_jit


def _test_paths() -> list[Path]:
    """An open path of lines, arcs and clothoids (both turns), and a closed circle of radius 40 m."""
    pieces = [(20.0, 0.0, 0.0), (30.0, 0.0, 0.025), (35.0, 0.025, 0.025), (25.0, 0.025, -0.02),
              (30.0, -0.02, -0.02), (15.0, 0.0, 0.0)]
    radius = 40.0
    return [Path.from_pieces(pieces, x0=3.0, y0=-2.0, psi0=0.4),
            Path.from_pieces([(2.0 * math.pi * radius, 1.0 / radius, 1.0 / radius)], closed=True)]


def _disagreement(kernel) -> str:
    """'' if kernel's point and newton give Path._point's and Path._newton's bits on _test_paths(),
    else the first case where they do not."""
    for path in _test_paths():
        newton, point = path.with_compiled_search(kernel)._compiled
        length = path.length
        for s in [*np.linspace(-12.0, length + 12.0, 41).tolist(), *path.s.tolist(), -0.0, length]:
            if repr(point(s)) != repr(path._point(s)):
                return f"at s = {s} it gives {point(s)}, Path._point {path._point(s)}"
        x, y, _, _ = path.evaluate(np.linspace(0.0, length, 9))
        for px, py in zip(x.tolist(), y.tolist()):
            for dx, dy in ((0.0, 0.0), (1.5, -0.7), (-6.0, 4.0), (-80.0, 3.0)):
                for guess in (0.37 * length, length):
                    expected, got = path._newton(px + dx, py + dy, guess), newton(px + dx, py + dy, guess)
                    if repr(got) != repr(expected):
                        return f"Newton from s = {guess} at ({px + dx}, {py + dy}) gives {got}, Path._newton {expected}"
    return ""
