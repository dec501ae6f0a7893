"""cosim.signal_types: which conversions between FMI types are exact, what an integer input
takes, when a 64-bit integer leaves float64."""

import numpy as np
import pytest

from cosim.signal_types import (INTEGER_RANGES, exact_into, inexact_integer, integer_problem,
                                is_integer)
from cosim.results.csv_writer import RowFormatter

NUMPY = {"Int8": np.int8, "UInt8": np.uint8, "Int16": np.int16, "UInt16": np.uint16,
         "Int32": np.int32, "UInt32": np.uint32, "Int64": np.int64, "UInt64": np.uint64}


@pytest.mark.parametrize("source", sorted(NUMPY))
def test_exact_into_float64_is_what_float64_holds(source):
    """A type is exact into Float64 when its extreme values survive a float64 round trip."""
    info = np.iinfo(NUMPY[source])
    survives = all(int(float(v)) == v for v in (int(info.min), int(info.max)))
    assert exact_into(source, "Float64") == survives


@pytest.mark.parametrize("source", sorted(NUMPY))
@pytest.mark.parametrize("destination", sorted(NUMPY))
def test_exact_between_integers_is_range_inclusion(source, destination):
    src, dst = np.iinfo(NUMPY[source]), np.iinfo(NUMPY[destination])
    assert exact_into(source, destination) == (dst.min <= src.min and src.max <= dst.max)


def test_floats_into_integers_and_booleans_need_convert():
    for destination in ("Integer", "Int32", "Boolean", "Enumeration"):
        assert not exact_into("Float64", destination) and not exact_into("Float32", destination)
    assert exact_into("Boolean", "Int8") and not exact_into("Int8", "Boolean")
    assert exact_into("Int16", "Float32") and not exact_into("Int32", "Float32")
    assert not exact_into("Float64", "Float32") and exact_into("Float32", "Float64")


def test_integer_inputs_take_integer_values_in_range():
    assert integer_problem(3.0, "Int8") is None and integer_problem(-128.0, "Int8") is None
    assert integer_problem(2.5, "Integer") == ("is not an integer (an Integer input takes "
                                               "integer values only)")
    assert integer_problem(float("nan"), "Int32").startswith("is not an integer")
    assert integer_problem(128.0, "Int8") == "is outside the range of Int8 [-128, 127]"
    assert integer_problem(2.0, "Boolean") == "is outside the range of Boolean [0, 1]"
    assert all(is_integer(t) for t in INTEGER_RANGES) and not is_integer("Float32")


def test_a_64_bit_integer_is_inexact_only_where_float64_rounds_it():
    assert not inexact_integer(2 ** 53) and inexact_integer(2 ** 53 + 1)
    assert not inexact_integer(2 ** 53 + 2) and not inexact_integer(-2 ** 63)
    assert inexact_integer(2 ** 64 - 1) and inexact_integer(-(2 ** 53) - 1)


def test_integer_columns_are_written_as_integers():
    rows = np.array([[0.1, 3.0, 3.0, -0.0], [0.2, 2.0 ** 53, 1.5, 1.0]])
    text = RowFormatter(4, integers={1, 3}).format(rows.tobytes())
    assert text == "0.1,3,3.0,0\n0.2,9007199254740992,1.5,1\n"
