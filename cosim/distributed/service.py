"""What the long-running services (`cosim worker`, `cosim router`) share: how
they learn that they should stop.

A service waits on a `threading.Event`; in the main thread SIGTERM and SIGINT
set it, so the service leaves its loop and closes its Zenoh session cleanly
(a session left open at exit can hang the process; see DESIGN.md).
"""

from __future__ import annotations

import signal
import threading


def stop_event_with_signals(stop_event: threading.Event | None = None) -> threading.Event:
    """The event that ends a service, set by SIGTERM/SIGINT when called in the main thread.

    Args:
        stop_event: the caller's event (None: a new one, which only the signals set).
            Outside the main thread the signal handlers are left alone (Python
            allows them only there); the caller then stops the service by the event.

    Returns:
        The event to wait on.
    """
    stop_event = stop_event or threading.Event()
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGTERM, signal.SIGINT):
            signal.signal(sig, lambda *_: stop_event.set())
    return stop_event
