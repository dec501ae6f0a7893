"""Fixtures of the controllers' tests: the compiled paths (projection, backstepping step) switched on or off."""

from __future__ import annotations

import pytest

from controllers import jit
from controllers.backstepping import step_path
from controllers.road import projection


@pytest.fixture
def jit_mode(monkeypatch):
    """set_mode(mode): COSIM_JIT = mode for one test, both gates asked afresh; returns the projection's answer."""
    def set_mode(mode: str):
        monkeypatch.setenv(jit.JIT_VARIABLE, mode)
        projection.compiled_kernel.cache_clear()
        step_path.compiled_step.cache_clear()
        return projection.compiled_kernel()
    yield set_mode
    projection.compiled_kernel.cache_clear()
    step_path.compiled_step.cache_clear()
