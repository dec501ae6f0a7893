"""Master side of distributed runs: find workers, start components on them.

    with DistributedComponents(specs, run_id, placement={"controller": "w1"},
                               settings=deploy_settings) as hosted:
        ...   # exactly like ZenohComponents: hosted.components are HostedComponents

`DistributedComponents` is a `ZenohComponents` whose session follows the
deployment settings (endpoints, TLS, ACL) and which starts the placed
components through their worker instead of as local children. Before any
component starts it checks that every named worker answers, and fails naming
the missing ones and the reachable ones, and that no name is answered by two
workers (a start request would reach both). A `WorkerChild` stands for a remote
process where the transport expects a local one: its exit code comes from the
worker's exit notice, and a failure mid-run names the worker and its host.
A placed component's process is the ordinary runner, so a parameter its
constructor rejects comes back in its handshake as a `ParameterProblem`,
which the master maps to the YAML line as for a local process.
`list_workers` is what `cosim workers` prints.
"""

from __future__ import annotations

import json
import secrets
import time
from collections.abc import Mapping, Sequence
from typing import Any

import zenoh

from cosim.distributed import protocol as proto
from cosim.distributed.deploy import (DeploySettings, session_mode, to_zenoh_config, zenoh_config,
                                      zenoh_settings)
from cosim.errors import ComponentFailure, UserError
from cosim.fmu.remote import FMU_HOST_CLASS, fmu_payload
from cosim.transport.launch import STARTUP_TIMEOUT_S, PythonComponentLaunch
from cosim.transport.zenoh import config
from cosim.transport.zenoh.auth import Credential, run_acl
from cosim.transport.zenoh.host import ZenohComponents
from cosim.transport.zenoh.processes import ChildProcess

QUERY_TIMEOUT_S = 0.3
QUERY_INTERVAL_S = 0.05  # between two discovery queries
START_TIMEOUT_S = 5.0
STOP_TIMEOUT_S = 1.8
SETTLE_PROBE_S = 0.2
SETTLE_POLL_S = 0.05


def query_workers(session: Any, timeout_s: float,
                  wanted: set[str] | None = None) -> dict[str, list[dict[str, Any]]]:
    """Ask every reachable worker for its info, retrying until `timeout_s`.

    Peers that just connected can miss the first query (DESIGN.md), so the
    query is repeated, `QUERY_INTERVAL_S` apart (a query nobody answers returns at
    once: the loop sleeps, it does not spin); it ends early once every worker of
    `wanted` answered. Every answer is kept (no consolidation by key), so two
    workers that answer to the same name both show up.

    Args:
        session: an open Zenoh session joined to the workers (or their router).
        timeout_s: total time to look.
        wanted: worker names that must answer (None: look for the whole time).
    Returns:
        worker name -> the info reply of each worker that answers to that name (one,
        unless several workers use the same name), in the order they first answered.
    """
    found: dict[str, dict[str, dict[str, Any]]] = {}  # name -> replier -> info
    end = time.monotonic() + timeout_s
    request = proto.encode({"op": "info"})
    while True:
        began = time.monotonic()
        wait = max(0.01, min(QUERY_TIMEOUT_S, end - began))
        for reply in session.get(proto.worker_key("*"), payload=request, timeout=wait,
                                 consolidation=zenoh.ConsolidationMode.NONE):
            if reply.ok is None:
                continue
            try:
                info = proto.decode(reply.ok.payload.to_bytes(), "worker info")
            except ValueError:
                continue
            if info.get("ok") and isinstance(info.get("name"), str):
                replier = str(getattr(reply, "replier_id", None)
                              or (info.get("host"), info.get("pid")))
                found.setdefault(info["name"], {})[replier] = info
        now = time.monotonic()
        if (wanted is not None and wanted <= set(found)) or now >= end:
            break
        time.sleep(max(0.0, min(QUERY_INTERVAL_S - (now - began), end - now)))
    return {name: list(by_replier.values()) for name, by_replier in found.items()}


