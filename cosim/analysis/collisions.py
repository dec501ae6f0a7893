"""Collisions between two vehicle bodies: do their rectangles overlap at a tick?

Each body is a rectangle in the ground plane, `length` x `width`, aligned
with its heading psi, its front `front` metres ahead of the CG (default
length / 2: the CG at the centre), as in cosim.analysis.cones. Two convex
rectangles overlap unless one of their four edge directions separates them
(the separating axis theorem); touching counts as overlapping.
"""

from __future__ import annotations

import numpy as np

Pose = tuple[np.ndarray, np.ndarray, np.ndarray]


def _centre(pose: Pose, length: float, front: float) -> tuple[np.ndarray, np.ndarray]:
    """The rectangle's centre from the CG pose (x, y, psi)."""
    x, y, psi = pose
    shift = front - 0.5 * length
    return x + shift * np.cos(psi), y + shift * np.sin(psi)


def bodies_overlap(a: Pose, b: Pose, length: float = 4.5, width: float = 1.8,
                   front: float | None = None) -> np.ndarray:
    """Per tick, whether two bodies of the same size overlap.

    Args:
        a, b: (x, y, psi) arrays of the two CGs (m, m, rad), one value per tick.
        length, width: body size (m), defaults 4.5 x 1.8.
        front: CG-to-front-bumper distance (m); None: length / 2.

    Returns:
        Boolean array, one entry per tick.
    """
    front = 0.5 * length if front is None else front
    ax, ay = _centre(a, length, front)
    bx, by = _centre(b, length, front)
    dx, dy = bx - ax, by - ay
    half = (0.5 * length, 0.5 * width)
    separated = np.zeros(np.shape(dx), dtype=bool)
    for own, other in ((a[2], b[2]), (b[2], a[2])):
        rel = other - own
        c, s = np.abs(np.cos(rel)), np.abs(np.sin(rel))
        for axis, (reach_own, cos_other, sin_other) in enumerate(((half[0], c, s), (half[1], s, c))):
            angle = own + 0.5 * np.pi * axis
            distance = np.abs(dx * np.cos(angle) + dy * np.sin(angle))
            reach_other = half[0] * cos_other + half[1] * sin_other
            separated |= distance > reach_own + reach_other
    return ~separated


def contact_events(overlap: np.ndarray) -> int:
    """The number of separate contacts: runs of consecutive overlapping ticks."""
    overlap = np.asarray(overlap, dtype=bool)
    if overlap.size == 0:
        return 0
    return int(overlap[0]) + int(np.count_nonzero(overlap[1:] & ~overlap[:-1]))
