"""`cosim worker`: a long-running agent that starts components on its host for masters.

    worker = Worker("w1", settings, allow=["controllers.", "cosim.sources"])
    worker.serve()              # until SIGTERM / SIGINT or `stop_event` is set

The worker opens one Zenoh peer session (endpoints, TLS and ACL from the
deployment settings), declares a liveliness token and a queryable under
`cosim/workers/<name>` and answers the requests of `cosim.distributed.protocol`.
A start request spawns the ordinary component runner
(`cosim.transport.zenoh.runner`) as a child process that connects back to the
master's endpoints; from then on master and component talk directly, the
worker only watches: when a child ends it puts an exit notice (exit code and
last output) on the run's key, so the master learns why. Only classes from
allowed module prefixes are started; the worker itself never imports what a
request names. A run's failure never ends the worker.

Security: a worker starts components only for masters it can authenticate
(a shared credential or TLS client certificates in its deployment settings:
nobody else can open a link to it); without either it refuses every start
unless it runs `insecure`. A child whose run's master does not show up within
`orphan_timeout_s`, or whose master disappears, is stopped and reaped. A stop
request must carry the run token of the start request (only the run that
started a component stops it), and at most `max_components` run at once.
"""

from __future__ import annotations

import hmac
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zenoh

from cosim.distributed import protocol as proto
from cosim.distributed.deploy import (DeploySettings, check_endpoint, session_mode, zenoh_config,
                          zenoh_settings)
from cosim.errors import UserError
from cosim.fmu.remote import FMU_HOST_CLASS, store_fmu
from cosim.transport.inproc import PythonComponentLaunch
from cosim.transport.launch import steps_from_json
from cosim.distributed.placement import RESERVED_HOSTS
from cosim.distributed.service import stop_event_with_signals
from cosim.transport.zenoh.config import check_key_chunk, master_alive_key
from cosim.transport.zenoh.processes import ChildProcess

POLL_S = 0.005
REAP_POLL_S = 0.05
STOP_GRACE_S = 1.5
MAX_COMPONENTS = 16
ORPHAN_TIMEOUT_S = 30.0


@dataclass
class _Hosted:
    """One component process and what the worker knows of its run."""

    child: ChildProcess
    run_id: str
    token: str         # the run token of its start request: a stop must repeat it
    started: float     # time.monotonic() of its start


