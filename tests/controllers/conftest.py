"""Fixtures of the controllers' tests: the compiled paths (projection, backstepping step, road search) on or off."""

from __future__ import annotations

import pytest

from controllers import jit
from controllers.backstepping import step_path
from controllers.road import compiled_path, projection


@pytest.fixture
def jit_mode(monkeypatch):
    """set_mode(mode): COSIM_JIT = mode for one test, every gate asked afresh; returns the projection's answer."""
    gates = (projection.compiled_kernel, step_path.compiled_step, compiled_path.compiled_geometry)

    def set_mode(mode: str):
        monkeypatch.setenv(jit.JIT_VARIABLE, mode)
        for gate in gates:
            gate.cache_clear()
        return projection.compiled_kernel()
    yield set_mode
    for gate in gates:
        gate.cache_clear()


@pytest.fixture
def fresh(monkeypatch):
    """mode(m): COSIM_JIT = m with neither of the controllers' compiled parts (projection, step)
    loaded in this process yet; unlike jit_mode it asks no gate."""
    def mode(value: str) -> None:
        monkeypatch.setenv(jit.JIT_VARIABLE, value)
        projection.compiled_kernel.cache_clear()
        step_path.compiled_step.cache_clear()
    yield mode
    projection.compiled_kernel.cache_clear()
    step_path.compiled_step.cache_clear()
