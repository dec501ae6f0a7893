"""Session fixtures shared by the whole suite: the FMUs the tests build once."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers.fmus import build_lag


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory) -> Path:
    """Session folder holding the FMUs built by the tests."""
    return tmp_path_factory.mktemp("fmus")


@pytest.fixture(scope="session")
def lag_fmus(tmp_path_factory) -> dict[int, Path]:
    """tests/fmus/Lag built as FMI 2.0 and 3.0 FMUs (version -> path)."""
    return build_lag(tmp_path_factory.mktemp("lag"))
