"""Zenoh session configurations and the run-scoped key expressions.

Every session is a peer with multicast scouting off and explicit endpoints
(DESIGN.md, "Zenoh: measured facts"): the master listens on one TCP endpoint,
component processes and watchers connect to it. All keys live under
`cosim/<run_id>/`, so runs sharing a network never see each other's traffic;
the sessions of a run authenticate with its credential (`auth`).
"""

from __future__ import annotations

import json
import re
import socket
from typing import Any

import zenoh

_CHUNK = re.compile(r"^[A-Za-z0-9_.\-]+$")


def check_key_chunk(value: str, what: str) -> str:
    """Return `value` if it can be one chunk of a key expression, else raise ValueError.

    Args:
        value: a run id or a component name.
        what: what the value is, for the error message ("run_id", "component name").
    """
    if not isinstance(value, str) or not _CHUNK.match(value):
        raise ValueError(f"{what} {value!r} must be non-empty and use only letters, digits, "
                         f"'_', '.' and '-' (it becomes a Zenoh key chunk)")
    return value


def request_key(run_id: str, name: str) -> str:
    """Key on which the master sends requests to component `name`."""
    return f"cosim/{run_id}/ctl/{name}/req"


def reply_key(run_id: str, name: str) -> str:
    """Key on which component `name` replies to the master ("*" for all components)."""
    return f"cosim/{run_id}/ctl/{name}/rep"


def alive_key(run_id: str, name: str) -> str:
    """Liveliness token key of component `name` ("*" for all components)."""
    return f"cosim/{run_id}/alive/{name}"


def master_alive_key(run_id: str) -> str:
    """Liveliness token key of the master of a run."""
    return f"cosim/{run_id}/master"


def live_data_key(run_id: str) -> str:
    """Key on which the master publishes every tick's signal vector ("*": all runs)."""
    return f"cosim/{run_id}/live/data"


def live_names_key(run_id: str) -> str:
    """Key of the queryable that answers the signal names of a run's live vector."""
    return f"cosim/{run_id}/live/names"


def run_id_of_live_key(key: str) -> str:
    """The run id inside a key made by `live_data_key`."""
    return key.split("/")[1]


def free_tcp_endpoint(host: str = "127.0.0.1") -> str:
    """A TCP endpoint on a port that is free right now (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((host, 0))
        port = sock.getsockname()[1]
    return f"tcp/{host}:{port}"


def _peer_config(listen: list[str], connect: list[str],
                 security: dict[str, Any] | None = None) -> zenoh.Config:
    settings: dict[str, Any] = {
        "mode": "peer",
        "listen": {"endpoints": listen},
        "connect": {"endpoints": connect},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
        **(security or {}),
    }
    return zenoh.Config.from_json5(json.dumps(settings))


def master_config(listen_endpoint: str, connect: list[str] | None = None,
                  security: dict[str, Any] | None = None) -> zenoh.Config:
    """Config of the master's session.

    Args:
        listen_endpoint: where components and watchers connect, e.g. "tcp/127.0.0.1:7447".
        connect: extra endpoints to join (another master, a router), or None.
        security: authentication and ACL blocks (`cosim.transport.zenoh.auth.security_settings`),
            or None for a plain session.
    """
    return _peer_config([listen_endpoint], list(connect or []), security)


def client_peer_config(connect_endpoint: str,
                       security: dict[str, Any] | None = None) -> zenoh.Config:
    """Config of a component process or a watcher: a peer that only connects.

    Args:
        connect_endpoint: the master's listen endpoint.
        security: the run's credential block (see `master_config`), or None.
    """
    return _peer_config([], [connect_endpoint], security)
