"""`cosim run --foxglove [PORT]`: the running co-simulation over the Foxglove WebSocket protocol.

`FoxgloveLive` starts a Foxglove WebSocket server (foxglove-sdk) on loopback
and is a master observer. The server has no authentication, so it listens on
loopback addresses only (docs/foxglove.md: reach it from another machine
through an SSH tunnel), in line with docs/distributed.md's security model.

It never blocks the lockstep and never changes results:
- it only reads the signal store; nothing from a client reaches the run;
- with no client subscribed, `after_tick` is one attribute test;
- with a client, it copies the tick's scalars (and the trajectory windows)
  at most `rate` times per wall-clock second into a bounded queue (the
  oldest snapshot is dropped when full) and returns; a daemon thread encodes
  and sends them (`cosim.foxglove.channels`, the same channels as run.mcap),
  so a slow or stalled viewer only loses frames.
"""

from __future__ import annotations

import collections
import ipaddress
import logging
import re
import sys
import threading
import time
from pathlib import Path
from typing import Any

import foxglove
import numpy as np

from controllers.spec import SpecError
from cosim.errors import UserError
from cosim.foxglove.channels import Layout, RunChannels, nanoseconds

DEFAULT_PORT = 8765
DEFAULT_RATE = 30.0     # snapshots per wall-clock second sent to viewers
QUEUE = 256             # snapshots waiting for the sender thread, at most
IDLE_WAIT = 0.02        # s the sender sleeps when it has nothing to send


def check_loopback(host: str) -> str:
    """`host` if it is a loopback address or localhost; otherwise a UserError."""
    if host == "localhost":
        return host
    try:
        if ipaddress.ip_address(host).is_loopback:
            return host
    except ValueError:
        pass
    raise UserError(f"--foxglove-host {host!r}: the Foxglove server has no authentication and "
                    "listens on loopback only (127.0.0.1, ::1, localhost); from another machine, "
                    "tunnel to it: ssh -L 8765:127.0.0.1:8765 THIS_HOST")


class _Subscriptions:
    """Server listener counting the subscribed channels (a plain int the master reads)."""

    def __init__(self) -> None:
        self.count = 0
        self.fresh = False   # a new subscription: the sender sends the static scene again
        self._lock = threading.Lock()

    def on_subscribe(self, client: Any, channel: Any) -> None:
        with self._lock:
            self.count += 1
            self.fresh = True

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        with self._lock:
            self.count = max(0, self.count - 1)


def static_scene(scenario: Any) -> tuple[list, tuple[float, float, float]]:
    """(lane lines, vehicle body) of a loaded scenario, for the viewers; no lines if no road."""
    from cosim.analysis.road import lane_lines, scenario_road
    from cosim.analysis.rundata import RunData

    manifest = {"scenario": scenario.model_dump(mode="json", by_alias=True),
                "scenario_file": str(scenario.source_file) if scenario.source_file else None}
    run = RunData(Path("."), np.empty(0), {}, manifest)
    try:
        found = scenario_road(run)
        lines = lane_lines(found) if found is not None else []
    except SpecError:
        lines = []
    metrics = scenario.metrics
    front = metrics.vehicle_front if metrics.vehicle_front is not None else 0.5 * metrics.vehicle_length
    return lines, (metrics.vehicle_length, metrics.vehicle_width, front)


_NOT_A_CLIENT = re.compile(r"^Dropping client \S+: handshake failed$")


class _SdkLog(logging.StreamHandler):
    """The Foxglove SDK's log records on stderr, one line each, without the refused
    handshakes (logged at ERROR level by the SDK, for every connection that is no
    WebSocket client)."""

    def __init__(self) -> None:
        super().__init__(sys.stderr)
        self.setFormatter(logging.Formatter("foxglove: %(message)s"))
        self.addFilter(lambda record: not _NOT_A_CLIENT.match(record.getMessage()))

    def emit(self, record: logging.LogRecord) -> None:
        self.stream = sys.stderr  # the current one (a test's capture replaces it)
        super().emit(record)


