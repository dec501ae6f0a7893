"""Test support for the compiled parts' gates (controllers.jit.load_compiled): a kernel made to disagree."""

from __future__ import annotations

import types
from collections.abc import Callable

import numpy as np
import pytest


def one_bit_off(monkeypatch, kernel: types.ModuleType, name: str) -> list[str]:
    """Make `kernel.<name>` return its first value one bit higher, and record (not run) the kernel's
    recompile(): the gate's check must then find the difference. Returns the record of recompiles."""
    exact, calls = getattr(kernel, name), []

    def off_by_one_bit(*arguments):
        first, *rest = exact(*arguments)
        return (float(np.nextafter(first, np.inf)), *rest)

    monkeypatch.setattr(kernel, name, off_by_one_bit)
    monkeypatch.setattr(kernel, "recompile", lambda: calls.append("recompile"))
    return calls


def assert_refused_after_one_recompile(monkeypatch, gate: Callable, kernel: types.ModuleType, name: str,
                                       warning: str) -> None:
    """With `kernel.<name>` one bit off, COSIM_JIT=auto's `gate()` compiles afresh once, then warns
    (`warning`, a regular expression) and gives the interpreted path (None)."""
    calls = one_bit_off(monkeypatch, kernel, name)
    monkeypatch.setenv("COSIM_JIT", "auto")
    gate.cache_clear()
    with pytest.warns(RuntimeWarning, match=warning):
        assert gate() is None
    assert calls == ["recompile"]
