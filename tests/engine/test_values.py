"""The value helpers shared by the master and the Zenoh codec (cosim/engine/values.py)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from cosim.engine.values import picker, value_problem
from tests.helpers.paths import REPO_ROOT


@pytest.mark.parametrize("keys, expected", [
    ((), ()), (("b",), (2.0,)), (("c", "a"), (3.0, 1.0))])
def test_picker_returns_a_tuple_for_any_number_of_names(keys, expected):
    assert picker(keys)({"a": 1.0, "b": 2.0, "c": 3.0}) == expected


def test_picker_reads_list_indices_too():
    assert picker([2])([10.0, 11.0, 12.0]) == (12.0,)
    assert picker([0, 2])([10.0, 11.0, 12.0]) == (10.0, 12.0)


@pytest.mark.parametrize("value, size, expected", [
    (1.5, 1, ""),
    (np.array([1.0, 2.0]), 2, ""),
    ([1.0, 2.0], 1, "has shape (2,), expected a scalar"),
    (3.0, 2, "has shape (), expected (2,)"),
    ("x", 1, "is not a number: 'x'"),
    (float("-inf"), 1, "is non-finite: -inf"),
    ([0.0, 1.0, float("nan")], 3, "is non-finite at [2]: nan"),
])
def test_value_problem_names_the_first_fault(value, size, expected):
    assert value_problem(value, size) == expected


def test_importing_values_loads_no_numpy():
    code = "import sys, cosim.engine.values; print('numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO_ROOT,
                         capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
