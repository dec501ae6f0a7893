"""Wire format of the lockstep exchange: one header, then packed float64 values.

A message is a 32-byte little-endian header (kind, seq, tick as int64, then
t as float64) followed either by the signal values of a port list or by a
UTF-8 JSON document for control messages. Float values round-trip bit for bit
(raw IEEE 754 bytes, no text). The header, the kinds and the JSON messages
live in `wire` (no numpy) and are re-exported.

A port list of scalars only is packed as one float64 per port, in declared
order. A port list with arrays (a planner's trajectory window) is packed as
one byte per array port (1: sent in this message, 0: held), padded to 8 bytes,
then every scalar in declared order, then the sent arrays in declared order.
An array is held when its bytes are those it had in the previous message of
the same direction: the window changes once per planner step, not every tick,
so most requests to a controller carry its scalars only, and the receiving
`Layout` hands out the array it kept, the very same read-only object (which a
controller can recognize without comparing bytes). Each `Layout` object is one
end of one direction of one component's exchange; a START message sends and
receives every array afresh (`forget`).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from cosim.component import Port, Value, is_frozen
from cosim.engine.values import picker, value_problem
# the stdlib-only part of the wire format, re-exported: one import for both halves
from cosim.transport.zenoh.wire import (HEADER, CodecError, Kind, decode_json,  # noqa: F401
                                        encode_json, header_tick)

__all__ = ["HEADER", "CodecError", "Kind", "Layout", "decode_json", "encode_json",
           "header_tick", "ports_from_json", "ports_to_json", "value_problem"]

_SENT = 1  # the mask byte of an array in the message (0: held)


class Layout:
    """The packing of a fixed port list into float64 slots, one end of one direction.

    Args:
        ports: the ports in declared order; their sizes fix the slot layout.
        role: "input" or "output", the word error messages name the ports with.
    """

    def __init__(self, ports: Sequence[Port], role: str = "output") -> None:
        self.ports = tuple(ports)
        self.role = role
        self.names = tuple(p.name for p in self.ports)
        self.size = sum(p.size for p in self.ports)
        self.scalar_only = all(p.size == 1 for p in self.ports)
        self._struct = struct.Struct(f"<qqqd{self.size}d")
        self._pick = picker(self.names)
        self._scalar_at = tuple(i for i, p in enumerate(self.ports) if p.size == 1)  # declared positions
        self._array_at = tuple(i for i, p in enumerate(self.ports) if p.size > 1)
        self._scalars_of = picker(self._scalar_at)  # the scalars of a declared-order sequence
        # `decode`'s mapping: the scalars, then the arrays, as the in-process master builds it
        # (a component that iterates its inputs sees the same order on both transports)
        mapping_order = self._scalar_at + self._array_at
        self._mapping_names = tuple(self.names[i] for i in mapping_order)
        self._in_mapping_order = picker(mapping_order)
        self._arrays = tuple((p.name, p.size) for p in self.ports if p.size > 1)
        self._mask_size = -(-len(self._arrays) // 8) * 8
        self._scalars = struct.Struct(f"<{len(self._scalar_at)}d")
        self._values_at = HEADER.size + self._mask_size  # where the scalars start
        self._arrays_at = self._values_at + self._scalars.size
        self._sent: list[tuple[Any, bytes] | None] = []  # per array port: (object, bytes)
        self._kept: list[np.ndarray | None] = []  # per array port: the last one received
        self.forget()

    def forget(self) -> None:
        """Start afresh: send every array in the next message and expect every one in the
        next received (both ends of a direction call it at START)."""
        self._sent = [None] * len(self._arrays)
        self._kept = [None] * len(self._arrays)

    def encode(self, kind: int, seq: int, tick: int, t: float, values: Mapping[str, Value],
               finite: bool = False) -> bytes:
        """Header plus every port's value; raises CodecError naming a bad port.

        Args:
            kind, seq, tick, t: the header fields.
            values: one value per port (float for size 1, array of the port's size).
            finite: also reject NaN and infinite values.
        """
        try:
            picked = self._pick(values)
        except (KeyError, TypeError):
            raise CodecError(self.problem(values) or "not packable") from None
        return self.encode_values(kind, seq, tick, t, picked, finite, values)

    def encode_values(self, kind: int, seq: int, tick: int, t: float, values: Sequence[Value],
                      finite: bool = False, named: Mapping[str, Value] | None = None) -> bytes:
        """`encode` of the port values given in declared order (the values lane).

        Args:
            kind, seq, tick, t, finite: as for `encode`.
            values: one value per port, in declared order.
            named: the same values by name if the caller has them (for error messages).
        """
        if self.scalar_only:
            try:
                message = self._struct.pack(kind, seq, tick, t, *values)
            except (TypeError, struct.error):
                raise CodecError(self._values_problem(values, named) or "not packable") from None
            if finite and not all(map(math.isfinite, values)):
                raise CodecError(self._values_problem(values, named))
            return message
        if len(values) != len(self.ports):
            raise CodecError(self._values_problem(values, named))
        floats = self._scalars_of(values)
        try:
            scalars = self._scalars.pack(*floats)
        except (TypeError, struct.error):
            raise CodecError(self._values_problem(values, named) or "not packable") from None
        if finite and not all(map(math.isfinite, floats)):
            raise CodecError(self._values_problem(values, named))
        mask = bytearray(self._mask_size)
        sent = [self._changed(index, values[at], values, named)
                for index, at in enumerate(self._array_at)]
        for index, data in enumerate(sent):
            if data:
                mask[index] = _SENT
        body = b"".join(filter(None, sent))
        if finite and body and not np.isfinite(np.frombuffer(body)).all():  # one test for all
            raise CodecError(self._values_problem(values, named))
        return b"".join([HEADER.pack(kind, seq, tick, t), mask, scalars, body])

    def _values_problem(self, values: Sequence[Value], named: Mapping[str, Value] | None) -> str:
        """`problem` of values given in declared order."""
        if named is not None:
            return self.problem(named)
        try:
            count = len(values)
        except TypeError:
            return f"returned {type(values).__name__}, expected a sequence of {len(self.ports)} values"
        if count != len(self.ports):
            return f"returned {count} values for {len(self.ports)} {self.role}s {list(self.names)}"
        return self.problem(dict(zip(self.names, values)))

    def _changed(self, index: int, value: Any, values: Sequence[Value],
                 named: Mapping[str, Value] | None) -> bytes | None:
        """The bytes of array port `index` if they differ from those last sent, else None."""
        last = self._sent[index]
        frozen = is_frozen(value)
        if frozen and last is not None and value is last[0]:
            return None  # the same read-only array as last time: the same bytes
        try:
            array = np.asarray(value, dtype="<f8")
        except (TypeError, ValueError):
            array = None
        if array is None or array.shape != (self._arrays[index][1],):
            raise CodecError(self._values_problem(values, named) or "not packable")
        data = array.tobytes()
        self._sent[index] = (value if frozen else None, data)
        if last is not None and data == last[1]:
            return None
        return data

    def decode(self, data: bytes) -> dict[str, Value]:
        """The port values of a message made by `encode` (floats, read-only arrays), the
        scalars first, then the arrays (each in declared order)."""
        return dict(zip(self._mapping_names, self._in_mapping_order(self.decode_values(data))))

    def decode_values(self, data: bytes) -> tuple[Value, ...]:
        """The port values of a message, in declared order (the values lane)."""
        if self.scalar_only:
            if len(data) != self._struct.size:
                raise CodecError(f"message of {len(data)} bytes, expected {self._struct.size} "
                                 f"for ports {list(self.names)}")
            return self._struct.unpack(data)[4:]
        if len(data) < self._arrays_at:
            raise CodecError(f"message of {len(data)} bytes, shorter than the "
                             f"{self._arrays_at} of ports {list(self.names)} without arrays")
        out: list[Value] = [0.0] * len(self.ports)
        for at, value in zip(self._scalar_at, self._scalars.unpack_from(data, self._values_at)):
            out[at] = value
        at, kept = self._arrays_at, self._kept
        for index, (name, size) in enumerate(self._arrays):
            mark = data[HEADER.size + index]
            if mark == _SENT:
                if at + 8 * size > len(data):
                    raise CodecError(f"message of {len(data)} bytes ends inside {self.role} "
                                     f"{name!r} (ports {list(self.names)})")
                array = np.frombuffer(data, dtype="<f8", count=size, offset=at).copy()
                array.flags.writeable = False
                kept[index] = array
                at += 8 * size
            elif mark != 0:
                raise CodecError(f"mask byte {mark} of {self.role} {name!r} is neither 0 "
                                 f"(held) nor 1 (sent)")
            elif kept[index] is None:
                raise CodecError(f"{self.role} {name!r} held before it was ever sent")
            out[self._array_at[index]] = kept[index]
        if at != len(data):
            raise CodecError(f"message of {len(data)} bytes, expected {at} for ports {list(self.names)}")
        return tuple(out)

    def problem(self, values: Any) -> str:
        """Why `values` cannot be packed, naming the first bad port, or "" if it can."""
        role = self.role
        if not isinstance(values, Mapping):
            return f"returned {type(values).__name__}, expected a mapping of {role} signals"
        for port in self.ports:
            if port.name not in values:
                return f"{role} {port.name!r} missing"
            problem = value_problem(values[port.name], port.size)
            if problem:
                return f"{role} {port.name!r} {problem}"
        return ""


def ports_to_json(ports: Sequence[Port]) -> list[dict[str, Any]]:
    """Port declarations as JSON-able dicts (for the handshake)."""
    return [{"name": p.name, "size": p.size, "unit": p.unit,
             "description": p.description, "default": p.default, "type": p.type} for p in ports]


def ports_from_json(items: Sequence[Mapping[str, Any]]) -> tuple[Port, ...]:
    """Port declarations back from `ports_to_json`."""
    return tuple(Port(name=str(i["name"]), size=int(i["size"]), unit=str(i["unit"]),
                      description=str(i["description"]), default=float(i["default"]),
                      type=str(i.get("type", "Float64")))
                 for i in items)