def describe_worker(info: Mapping[str, Any]) -> str:
    """"host 'h' (pid 12, listening on tcp/...)" of a worker's info reply, for messages."""
    listen = ", ".join(map(str, info.get("listen") or [])) or "no endpoint of its own"
    return f"host {info.get('host')!r} (pid {info.get('pid')}, listening on {listen})"


def duplicate_names(found: Mapping[str, Sequence[Mapping[str, Any]]],
                    names: set[str] | None = None) -> str:
    """The message naming every worker name (of `names`, None: all) that several
    workers answer to, or "" when each name is one worker's.

    Args:
        found: what `query_workers` returned.
        names: the names that matter (the placed ones).
    """
    lines = [f"worker name {name!r} is answered by {len(infos)} workers: "
             + "; ".join(sorted(describe_worker(i) for i in infos))
             for name, infos in sorted(found.items())
             if len(infos) > 1 and (names is None or name in names)]
    return "\n".join(lines)


def list_workers(settings: DeploySettings, timeout_s: float = 1.0) -> list[dict[str, Any]]:
    """Every worker reachable with these settings, sorted by name (`cosim workers`).

    Workers that share a name are all listed (each with its host and pid), so that
    the duplicate shows; a run placed on that name refuses to start.

    Args:
        settings: connect endpoints (workers or a router), TLS, ACL.
        timeout_s: how long to look.
    """
    try:
        mode = session_mode(settings.listen, settings.connect)
        session = zenoh.open(zenoh_config(settings, mode, settings.listen, settings.connect))
    except zenoh.ZError as exc:
        raise UserError(f"cannot open a Zenoh session to {settings.connect}: {exc}") from None
    with session:
        found = query_workers(session, timeout_s)
    return [info for name in sorted(found)
            for info in sorted(found[name], key=lambda i: (str(i.get("host")), str(i.get("pid")),
                                                           str(i.get("listen"))))]


def ask_worker(session: Any, worker: str, request: dict[str, Any],
               timeout_s: float) -> dict[str, Any] | None:
    """Send one request to `worker` and return its reply (None: no answer in time).

    Args:
        session: an open session joined to the worker.
        worker: its name.
        request: a cosim.distributed.protocol request.
        timeout_s: longest wait.
    """
    for reply in session.get(proto.worker_key(worker), payload=proto.encode(request),
                             timeout=timeout_s):
        if reply.ok is not None:
            return proto.decode(reply.ok.payload.to_bytes(), f"reply of worker {worker!r}")
    return None


class _RemotePopen:
    """The few `subprocess.Popen` methods `processes.reap` uses, for a process on a worker."""

    def __init__(self, child: "WorkerChild") -> None:
        self._child = child
        self._stop_reply: Any = None

    def poll(self) -> int | None:
        return self._child.exit_code()

    def terminate(self) -> None:
        if self._stop_reply is None and not self._child.hosted.worker_gone(self._child.worker):
            request = {"op": "stop", "run_id": self._child.run_id, "component": self._child.name,
                       "run_token": self._child.hosted.run_token}
            self._stop_reply = self._child.hosted.session.get(
                proto.worker_key(self._child.worker), payload=proto.encode(request),
                timeout=STOP_TIMEOUT_S)

    def send_signal(self, sig: int) -> None:
        """Signals are the worker's business (its stop request sends them)."""

    def wait(self, timeout: float | None = None) -> int | None:
        """Wait for the worker's answer to the stop request (or the exit notice)."""
        if self._stop_reply is None or timeout is None:
            return self.poll()
        for _reply in self._stop_reply:  # ends at the first answer or at STOP_TIMEOUT_S
            break
        self._stop_reply = None
        return self.poll()

    def kill(self) -> None:
        """Nothing more to do from here: the worker kills what ignores SIGTERM."""


