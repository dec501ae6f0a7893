"""Wire format of the lockstep exchange: one header, then packed float64 values.

A message is a 32-byte little-endian header (kind, seq, tick as int64, then
t as float64) followed either by the signal values of a port list, packed
as one contiguous float64 byte string in declared port order (scalars as one
float, arrays flattened), or by a UTF-8 JSON document for control messages.
Float values round-trip bit for bit (raw IEEE 754 bytes, no text). The header,
the kinds and the JSON messages live in `wire` (no numpy) and are re-exported.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from cosim.component import Port, Value
from cosim.engine.values import picker, value_problem
# the stdlib-only part of the wire format, re-exported: one import for both halves
from cosim.transport.zenoh.wire import (HEADER, CodecError, Kind, decode_json,  # noqa: F401
                                        encode_json, header_tick)

__all__ = ["HEADER", "CodecError", "Kind", "Layout", "decode_json", "encode_json",
           "header_tick", "ports_from_json", "ports_to_json", "value_problem"]


class Layout:
    """The packing of a fixed port list into float64 slots.

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
        self._slices: list[tuple[str, int, int]] = []
        offset = 0
        for port in self.ports:
            self._slices.append((port.name, offset, port.size))
            offset += port.size

    def encode(self, kind: int, seq: int, tick: int, t: float, values: Mapping[str, Value],
               finite: bool = False) -> bytes:
        """Header plus every port's value; raises CodecError naming a bad port.

        Args:
            kind, seq, tick, t: the header fields.
            values: one value per port (float for size 1, array of the port's size).
            finite: also reject NaN and infinite values.
        """
        if self.scalar_only:
            try:
                floats = self._pick(values)
                message = self._struct.pack(kind, seq, tick, t, *floats)
            except (KeyError, TypeError, struct.error):
                raise CodecError(self.problem(values) or "not packable") from None
            if finite and not all(map(math.isfinite, floats)):
                raise CodecError(self.problem(values))
            return message
        buf = self.pack_array(values)
        if finite and not np.isfinite(buf).all():
            raise CodecError(self.problem(values))
        return HEADER.pack(kind, seq, tick, t) + buf.tobytes()

    def pack_array(self, values: Mapping[str, Value]) -> np.ndarray:
        """The values as one float64 vector in slot order; raises CodecError on a bad port."""
        buf = np.empty(self.size)
        try:
            for name, offset, size in self._slices:
                if size == 1:
                    buf[offset] = float(values[name])
                else:
                    array = np.asarray(values[name], dtype=np.float64)
                    if array.shape != (size,):
                        raise ValueError
                    buf[offset:offset + size] = array
        except (KeyError, TypeError, ValueError):
            raise CodecError(self.problem(values) or "not packable") from None
        return buf

    def decode(self, data: bytes) -> dict[str, Value]:
        """The port values of a message made by `encode` (floats, read-only arrays)."""
        if len(data) != self._struct.size:
            raise CodecError(f"message of {len(data)} bytes, expected {self._struct.size} "
                             f"for ports {list(self.names)}")
        if self.scalar_only:
            return dict(zip(self.names, self._struct.unpack(data)[4:]))
        flat = np.frombuffer(data, dtype="<f8", offset=HEADER.size)
        out: dict[str, Value] = {}
        for name, offset, size in self._slices:
            out[name] = float(flat[offset]) if size == 1 else flat[offset:offset + size]
        return out

    def problem(self, values: Any) -> str:
        """Why `values` cannot be packed, naming the first bad port, or "" if it can."""
        role = self.role
        if not isinstance(values, Mapping):
            return f"returned {type(values).__name__}, expected a mapping of {role} signals"
        for name, _, size in self._slices:
            if name not in values:
                return f"{role} {name!r} missing"
            problem = value_problem(values[name], size)
            if problem:
                return f"{role} {name!r} {problem}"
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