class Worker:
    """One worker agent.

    Args:
        name: the worker's name (a key chunk: letters, digits, '_', '.', '-').
        settings: endpoints, TLS and ACL of its session.
        allow: module prefixes of the component classes it may start, in addition to
            `protocol.DEFAULT_ALLOW` (an empty or malformed prefix is refused).
        allow_fmu: whether masters may send FMUs (native code) to run here.
        insecure: start components even though nothing authenticates the masters.
        max_components: most component processes hosted at once.
        orphan_timeout_s: a child whose master has not appeared by then is ended.
    """

    def __init__(self, name: str, settings: DeploySettings | None = None,
                 allow: Sequence[str] = proto.DEFAULT_ALLOW, allow_fmu: bool = False, *,
                 insecure: bool = False, max_components: int = MAX_COMPONENTS,
                 orphan_timeout_s: float = ORPHAN_TIMEOUT_S) -> None:
        self.name = check_key_chunk(name, "worker name")
        if self.name in RESERVED_HOSTS:
            raise ValueError(f"worker name {name!r} is reserved: host: {name} (and --place NAME={name}) "
                             f"means {RESERVED_HOSTS[name]}")
        self.settings = settings or DeploySettings()
        self.allow = tuple(dict.fromkeys([*proto.DEFAULT_ALLOW,
                                          *(proto.check_prefix(p) for p in allow)]))
        self.host = socket.gethostname()
        self._children: dict[tuple[str, str], _Hosted] = {}
        self._masters: dict[str, Any] = {}        # run id -> liveliness subscriber of its master
        self._master_seen: dict[str, bool] = {}   # run id -> True alive, False gone
        self.insecure = bool(insecure)
        self.authenticated = self.settings.authenticates_peers()
        if max_components < 1 or not orphan_timeout_s > 0:
            raise UserError(f"worker {name!r}: --max-components must be >= 1 and "
                            f"--orphan-timeout > 0, got {max_components} and {orphan_timeout_s}")
        self.max_components = int(max_components)
        self.orphan_timeout_s = float(orphan_timeout_s)
        self._lock = threading.Lock()
        self._session: Any = None
        self.allow_fmu = bool(allow_fmu)
        # private (0700) and this process's own: a shared folder in /tmp would let another
        # local user plant an FMU under the name of a hash, which would then be run; made
        # once the session is open (`serve`) or at the first FMU, removed when serve ends
        self._fmu_cache: Path | None = None
        self.mode = session_mode(self.settings.listen, self.settings.connect)

    # ------------------------------------------------------------------ serving
    def serve(self, stop_event: threading.Event | None = None,
              on_ready: Callable[[], None] | None = None) -> None:
        """Answer requests until `stop_event` is set (or SIGTERM/SIGINT in the main thread).

        Args:
            stop_event: set it to end the worker (None: only signals end it).
            on_ready: called once the queryable and token are declared.
        """
        stop_event = stop_event_with_signals(stop_event)
        try:
            self._serve(stop_event, on_ready)
        finally:  # on every path, a failed start included: no cache folder left behind
            if self._fmu_cache is not None:
                shutil.rmtree(self._fmu_cache, ignore_errors=True)
                self._fmu_cache = None

    def _serve(self, stop_event: threading.Event,
               on_ready: Callable[[], None] | None) -> None:
        conf = zenoh_config(self.settings, self.mode, self.settings.listen, self.settings.connect)
        try:
            session = zenoh.open(conf)
        except zenoh.ZError as exc:
            raise UserError(f"worker {self.name!r}: cannot open its Zenoh session "
                            f"(listen {self.settings.listen}, connect {self.settings.connect}): "
                            f"{exc}") from None
        with session:
            self._session = session
            self._cache_folder()
            token = session.liveliness().declare_token(proto.worker_key(self.name))
            queryable = session.declare_queryable(proto.worker_key(self.name))
            reaper = threading.Thread(target=self._reap_loop, args=(stop_event,),
                                      name="cosim-worker-reaper", daemon=True)
            reaper.start()
            if on_ready is not None:
                on_ready()
            try:
                self._answer_until(queryable, stop_event)
            finally:
                stop_event.set()
                reaper.join()
                self._stop_all()
                queryable.undeclare()
                token.undeclare()

    def _cache_folder(self) -> Path:
        """The worker's private FMU cache folder (made on first use)."""
        if self._fmu_cache is None:
            self._fmu_cache = Path(tempfile.mkdtemp(prefix=f"cosim-worker-{self.name}-fmus-"))
        return self._fmu_cache

    def _answer_until(self, queryable: Any, stop_event: threading.Event) -> None:
        while not stop_event.is_set():
            query = queryable.try_recv()
            if query is None:
                time.sleep(POLL_S)
                continue
            try:
                reply = self.handle(query.payload.to_bytes() if query.payload else b"")
                query.reply(proto.worker_key(self.name), proto.encode(reply))
            finally:
                query.drop()

    # ------------------------------------------------------------------ requests
    def handle(self, data: bytes) -> dict[str, Any]:
        """The reply to one request (never raises for a bad request).

        Args:
            data: the request payload (JSON, see cosim.distributed.protocol).
        """
        try:
            request = proto.decode(data, f"request to worker {self.name!r}")
            op = request.get("op")
            if op == "info":
                return self.info()
            if op == "start":
                return {"ok": True, "pid": self._start(request)}
            if op == "stop":
                return {"ok": True, "exit_code": self._stop(request)}
            raise ValueError(f"unknown op {op!r} (info, start, stop)")
        except (ValueError, UserError, KeyError, TypeError) as exc:
            text = str(exc)
            if not text.startswith(f"worker {self.name!r}"):
                text = f"worker {self.name!r} on host {self.host!r}: {text}"
            return {"ok": False, "error": text}

    def info(self) -> dict[str, Any]:
        """What `cosim workers` shows of this worker."""
        with self._lock:
            running = len(self._children)
        return {"ok": True, "name": self.name, "host": self.host, "pid": os.getpid(),
                "allow": list(self.allow), "allow_fmu": self.allow_fmu, "running": running,
                "listen": self.settings.listen, "max_components": self.max_components,
                "authenticated": self.authenticated}

    def _start(self, request: dict[str, Any]) -> int:
        run_id = check_key_chunk(request["run_id"], "run_id")
        component = check_key_chunk(request["component"], "component name")
        if not self.authenticated and not self.insecure:
            raise UserError(f"worker {self.name!r} on host {self.host!r} refuses component "
                            f"{component!r}: it cannot authenticate masters (no auth: "
                            f"credential and no TLS client certificates in its --deploy "
                            f"file); give it one, or start it with --insecure on a trusted "
                            f"network")
        class_path = str(request["class_path"])
        parameters = dict(request.get("parameters", {}))
        if class_path == FMU_HOST_CLASS:
            parameters["fmu_file"] = str(self._receive_fmu(component, request.get("fmu")))
        elif not proto.module_allowed(class_path, self.allow):
            raise UserError(f"worker {self.name!r} on host {self.host!r} refuses component "
                            f"{component!r}: module {class_path.partition(':')[0]!r} is not "
                            f"in its allow-list ({', '.join(self.allow)}); start the worker "
                            f"with --allow to permit it")
        connect = [check_endpoint(str(e)) for e in request["connect"]]
        if not connect:
            raise ValueError("start request without a master endpoint")
        token = str(request.get("run_token") or "")
        if not token:
            raise ValueError("start request without a run_token")
        launch = PythonComponentLaunch(component, class_path, parameters,
                                       int(request.get("period_ticks", 1)),
                                       steps=steps_from_json(request.get("steps")))
        # behind a router (client mode) the component falls back to the router when the
        # master's own endpoint cannot be reached from here
        session_conf = zenoh_settings(self.settings, self.mode, [],
                                      list(dict.fromkeys([*connect, *self.settings.connect])))
        with self._lock:
            if (run_id, component) in self._children:
                raise ValueError(f"component {component!r} of run {run_id!r} already runs here")
            if len(self._children) >= self.max_components:
                raise UserError(f"worker {self.name!r} on host {self.host!r} refuses component "
                                f"{component!r}: it already hosts {len(self._children)} "
                                f"components (--max-components {self.max_components})")
            child = ChildProcess(launch, run_id, connect[0], session_config=session_conf,
                                 handshake_timeout_s=self.orphan_timeout_s, one_runtime_thread=False)
            self._children[(run_id, component)] = _Hosted(child, run_id, token, time.monotonic())
            self._watch_master(run_id)
        return child.pid

    def _watch_master(self, run_id: str) -> None:
        """Follow the liveliness token of the run's master (called under the lock)."""
        if self._session is not None and run_id not in self._masters:
            self._masters[run_id] = self._session.liveliness().declare_subscriber(
                master_alive_key(run_id), history=True)

    def _receive_fmu(self, component: str, payload: Any) -> Path:
        """Check and cache the FMU a start request carries; its path on this host."""
        if not self.allow_fmu:
            raise UserError(f"worker {self.name!r} on host {self.host!r} refuses FMU component "
                            f"{component!r}: it does not run FMUs sent over the network; "
                            f"start it with --allow-fmu to permit it")
        if not isinstance(payload, dict):
            raise ValueError(f"start request of FMU component {component!r} carries no FMU")
        return store_fmu(payload, self._cache_folder())

    def _stop(self, request: dict[str, Any]) -> int | None:
        key = (str(request["run_id"]), str(request["component"]))
        with self._lock:
            hosted = self._children.get(key)
        if hosted is None:
            return None  # already ended (and reported)
        if not hmac.compare_digest(hosted.token.encode(),
                                   str(request.get("run_token") or "").encode()):
            raise UserError(f"worker {self.name!r} on host {self.host!r} refuses to stop "
                            f"component {key[1]!r} of run {key[0]!r}: the request does not "
                            f"come from the run that started it")
        _end_process(hosted.child)
        return hosted.child.exit_code()

    # ------------------------------------------------------------------ children
    def _reap_loop(self, stop_event: threading.Event) -> None:
        while not stop_event.wait(REAP_POLL_S):
            for hosted in self._orphans():
                _end_process(hosted.child)
            with self._lock:
                ended = [(k, h.child) for k, h in self._children.items()
                         if h.child.exit_code() is not None]
                for key, _ in ended:
                    del self._children[key]
                self._forget_masters()
            for (run_id, component), child in ended:
                self._notify_exit(run_id, component, child)

    def _orphans(self) -> list[_Hosted]:
        """Children whose master is gone, or has not appeared within the timeout."""
        with self._lock:
            for run_id, watcher in self._masters.items():
                while (sample := watcher.try_recv()) is not None:
                    self._master_seen[run_id] = sample.kind != zenoh.SampleKind.DELETE
            late = time.monotonic() - self.orphan_timeout_s
            return [h for h in self._children.values() if h.child.exit_code() is None
                    and (self._master_seen.get(h.run_id) is False
                         or (h.run_id not in self._master_seen and h.started < late))]

    def _forget_masters(self) -> None:
        """Undeclare the master watchers of runs that have no child here any more
        (called under the lock)."""
        running = {h.run_id for h in self._children.values()}
        for run_id in [r for r in self._masters if r not in running]:
            self._masters.pop(run_id).undeclare()
            self._master_seen.pop(run_id, None)

    def _notify_exit(self, run_id: str, component: str, child: ChildProcess) -> None:
        notice = {"worker": self.name, "host": self.host, "exit_code": child.exit_code(),
                  "cause": child.describe_exit()}
        child.close_log()
        try:
            self._session.put(proto.exit_key(run_id, component), proto.encode(notice))
        except zenoh.ZError:
            pass  # session closing: nobody listens any more

    def _stop_all(self) -> None:
        with self._lock:
            children = [h.child for h in self._children.values()]
            self._children.clear()
            self._forget_masters()
        for child in children:
            _end_process(child)
            child.close_log()


def _end_process(child: ChildProcess) -> None:
    """SIGTERM (and SIGCONT) a child, SIGKILL it after a grace period; always waits."""
    if child.exit_code() is None:
        try:
            child.popen.terminate()
            child.popen.send_signal(signal.SIGCONT)
        except ProcessLookupError:
            pass
    try:
        child.popen.wait(timeout=STOP_GRACE_S)
    except subprocess.TimeoutExpired:
        child.popen.kill()
        child.popen.wait()
