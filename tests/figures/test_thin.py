"""Tests of `cosim.figures.thin`: a long path thinned to a quarter of a pixel stays the same line."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.figure import Figure

from cosim.figures.thin import pixel_size, thin_path


def spiral(n: int) -> tuple[np.ndarray, np.ndarray]:
    angle = np.linspace(0.0, 6 * np.pi, n)
    radius = 50.0 + 5.0 * angle
    return radius * np.cos(angle), radius * np.sin(angle)


def distance_to_polyline(px: np.ndarray, py: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Distance from each point (px, py) to the polyline (x, y)."""
    ax, ay, dx, dy = x[:-1], y[:-1], np.diff(x), np.diff(y)
    u = np.clip(((px[:, None] - ax) * dx + (py[:, None] - ay) * dy) / (dx * dx + dy * dy), 0.0, 1.0)
    return np.hypot(ax + u * dx - px[:, None], ay + u * dy - py[:, None]).min(axis=1)


@pytest.mark.parametrize("block", [7, 1 << 15])
def test_thinned_path_keeps_the_ends_and_stays_within_the_spacing(block):
    x, y = spiral(20000)
    spacing = 0.5
    tx, ty = thin_path(x, y, spacing, block=block)
    assert 100 < len(tx) < len(x) // 4
    assert (tx[0], ty[0], tx[-1], ty[-1]) == (x[0], y[0], x[-1], y[-1])
    kept = np.flatnonzero(np.isin(x, tx))
    assert np.all(np.diff(kept) > 0)            # a subsequence of the points, in order
    every = np.arange(0, len(x), 37)
    assert distance_to_polyline(x[every], y[every], tx, ty).max() < spacing
    assert np.hypot(np.diff(tx), np.diff(ty))[:-1].min() > 0.5 * spacing


def test_thinning_is_the_same_in_any_block_size():
    x, y = spiral(5000)
    assert np.array_equal(thin_path(x, y, 0.3, block=11)[0], thin_path(x, y, 0.3, block=4096)[0])


def test_short_paths_and_no_spacing_are_left_alone():
    x, y = spiral(2)
    assert thin_path(x, y, 1.0)[0] is x
    x, y = spiral(100)
    assert thin_path(x, y, 0.0)[0] is x


def test_pixel_size_is_the_larger_span_per_pixel():
    fig = Figure(figsize=(10, 5))
    ax = fig.add_axes((0.0, 0.0, 0.5, 1.0))     # 5 x 5 inches
    x, y = np.array([0.0, 1000.0]), np.array([0.0, 100.0])
    assert pixel_size(ax, x, y, dpi=100) == pytest.approx(1000.0 / 500)
