"""Live observation of a run's signals over Zenoh.

The master publishes the whole signal vector of every tick on
`cosim/<run_id>/live/data` (header: LIVE, names version, tick, t; then the
float64 values), only when some subscriber matches, so an unwatched run pays
almost nothing: a matching listener keeps `LivePublisher.matching` up to date
as a plain attribute (asking Zenoh for the matching status costs microseconds;
the listener also reports subscribers that were there before it). The names
of the vector are answered by a queryable on
`cosim/<run_id>/live/names`, and also sent in band (a NAMES message on the data
key ahead of the first vector that uses them). `watch` is the other end, for
another process; it needs the run's credential (or a deployment file's
session), and says so within seconds when it cannot link to the master.
"""

from __future__ import annotations

import contextlib
import json
import time
from collections.abc import Iterator, Sequence

import numpy as np
import zenoh

from cosim.transport.zenoh import auth, config
from cosim.transport.zenoh.auth import Credential
from cosim.transport.zenoh.wire import HEADER, Kind

NAMES_QUERY_TIMEOUT_S = 2.0
CONNECT_TIMEOUT_S = 5.0
WATCH_QUEUE = 4096  # samples kept for a slow watcher; older ones are dropped


class LivePublisher:
    """Publishes a run's signal vectors; answers queries for their names.

    Args:
        session: the master's open session.
        run_id: the run's id.
    """

    def __init__(self, session: zenoh.Session, run_id: str) -> None:
        self._publisher = session.declare_publisher(
            config.live_data_key(run_id), congestion_control=zenoh.CongestionControl.DROP)
        self.matching = False  # True while at least one subscriber listens (see module doc)
        self._listener = self._publisher.declare_matching_listener(self._on_matching)
        self._names: list[str] = []
        self._names_ref: object = None  # the caller's list: an identity check per tick
        self._version = 0
        self._queryable = session.declare_queryable(config.live_names_key(run_id),
                                                    self._answer_names)

    def _on_matching(self, status: zenoh.MatchingStatus) -> None:
        self.matching = status.matching

    def publish(self, tick: int, t: float, names: Sequence[str], values: np.ndarray) -> None:
        """Publish one tick's signal vector if anybody listens.

        Args:
            tick: the master tick.
            t: its simulation time.
            names: one name per element of `values` (the same list object each tick is cheapest).
            values: float64 vector of every signal at this tick.
        """
        if not self.matching:
            return
        if names is not self._names_ref and list(names) != self._names:
            self._set_names(names, values)
        body = np.ascontiguousarray(values, dtype=np.float64)
        if body.size != len(self._names):
            raise ValueError(f"live publish at tick {tick}: {body.size} values for "
                             f"{len(self._names)} names")
        self._publisher.put(HEADER.pack(Kind.LIVE, self._version, tick, t) + body.tobytes())

    def close(self) -> None:
        """Tell watchers the run is over; undeclare everything."""
        self._publisher.put(HEADER.pack(Kind.END, self._version, -1, 0.0))
        self._queryable.undeclare()
        self._listener.undeclare()
        self._publisher.undeclare()

    def _set_names(self, names: Sequence[str], values: np.ndarray) -> None:
        if len(names) != np.size(values):
            raise ValueError(f"live publish: {np.size(values)} values for {len(names)} names")
        self._version += 1
        # Replace the whole tuple so the query callback always sees a consistent pair.
        self._names_doc = json.dumps({"version": self._version, "names": list(names)})
        self._names = list(names)
        self._names_ref = names
        # in band too, ahead of the first vector that uses them: a watcher that was
        # already listening needs no query (which could come too late at a run's end)
        self._publisher.put(HEADER.pack(Kind.NAMES, self._version, -1, 0.0)
                            + self._names_doc.encode())

    def _answer_names(self, query: zenoh.Query) -> None:
        document = getattr(self, "_names_doc", json.dumps({"version": 0, "names": []}))
        query.reply(query.key_expr, document.encode())