class WorkerChild:
    """A component process on a worker, standing in for a local ChildProcess.

    Args:
        hosted: the DistributedComponents of the run.
        spec: what to start.
        worker: the worker's name.
        info: the worker's info reply (host, pid).
    """

    is_local = False  # its pid is the worker's
    # after its token vanished: for the worker's exit notice, or the worker's own token to
    # vanish too (a host killed or cut off: the two losses come over two connections)
    verdict_wait_s = 1.0

    def __init__(self, hosted: "DistributedComponents", spec: PythonComponentLaunch,
                 worker: str, info: Mapping[str, Any]) -> None:
        self.hosted, self.name, self.worker = hosted, spec.name, worker
        self.run_id = hosted.run_id
        self.worker_host = str(info.get("host", "?"))
        request = {"op": "start", "run_id": hosted.run_id, "run_token": hosted.run_token,
                   "component": spec.name,
                   "class_path": spec.class_path, "parameters": _jsonable(spec),
                   "period_ticks": int(spec.period_ticks), "steps": spec.steps,
                   "connect": [hosted.endpoint]}
        if spec.class_path == FMU_HOST_CLASS:
            request["fmu"] = fmu_payload(spec)  # the file travels; the worker checks its hash
        reply = ask_worker(hosted.session, worker, request, START_TIMEOUT_S)
        if reply is None:
            raise UserError(f"component {spec.name!r}: worker {worker!r} on host "
                            f"{self.worker_host!r} did not answer the start request within "
                            f"{START_TIMEOUT_S:g} s")
        if not reply.get("ok"):
            error = str(reply.get("error"))
            raise UserError(error if repr(spec.name) in error
                            else f"component {spec.name!r}: {error}")
        self.pid = int(reply["pid"])
        self.popen = _RemotePopen(self)

    @property
    def where(self) -> str:
        """"worker 'w1' on host 'h'" for messages."""
        return f"worker {self.worker!r} on host {self.worker_host!r}"

    def exit_code(self) -> int | None:
        """The exit code the worker reported, or None while the process runs."""
        notice = self.hosted.exit_notice(self.name)
        return None if notice is None else int(notice.get("exit_code") or 0)

    def end_known(self) -> bool:
        """Whether how the process ended can be told: its worker's notice, or the worker gone."""
        return self.hosted.exit_notice(self.name) is not None or self.hosted.worker_gone(self.worker)

    def describe_exit(self) -> str:
        """How the process ended, as its worker told (or that both went silent)."""
        notice = self.hosted.exit_notice(self.name)
        if notice is not None:
            return f"{notice.get('cause')} ({self.where})"
        if self.hosted.worker_gone(self.worker):
            return (f"{self.where} became unreachable (host down, frozen or cut off): the "
                    f"liveliness tokens of the component process and of the worker were lost")
        return (f"process stopped or not responding (liveliness token lost) on "
                f"{self.where}; the worker is still up")

    def log_tail(self) -> str:
        """The last output, as sent in the worker's exit notice."""
        notice = self.hosted.exit_notice(self.name)
        return "" if notice is None else str(notice.get("cause", ""))

    def close_log(self) -> None:
        """Nothing to release here: the worker keeps the log."""


def _jsonable(spec: PythonComponentLaunch) -> dict[str, Any]:
    try:
        from cosim.transport.zenoh.processes import _json_default
        return json.loads(json.dumps(dict(spec.parameters), default=_json_default))
    except (TypeError, ValueError) as exc:
        raise UserError(f"component {spec.name!r}: parameters cannot be sent to its "
                        f"worker: {exc}") from None


