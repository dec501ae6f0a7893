"""Message header, message kinds and JSON control messages of the Zenoh transport.

The part of the wire format that needs only the standard library, so that
the master can spawn the component processes before it loads numpy (see
`cosim.transport.zenoh.codec` for the packed signal values).
"""

from __future__ import annotations

import json
import struct
from typing import Any

HEADER = struct.Struct("<qqqd")
"""kind, seq (request number, echoed by the reply), tick, t."""


class Kind:
    """What a message is (plain ints: enum member lookups are slow on the hot path)."""

    HELLO = 1      # master -> component: handshake request
    START = 2      # master -> component: initialize(t0, inputs)
    STEP = 3       # master -> component: step(t, inputs)
    STOP = 4       # master -> component: finish() and exit
    USE = 5        # master -> component: JSON {"outputs"}: use_outputs(outputs), before START
    PORTS = 11     # component -> master: JSON port declarations
    OUTPUTS = 12   # component -> master: packed outputs
    METRICS = 13   # component -> master: JSON final metrics
    ERROR = 14     # component -> master: JSON {"cause": text}
    USED = 15      # component -> master: JSON {} once use_outputs returned
    DIED = 21      # master watchdog -> master: JSON {"component", "cause"}
    TIMEOUT = 22   # master watchdog -> master: JSON {"component", "cause"}
    LIVE = 31      # master -> watchers: packed signal vector of one tick
    END = 32       # master -> watchers: the run is over
    NAMES = 33     # master -> watchers: JSON {"version", "names"} of the LIVE vectors


class CodecError(ValueError):
    """A value does not fit its declared port (missing, wrong shape, not a number)."""


def encode_json(kind: int, seq: int, tick: int, t: float, document: Any) -> bytes:
    """A control message: header plus a UTF-8 JSON document.

    Args:
        kind, seq, tick, t: the header fields.
        document: anything `json.dumps` accepts.
    """
    return HEADER.pack(kind, seq, tick, t) + json.dumps(document).encode()


def decode_json(data: bytes) -> Any:
    """The JSON document of a message made by `encode_json`.

    Args:
        data: the whole message, header included.
    """
    return json.loads(data[HEADER.size:].decode())


def header_tick(tick: int | None) -> int:
    """Tick as carried in the header: -1 stands for the initialization phase (None).

    Args:
        tick: the master tick, or None for the initialization phase.
    """
    return -1 if tick is None else tick