def _fetch_names(session: zenoh.Session, run_id: str) -> tuple[int, list[str]]:
    """Ask a run's master for the names of its live vector: (version, names)."""
    for reply in session.get(config.live_names_key(run_id), timeout=NAMES_QUERY_TIMEOUT_S):
        if reply.ok is not None:
            document = json.loads(reply.ok.payload.to_bytes())
            return int(document["version"]), [str(n) for n in document["names"]]
    raise TimeoutError(f"run {run_id!r}: no answer on {config.live_names_key(run_id)}")


def _wait_linked(session: zenoh.Session, endpoint: str) -> None:
    """Return once the session has a link to another node; ConnectionError after
    CONNECT_TIMEOUT_S (a peer that cannot authenticate keeps retrying in silence)."""
    end = time.monotonic() + CONNECT_TIMEOUT_S
    while not (list(session.info.peers_zid()) or list(session.info.routers_zid())):
        if time.monotonic() > end:
            raise ConnectionError(
                f"cannot open a session with {endpoint} within {CONNECT_TIMEOUT_S:g} s: "
                f"the credential or certificate is missing or not the run's, or the run "
                f"has ended")
        time.sleep(0.02)


def watch(run_id: str = "*", endpoint: str = "tcp/127.0.0.1:7447",
          credential: Credential | None = None, conf: zenoh.Config | None = None
          ) -> Iterator[tuple[int, float, dict[str, float]]]:
    """Yield (tick, t, {signal name: value}) for every tick a running master publishes.

    Blocks between ticks. With a given run id, ends when that run ends; with
    "*", watches every run reachable through `endpoint` until closed.

    Args:
        run_id: the run to watch, or "*" for any.
        endpoint: the master's listen endpoint, e.g. "tcp/127.0.0.1:7447".
        credential: the run's credential (its run folder's live.credential).
        conf: a whole session config instead (a deployment file's TLS), or None.
    Raises:
        ConnectionError when no authenticated link to the master opens within
        CONNECT_TIMEOUT_S (wrong credential or certificate, or nobody there).
    """
    with contextlib.closing(watch_runs(run_id, endpoint, credential, conf)) as runs:  # session closed at once
        for _, tick, t, values in runs:
            yield tick, t, values


def watch_runs(run_id: str = "*", endpoint: str = "tcp/127.0.0.1:7447",
               credential: Credential | None = None, conf: zenoh.Config | None = None
               ) -> Iterator[tuple[str, int, float, dict[str, float]]]:
    """Like `watch`, with the run id of each tick first (for watching "*").

    Args: as `watch`.
    """
    if run_id != "*":
        config.check_key_chunk(run_id, "run_id")
    if conf is None:
        conf = config.client_peer_config(endpoint, auth.security_settings(credential))
    try:
        session = zenoh.open(conf)
    except zenoh.ZError as exc:
        raise ConnectionError(f"cannot open a session to {endpoint}: {exc}") from None
    with session:
        _wait_linked(session, endpoint)
        subscriber = session.declare_subscriber(config.live_data_key(run_id),
                                                zenoh.handlers.RingChannel(WATCH_QUEUE))
        names: dict[str, tuple[int, list[str]]] = {}
        while True:
            sample = subscriber.recv()
            data = sample.payload.to_bytes()
            kind, version, tick, t = HEADER.unpack_from(data)
            run = config.run_id_of_live_key(str(sample.key_expr))
            if kind == Kind.END:
                if run_id != "*":
                    return
                continue
            if kind == Kind.NAMES:
                document = json.loads(data[HEADER.size:])
                names[run] = (int(document["version"]), [str(n) for n in document["names"]])
                continue
            if run not in names or names[run][0] != version:
                names[run] = _fetch_names(session, run)
                if names[run][0] != version:
                    continue  # names changed again since this sample: its names are gone
            values = np.frombuffer(data, dtype="<f8", offset=HEADER.size).tolist()
            yield run, tick, t, dict(zip(names[run][1], values))
