"""Fixtures of the controllers' tests: the projection's compiled path switched on or off."""

from __future__ import annotations

import pytest

from controllers.road import projection


@pytest.fixture
def jit_mode(monkeypatch):
    """set_mode(mode): COSIM_JIT = mode for one test, compiled_kernel() asked afresh; returns its answer."""
    def set_mode(mode: str):
        monkeypatch.setenv(projection.JIT_VARIABLE, mode)
        projection.compiled_kernel.cache_clear()
        return projection.compiled_kernel()
    yield set_mode
    projection.compiled_kernel.cache_clear()