def _quiet_sdk_log() -> None:
    """Route the SDK's logger (and its children) to `_SdkLog` once, not to the root's."""
    sdk = logging.getLogger("foxglove")
    if not any(isinstance(h, _SdkLog) for h in sdk.handlers):
        sdk.addHandler(_SdkLog())
        sdk.propagate = False


class FoxgloveLive:
    """Foxglove WebSocket server and master observer (see the module docstring).

    Args:
        port: TCP port (0: any free port; `port` tells which after start()).
        host: a loopback address.
        rate: snapshots per wall-clock second sent while a client is subscribed.
        static: (lane lines, vehicle body) logged once when the run begins.
    """

    def __init__(self, port: int = DEFAULT_PORT, host: str = "127.0.0.1", rate: float = DEFAULT_RATE,
                 static: tuple[list, tuple[float, float, float]] | None = None) -> None:
        self.host = check_loopback(host)
        if not 0 <= port <= 65535:
            raise UserError(f"--foxglove: expected a TCP port 0..65535, got {port}")
        self.requested_port, self.rate, self.static = port, rate, static
        self.subscriptions = _Subscriptions()
        self.context = foxglove.Context()
        self.server: Any = None
        self.sent = self.dropped = 0
        self._queue: collections.deque = collections.deque(maxlen=QUEUE)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._channels: RunChannels | None = None

    @property
    def port(self) -> int:
        """The port the server listens on."""
        return self.server.port if self.server is not None else self.requested_port

    @property
    def url(self) -> str:
        """ws:// address to open in Foxglove."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"

    def start(self) -> "FoxgloveLive":
        """Start the server; a UserError when the port cannot be bound. The SDK's messages
        go to stderr as "foxglove: ...", except its line per connection that is no
        Foxglove client (any local port scan would fill the run's terminal)."""
        _quiet_sdk_log()
        try:
            self.server = foxglove.start_server(name="cosim", host=self.host, port=self.requested_port,
                                                context=self.context, server_listener=self.subscriptions)
        except Exception as exc:  # the SDK raises a plain RuntimeError for a busy port
            raise UserError(f"--foxglove: cannot listen on {self.host}:{self.requested_port}: {exc}") from None
        self._thread = threading.Thread(target=self._send_loop, name="foxglove-live", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Send what is queued, then stop the sender and the server (safe to call twice)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        if self.server is not None:
            self.server.stop()
            self.server = None

    def __enter__(self) -> "FoxgloveLive":
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.stop()

    # ---- observer -------------------------------------------------------------
    def begin(self, master: Any) -> None:
        """Channels from the master's layout; the static scene is queued for the sender."""
        columns = master.layout.scalar_columns()
        arrays = master.layout.array_signals()
        self._index = [i for _, i in columns]
        self._offsets = {f"{c}.{s}": (off, off + size) for c, s, off, size in arrays}
        layout = Layout.of([n for n, _ in columns], list(self._offsets))
        self._windows = [(self._offsets[x], self._offsets[y]) for _, x, y in layout.windows]
        self._channels = RunChannels(self.context, layout)
        self._last = 0.0

    def after_tick(self, tick: int, t: float, values: list[float], arrays: Any) -> None:
        """Snapshot for the sender while a client is subscribed, at most `rate` per second."""
        if not self.subscriptions.count:
            return
        now = time.monotonic()
        if now - self._last < 1.0 / self.rate:
            return
        self._last = now
        windows = [(arrays[a:b].tolist(), arrays[c:d].tolist()) for (a, b), (c, d) in self._windows]
        if len(self._queue) == QUEUE:
            self.dropped += 1
        self._queue.append((t, [values[i] for i in self._index], windows))

    # ---- sender thread ---------------------------------------------------------
    def _send_loop(self) -> None:
        while True:
            try:
                t, row, windows = self._queue.popleft()
            except IndexError:
                if self._stop.is_set():
                    return
                time.sleep(IDLE_WAIT)
                continue
            channels = self._channels
            if self.subscriptions.fresh and self.static is not None:  # not latched: once per subscriber
                self.subscriptions.fresh = False
                channels.log_static(*self.static, nanoseconds(t))
            channels.log_tick(t, row)
            for k, (xs, ys) in enumerate(windows):
                channels.log_window(k, t, xs, ys)
            self.sent += 1
