"""Session fixtures shared by the whole suite: the FMUs the tests build once."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.helpers.fmus import FaultyFmus, build_lag

# The suite runs the controllers' interpreted paths (and every component process it starts
# inherits this): the compiled ones (numba) are held to them bit for bit by
# tests/controllers/road/test_projection_jit.py and tests/controllers/backstepping/test_step_jit.py,
# which switch them on themselves.
os.environ.setdefault("COSIM_JIT", "off")


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory) -> Path:
    """Session folder holding the FMUs built by the tests."""
    return tmp_path_factory.mktemp("fmus")


@pytest.fixture(scope="session")
def lag_fmus(tmp_path_factory) -> dict[int, Path]:
    """tests/fmus/Lag built as FMI 2.0 and 3.0 FMUs (version -> path)."""
    return build_lag(tmp_path_factory.mktemp("lag"))


@pytest.fixture(scope="session")
def faulty_fmus(tmp_path_factory) -> FaultyFmus:
    """tests/fmus/Faulty and FaultyOnce as FMI 2.0 / 3.0 FMUs, built on first use:
    faulty_fmus["Faulty", 2] is a path."""
    return FaultyFmus(tmp_path_factory.mktemp("faulty"))


@pytest.fixture(scope="session")
def arrays_fmu(tmp_path_factory) -> Path:
    """tests/fmus/Arrays (hand-written FMI 3.0: arrays, 64-bit integers, Enumeration, String)."""
    from tests.helpers.fmus import build_handwritten_fmu
    from tests.helpers.paths import TEST_FMUS_DIR

    return build_handwritten_fmu(TEST_FMUS_DIR / "Arrays", tmp_path_factory.mktemp("arrays"))
