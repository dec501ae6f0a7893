"""Reading and writing an FMU's variables of every numeric type, and FMI 3 arrays.

`TypedIO` groups an FMU's inputs and outputs by the FMI function that moves
them (fmi2GetReal/Integer/Boolean; fmi3GetFloat64/Float32/Int8.../Boolean,
FMI 3 Enumeration through Int64), once at setup, and calls each group's C
function directly with preallocated ctypes arrays; an FMI 3 array is a run of
values of its group. Values go to the master as float64 (arrays as float64
numpy arrays): exact for every type, except a 64-bit integer that float64
cannot hold exactly, which fails the run (naming component, signal, tick and
value) instead of being rounded. A value written to an integer or Boolean
input must be integer-valued and in its type's range, else the same kind of
failure (`cosim.signal_types`).

`TypedFmuComponent` is the co-simulation host with this I/O; `hosted_fmu`
picks it only for FMUs that have a non-Float64 or an array port, so a
Real-only FMU keeps the plain host's step path (`cosim.fmu.host`).
"""

from __future__ import annotations

import ctypes
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
from fmpy.fmi1 import FMICallException

from cosim.component import Port, Value
from cosim.errors import ComponentFailure, StopRequested
from cosim.fmu.host import FmuComponent
from cosim.signal_types import FLOAT_TYPES, inexact_integer, integer_problem, is_integer

#: FMI type -> (C function suffix, ctypes type)
_FMI2 = {"Float64": ("Real", ctypes.c_double), "Integer": ("Integer", ctypes.c_int),
         "Enumeration": ("Integer", ctypes.c_int), "Boolean": ("Boolean", ctypes.c_int)}
_FMI3 = {"Float64": ("Float64", ctypes.c_double), "Float32": ("Float32", ctypes.c_float),
         "Int8": ("Int8", ctypes.c_int8), "UInt8": ("UInt8", ctypes.c_uint8),
         "Int16": ("Int16", ctypes.c_int16), "UInt16": ("UInt16", ctypes.c_uint16),
         "Int32": ("Int32", ctypes.c_int32), "UInt32": ("UInt32", ctypes.c_uint32),
         "Int64": ("Int64", ctypes.c_int64), "UInt64": ("UInt64", ctypes.c_uint64),
         "Enumeration": ("Int64", ctypes.c_int64), "Boolean": ("Boolean", ctypes.c_bool)}
_WIDE = (ctypes.c_int64, ctypes.c_uint64)


def needs_typed_io(interface: Any) -> bool:
    """Whether an FMU has a port the Float64-only host cannot move (another type, an array)."""
    return any(p.type not in FLOAT_TYPES or p.size != 1
               for p in (*interface.inputs, *interface.outputs))


def hosted_fmu(name: str, path: Any, interface: Any, parameters: Mapping[str, float],
               period_ticks: int, log_file: Any = None, use_shim: bool = True) -> FmuComponent:
    """The co-simulation host for an FMU: `TypedFmuComponent` when it needs typed I/O."""
    kind = TypedFmuComponent if needs_typed_io(interface) else FmuComponent
    return kind(name, path, interface, parameters, period_ticks, log_file, use_shim)


class _Group(NamedTuple):
    """The ports one FMI function moves: value references, values, (port, offset) pairs."""

    function: str
    ctype: Any
    vrs: Any
    values: Any
    ports: list[tuple[Port, int]]


def _groups(ports: Sequence[Port], vrs: Mapping[str, int], fmi3: bool, verb: str) -> list[_Group]:
    table = _FMI3 if fmi3 else _FMI2
    by_function: dict[str, list[Port]] = {}
    for port in ports:
        by_function.setdefault(table[port.type][0], []).append(port)
    groups = []
    for suffix, members in by_function.items():
        ctype = next(c for s, c in table.values() if s == suffix)
        offsets = np.cumsum([0] + [p.size for p in members]).tolist()
        groups.append(_Group(f"fmi{3 if fmi3 else 2}{verb}{suffix}", ctype,
                             (ctypes.c_uint * len(members))(*[vrs[p.name] for p in members]),
                             (ctype * offsets[-1])(), list(zip(members, offsets))))
    return groups


