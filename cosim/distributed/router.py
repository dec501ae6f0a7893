"""`cosim router`: a Zenoh router for networks where peers cannot reach each other.

Masters, workers and component processes that connect to the router reach
each other through it (Zenoh routes between the peers attached to a router),
so only the router needs an address everyone can reach. It runs from Python
alone (mode "router"; `zenohd` is not on PyPI) and follows the same
deployment settings (TLS, ACL) as the other sessions.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import zenoh

from cosim.distributed.deploy import DeploySettings, zenoh_config
from cosim.errors import UserError
from cosim.distributed.service import stop_event_with_signals


def run_router(settings: DeploySettings, stop_event: threading.Event | None = None,
               on_ready: Callable[[], None] | None = None) -> None:
    """Serve as a router until `stop_event` is set or SIGTERM/SIGINT arrives.

    Args:
        settings: `listen` endpoints (at least one), `connect` (other routers), TLS, ACL.
        stop_event: set it to end the router (None: only signals end it).
        on_ready: called once the router listens.
    """
    if not settings.listen:
        raise UserError("cosim router needs at least one --listen ENDPOINT")
    stop_event = stop_event_with_signals(stop_event)
    conf = zenoh_config(settings, "router", settings.listen, settings.connect)
    try:
        session = zenoh.open(conf)
    except zenoh.ZError as exc:
        raise UserError(f"router cannot listen on {settings.listen}: {exc}") from None
    with session:
        if on_ready is not None:
            on_ready()
        while not stop_event.wait(0.2):
            pass