class DistributedComponents(ZenohComponents):
    """ZenohComponents with deployment settings and components placed on workers.

    Its processes keep Zenoh's default runtime pools: with one runtime thread, a link cut
    mid-run left the master waiting past every deadline (tests/distributed/test_netns.py).

    Args:
        specs: every Python component of the run.
        run_id: scopes every key.
        deadline_s: longest wait for any one reply.
        placement: component name -> worker name (components not named run locally).
        settings: endpoints (the first `listen` one is the master's), TLS, ACL.
        startup_timeout_s: longest wait for every component's handshake.
    """

    one_runtime_thread = False

    def __init__(self, specs: Sequence[PythonComponentLaunch], run_id: str,
                 deadline_s: float = 5.0, *, placement: Mapping[str, str] | None = None,
                 settings: DeploySettings | None = None,
                 startup_timeout_s: float = STARTUP_TIMEOUT_S) -> None:
        self.settings = settings or DeploySettings()
        self.placement = dict(placement or {})
        unknown = sorted(set(self.placement) - {s.name for s in specs})
        if unknown:
            raise UserError(f"placement names unknown components: {', '.join(unknown)}")
        if self.placement and not self.settings.listen:
            raise UserError("components placed on workers ("
                            + ", ".join(f"{c} on {w!r}" for c, w in self.placement.items())
                            + ") need an endpoint of this master that the workers can reach: "
                              "give --listen tcp/ADDRESS:PORT (or listen: in --deploy)")
        endpoint = master_endpoint(self.settings.listen[0]) if self.settings.listen else None
        if self.placement and endpoint and _unspecified(endpoint):
            raise UserError(f"--listen {self.settings.listen[0]}: the workers' component "
                            f"processes connect back to this endpoint, so give an address "
                            f"of this host they can reach, not a wildcard one")
        super().__init__(specs, run_id, deadline_s, endpoint, connect=self.settings.connect,
                         startup_timeout_s=startup_timeout_s)
        self._shared = self.settings.credential()  # None: the deployment has no `auth`
        self.run_token = secrets.token_urlsafe(24)  # proves a stop request is this run's
        self.workers: dict[str, dict[str, Any]] = {}
        self._notices: dict[str, dict[str, Any]] = {}
        self._gone: set[str] = set()

    @property
    def hosts(self) -> dict[str, str]:
        """Component -> "worker@host" for the placed components (for the manifest)."""
        return {c: f"{w}@{self.workers.get(w, {}).get('host', '?')}"
                for c, w in self.placement.items()}

    def close(self) -> None:
        """End the run's processes and the session, even when a peer was cut off."""
        try:
            super().close()
        except zenoh.ZError:
            # a peer behind a cut link cannot acknowledge the close: the session is gone anyway
            self.session = None

    def wait_ready(self) -> dict[str, Any]:
        """Handshake with every component; FMUs on workers keep their FMU step order."""
        components = super().wait_ready()
        for spec in self.specs:
            if spec.class_path == FMU_HOST_CLASS:
                components[spec.name].direct_feedthrough = False  # as a local FmuComponent
        return components

    @property
    def live_credential(self) -> Credential | None:
        """The run's credential when this master checks credentials (a deployment
        with `auth`); None with TLS alone or a plain deployment (watch with --deploy)."""
        return self.credential if self._shared is not None else None

    def _accepted(self) -> list[Credential]:
        return [self.credential, *([self._shared] if self._shared else [])]

    def _session_config(self, endpoint: str) -> zenoh.Config:
        """The deployment's session (TLS, shared credential) accepting the run's own
        credential too, restricted to the run's and the workers' keys unless the
        deployment has its own ACL."""
        listen = [endpoint, *self.settings.listen[1:]]
        document = zenoh_settings(self.settings, "peer", listen, self.settings.connect)
        if self._shared is not None:
            assert self._dictionary is not None
            document["transport"]["auth"] = {
                "usrpwd": self._shared.usrpwd(str(self._dictionary.path))}
        if self.settings.access_control is None:
            document["access_control"] = run_acl(self.run_id, [proto.worker_key("**")])
        return to_zenoh_config(document)

    def _open_session(self) -> None:
        super()._open_session()
        self._exits = self.session.declare_subscriber(proto.exit_key(self.run_id, "*"))
        self._worker_tokens = self.session.liveliness().declare_subscriber(
            proto.worker_key("*"))
        self._find_workers()

    def _find_workers(self) -> None:
        wanted = set(self.placement.values())
        if not wanted:
            return
        found = query_workers(self.session, self.settings.discovery_timeout_s, wanted)
        self.workers = {name: infos[0] for name, infos in found.items()}
        missing = sorted(wanted - set(self.workers))
        if missing:
            placed = ", ".join(f"{c} on {w!r}" for c, w in sorted(self.placement.items())
                               if w in missing)
            reachable = ", ".join(f"{n} (host {i.get('host')!r})"
                                  for n, i in sorted(self.workers.items())) or "none"
            raise UserError(f"run {self.run_id!r}: worker(s) {', '.join(map(repr, missing))} "
                            f"not reachable within {self.settings.discovery_timeout_s:g} s "
                            f"(placed: {placed}); reachable workers: {reachable}")
        duplicates = duplicate_names(found, wanted)
        if duplicates:  # a start request to that name would reach (and start on) each of them
            raise UserError(f"run {self.run_id!r}: " + duplicates.replace("\n", "; ")
                            + "; give each worker its own --name")

    def _spawn(self, spec: PythonComponentLaunch) -> Any:
        worker = self.placement.get(spec.name)
        if worker is not None:
            return WorkerChild(self, spec, worker, self.workers[worker])
        conf = zenoh_settings(self.settings, "peer", [], [self.endpoint])
        if self._shared is not None:  # the master checks credentials: present the run's
            conf["transport"]["auth"] = {"usrpwd": self.credential.usrpwd()}
        return ChildProcess(spec, self.run_id, self.endpoint, session_config=conf,
                            one_runtime_thread=self.one_runtime_thread)

    def exit_notice(self, component: str) -> dict[str, Any] | None:
        """The exit notice a worker sent for `component`, if any."""
        while (sample := self._exits.try_recv()) is not None:
            name = str(sample.key_expr).rsplit("/", 1)[-1]
            try:
                notice = proto.decode(sample.payload.to_bytes(), "exit notice")
            except ValueError:
                continue
            code = notice.get("exit_code")
            if (isinstance(code, int) and not isinstance(code, bool)) or code is None:
                self._notices[name] = notice  # anything else is no worker's notice: ignored
        return self._notices.get(component)

    def worker_gone(self, worker: str) -> bool:
        """Whether the liveliness token of `worker` has disappeared during the run."""
        while (sample := self._worker_tokens.try_recv()) is not None:
            name = str(sample.key_expr).rsplit("/", 1)[-1]
            if sample.kind == zenoh.SampleKind.DELETE:
                self._gone.add(name)
            else:
                self._gone.discard(name)
        return worker in self._gone

    def _fail(self, failure: ComponentFailure) -> ComponentFailure:
        child = self._children.get(failure.component)
        if isinstance(child, WorkerChild):
            if child.where not in failure.cause:
                failure = ComponentFailure(failure.component, failure.tick, failure.time,
                                           f"{failure.cause}; it ran on {child.where}",
                                           failure.details)
            if self.exit_notice(child.name) is None:
                self._settle(child.worker)
        return super()._fail(failure)

    def _settle(self, worker: str) -> None:
        """Wait until `worker` either answers or has lost its link (lease expired).

        A session whose link to a silent peer is still open blocks other traffic
        and its own close for seconds (measured: close times out after 10 s), so
        after a worker went silent the run waits for Zenoh to drop that link
        before stopping the other components.
        """
        end = time.monotonic() + self.settings.lease_s + 1.0
        while time.monotonic() < end and not self.worker_gone(worker):
            if ask_worker(self.session, worker, {"op": "info"}, SETTLE_PROBE_S) is not None:
                return
            time.sleep(SETTLE_POLL_S)


def _unspecified(endpoint: str) -> bool:
    """Whether the endpoint listens on every interface (0.0.0.0, [::])."""
    host = endpoint.partition("/")[2].rpartition(":")[0].strip("[]")
    return host in ("0.0.0.0", "::", "")


def master_endpoint(endpoint: str) -> str:
    """`endpoint` with port 0 (or none) replaced by a port that is free now.

    Args:
        endpoint: e.g. "tcp/10.0.0.1:0" or "tls/10.0.0.1:7447".
    """
    proto_name, _, address = endpoint.partition("/")
    host, sep, port = address.rpartition(":")
    if not sep:
        host, port = address, "0"
    if port not in ("", "0"):
        return endpoint
    free = config.free_tcp_endpoint(host.strip("[]"))
    return f"{proto_name}/{host}:{free.rsplit(':', 1)[1]}"
