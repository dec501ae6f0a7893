"""`cosim.fmu.solvers.finite_derivatives`: a derivative the FMU gives as NaN or infinite
stops the integration with its name (CVode would go on until it gave up, saying only
that it took too many steps); finite ones pass through untouched."""

from __future__ import annotations

import math
from ctypes import POINTER, c_double

import pytest

from cosim.fmu.solvers import NonFiniteDerivative, finite_derivatives


def _getter(values):
    """A stand-in for fmpy's getDerivatives(pointer, n): writes `values`."""
    def get_dx(pointer, count):
        for i in range(count):
            pointer[i] = values[i]
    return get_dx


def test_finite_derivatives_are_written_as_given():
    buffer = (c_double * 3)()
    finite_derivatives(_getter([1.5, -2.0, 0.0]), ["der(x)", "der(v)", "der(z)"])(
        buffer, 3)
    assert list(buffer) == [1.5, -2.0, 0.0]


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_the_first_non_finite_derivative_is_named(bad):
    buffer = (c_double * 3)()
    pointer = POINTER(c_double)(buffer)  # fmpy passes a pointer, not an array
    get_dx = finite_derivatives(_getter([1.0, bad, bad]), ["der(x)", "der(v)", "der(z)"])
    with pytest.raises(NonFiniteDerivative) as raised:
        get_dx(pointer, 3)
    assert str(raised.value) == f"the FMU's der(v) is {bad!r}"
    assert raised.value.details == {"kind": "non_finite_derivative", "derivative": "der(v)",
                                    "value": repr(bad)}