class TypedIO:
    """Sets an FMU's inputs and gets its outputs, of any numeric type (see the module).

    Args:
        component: the component's name, for failures.
        fmu: the instantiated fmpy FMU object (co-simulation or Model Exchange).
        fmi3: FMI 3 (else FMI 2).
        inputs, outputs: the ports (with their FMI types).
        vrs: canonical name -> value reference.
    """

    def __init__(self, component: str, fmu: Any, fmi3: bool, inputs: Sequence[Port],
                 outputs: Sequence[Port], vrs: Mapping[str, int]) -> None:
        self.component, self.fmi3, self.tick = component, fmi3, None
        self._fmu = fmu
        self._set = _groups(inputs, vrs, fmi3, "Set")
        self._get = _groups(outputs, vrs, fmi3, "Get")

    def _call(self, group: _Group) -> None:
        count = len(group.vrs)
        args = (len(group.values),) if self.fmi3 else ()
        status = self._fmu._functions[group.function](self._fmu.component, group.vrs, count,
                                                      group.values, *args)
        if status > 1:
            raise FMICallException(group.function, status)

    def set(self, inputs: Mapping[str, Value], t: float) -> None:
        """Write the inputs (checked against their types) to the FMU."""
        for group in self._set:
            for port, offset in group.ports:
                values = np.ravel(inputs[port.name]).tolist()
                if is_integer(port.type):
                    values = [self._integer(port, v, t) for v in values]
                group.values[offset:offset + port.size] = values
            self._call(group)

    def _integer(self, port: Port, value: float, t: float) -> int:
        problem = integer_problem(value, port.type)
        if problem:
            raise ComponentFailure(self.component, self.tick, t, f"input {port.name!r} = "
                                   f"{value!r} {problem}", {"kind": "value", "signal": port.name})
        return int(value)

    def get(self, t: float) -> dict[str, Value]:
        """Read the outputs: floats for scalars, float64 arrays for arrays."""
        out: dict[str, Value] = {}
        for group in self._get:
            self._call(group)
            values = group.values[:]
            for port, offset in group.ports:
                if group.ctype in _WIDE:
                    self._check_exact(port, values[offset:offset + port.size], t)
                if port.size == 1:
                    out[port.name] = float(values[offset])
                else:
                    out[port.name] = np.array(values[offset:offset + port.size], dtype=np.float64)
        return out

    def _check_exact(self, port: Port, values: list[int], t: float) -> None:
        bad = next((v for v in values if inexact_integer(v)), None)
        if bad is not None:
            raise ComponentFailure(self.component, self.tick, t, f"output {port.name!r} = {bad} "
                                   f"({port.type}) cannot be recorded exactly: beyond 2^53, "
                                   "float64 (the signal store) would round it",
                                   {"kind": "value", "signal": port.name, "value": str(bad)})


class TypedFmuComponent(FmuComponent):
    """`FmuComponent` whose inputs and outputs go through `TypedIO` (any type, arrays).

    It steps in three calls from Python: the stepping shim and the master's
    values lane move Float64 scalars only.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.value_names = None  # no values lane: the ports are not all Float64 scalars

    def _bind_shim(self) -> None:
        """No shim step: the per-call path, whose set and get are TypedIO's."""

    def _bind(self) -> None:
        super()._bind()
        self._io = TypedIO(self.name, self._fmu, self.fmi3, self.inputs, self.outputs,
                           self.interface.value_references)

    def step(self, tick: int, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """As `FmuComponent.step`; a value failure names this tick."""
        self._io.tick, self.log.time = tick, t
        try:
            return self._step_per_call(tick, t, inputs)
        except (ComponentFailure, StopRequested):
            raise
        except Exception as exc:
            raise self._failure(tick, t, exc) from exc

    def _set_inputs(self, inputs: Mapping[str, Value]) -> None:
        self._io.set(inputs, self.log.time)

    def _get_outputs(self) -> dict[str, Value]:
        return self._io.get(self.log.time)
