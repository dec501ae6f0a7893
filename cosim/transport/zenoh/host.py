"""Master side of the Zenoh transport: one OS process per Python component.

`ZenohComponents` opens the master's peer session, spawns the component
processes, shakes hands with each (retrying until every one answers with its
port declarations) and exposes one `RemoteComponent` per component, which the
master drives through the `cosim.engine.hosting.HostedComponent` protocol. Each
exchange puts one request and waits in a blocking `recv()` on the subscriber
of that component's replies (exact keys: no wildcard on the hot path); the
watchdog wakes that wait on a death (of any component) or a missed deadline,
which then raises `ComponentFailure`.

Every session of the run authenticates with the run's credential (Zenoh
user-password; see `cosim.transport.zenoh.auth`): the master accepts only
peers that present it, and only on the run's keys.

A reply that is not a well-formed message of the protocol (shorter than the
header, of an unknown kind, JSON that is not the expected object, values of
the wrong size) fails the run like any component failure, naming the
component and the tick: "malformed reply: ..." (the manifest's cause has
kind "malformed_reply"). It never ends the master with a traceback.

Start-up is ordered for speed: `spawn()` opens the session and starts the
processes before this module loads numpy (codec, live view, watchdog), so
the children's interpreters start while the master finishes its own imports.
"""

from __future__ import annotations

import json
import struct
import time
from collections.abc import Mapping, Sequence, Set
from typing import TYPE_CHECKING, Any

import zenoh

from cosim.errors import ComponentFailure, StartFault, UserError
from cosim.transport.launch import STARTUP_TIMEOUT_S, PythonComponentLaunch
from cosim.transport.zenoh import auth, config, runtime
from cosim.transport.zenoh.auth import Credential, Dictionary, new_credential
from cosim.transport.zenoh.processes import ChildProcess, reap
from cosim.transport.zenoh.wire import HEADER, CodecError, Kind, decode_json, encode_json, header_tick

if TYPE_CHECKING:  # numpy-backed modules load after the processes are spawned
    import numpy as np

    from cosim.component import Port, Value
    from cosim.transport.zenoh.live import LivePublisher
    from cosim.transport.zenoh.watchdog import Watchdog

HELLO_RETRY_S = 0.02
TERMINATE_GRACE_S = 2.0
OPEN_ATTEMPTS = 5
# what may arrive on a component's reply key: its own replies, and the watchdog's wake-ups
REPLY_KINDS = frozenset({Kind.PORTS, Kind.OUTPUTS, Kind.METRICS, Kind.ERROR, Kind.USED,
                         Kind.DIED, Kind.TIMEOUT})


class RemoteComponent:
    """A component running in its own process, seen through HostedComponent."""

    def __init__(self, host: "ZenohComponents", spec: PythonComponentLaunch,
                 inputs: tuple[Port, ...], outputs: tuple[Port, ...], pid: int,
                 channel: tuple[Any, Any], uses_outputs: bool = False) -> None:
        from cosim.transport.zenoh.codec import Layout

        self.name = spec.name
        self.period_ticks = int(spec.period_ticks)
        self.inputs = inputs
        self.outputs = outputs
        self.pid = pid
        self.in_layout = Layout(inputs, "input")
        self.out_layout = Layout(outputs, "output")
        self.publisher, self.replies = channel  # requests out, replies in
        self.uses_outputs = uses_outputs  # its class hears use_outputs (from the handshake)
        self._host = host
        # the master's values lane (cosim.engine.master): the wire carries the values in
        # declared order either way, so every component with scalar outputs is offered it
        self.value_names: tuple[tuple[str, ...], tuple[str, ...]] | None = None
        if all(port.size == 1 for port in outputs):
            self.value_names = (tuple(p.name for p in inputs), tuple(p.name for p in outputs))
        self.values_exact = True  # the reply's floats, one per output (decoded by struct)

    def use_outputs(self, names: Set[str]) -> None:
        """Tell the remote component which outputs the run reads (one exchange, when its
        class hears it: as in-process, it then hears it whatever the names)."""
        if self.uses_outputs:
            self._host.exchange_use(self, names)

    def start(self, t0: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Initialize the remote component at t0; return its initial outputs."""
        return self._host.exchange_outputs(self, Kind.START, None, t0, inputs)

    def step(self, tick: int, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Step the remote component to time t; return its outputs."""
        return self._host.exchange_outputs(self, Kind.STEP, tick, t, inputs)

    def step_values(self, tick: int, t: float, inputs: Sequence[Value]) -> tuple[float, ...]:
        """Step the remote component on its inputs in declared order; its outputs likewise."""
        return self._host.exchange_values(self, tick, t, inputs)

    def stop(self) -> dict[str, float]:
        """Ask the remote component to finish; return its metrics. Its process then exits."""
        return self._host.exchange_stop(self)


class ZenohComponents:
    """Context manager hosting Python components in their own processes over Zenoh.

    Its processes run Zenoh's runtime on one thread (`runtime`, `one_runtime_thread`).

    Args:
        specs: the components to launch, one process each.
        run_id: scopes every key expression (letters, digits, '_', '.', '-').
        deadline_s: longest wait for any one reply before the component fails.
        endpoint: the master's listen endpoint; None picks a free 127.0.0.1 TCP port.
        connect: extra endpoints the master joins (a router, another host), or None.
        startup_timeout_s: longest wait for every process's handshake.
        prestarted: processes already started with `ChildProcess.prestart` (same
            run id, `endpoint` and `credential`), by component name; `spawn` sends
            them their spec instead of starting new ones and ends those no spec names.
        credential: what every session of the run authenticates with (None: a new
            random one); the master accepts only peers that present it.
    """

    one_runtime_thread = True  # False: Zenoh's default pools (runs across hosts)

    def __init__(self, specs: Sequence[PythonComponentLaunch], run_id: str,
                 deadline_s: float = 5.0, endpoint: str | None = None, *,
                 connect: Sequence[str] | None = None, startup_timeout_s: float = STARTUP_TIMEOUT_S,
                 prestarted: Mapping[str, ChildProcess] | None = None,
                 credential: Credential | None = None) -> None:
        self.specs = list(specs)
        self.run_id = config.check_key_chunk(run_id, "run_id")
        names = [config.check_key_chunk(s.name, "component name") for s in self.specs]
        if len(set(names)) != len(names):
            raise UserError(f"run {run_id!r}: component names must be unique, got {names}")
        if not deadline_s > 0:
            raise UserError(f"run {run_id!r}: deadline_s must be > 0, got {deadline_s!r}")
        self.deadline_s = float(deadline_s)
        self.endpoint = endpoint
        self._connect = list(connect or [])
        self._startup_timeout_s = startup_timeout_s
        self.credential = credential or new_credential(self.run_id)
        self._dictionary: Dictionary | None = None
        self._components: dict[str, RemoteComponent] | None = None
        self.session: Any = None
        self._children: dict[str, ChildProcess] = {}
        self._prestarted = dict(prestarted or {})
        if self._prestarted and endpoint is None:
            raise ValueError("prestarted processes need the endpoint they connect to")
        self._watchdog: Watchdog | None = None
        self._live: LivePublisher | None = None
        self._seq = 0
        self._failed: dict[str, ComponentFailure] = {}  # by component: raised again on reuse
        # start-up marks of each process, seconds since its start: "imported" (runner
        # modules loaded), "spec" (its class and parameters known), "session" (Zenoh
        # open), "built" (component), "ready" (handshake); "cpu": CPU seconds by then
        self.process_startup_s: dict[str, dict[str, float | None]] = {}

    # ----------------------------------------------------------------- lifecycle
    def __enter__(self) -> "ZenohComponents":
        """Open the session, spawn the processes and wait for every handshake."""
        self.spawn()
        self.wait_ready()
        return self

    def spawn(self) -> None:
        """Open the session and start the processes without waiting for them, so
        that the caller can do other start-up work (load FMUs) meanwhile; then call
        `wait_ready` (or use the object as a context manager, which does both)."""
        try:
            self._open_session()
            for spec in self.specs:
                early = self._prestarted.pop(spec.name, None)
                if early is not None:
                    early.send_spec(spec)
                    self._children[spec.name] = early
                else:
                    self._children[spec.name] = self._spawn(spec)
            reap(list(self._prestarted.values()), TERMINATE_GRACE_S)  # not in this run
            self._prestarted.clear()
        except BaseException:
            self.close()
            raise

    def wait_ready(self) -> dict[str, "RemoteComponent"]:
        """Wait for every component's handshake (once); return `components`."""
        if self._components is None:
            try:
                from cosim.transport.zenoh.live import LivePublisher
                from cosim.transport.zenoh.watchdog import Watchdog

                if self._live is None:
                    self._live = LivePublisher(self.session, self.run_id)
                self._components = self._handshake()
                self._watchdog = Watchdog(self.session, self.run_id, self._children,
                                          self.deadline_s)
                self._watchdog.start()
            except BaseException:
                self.close()
                raise
        return self._components

    @property
    def components(self) -> dict[str, "RemoteComponent"]:
        """The hosted components by name, in declaration order (after the handshake)."""
        if self._components is None:
            raise RuntimeError("ZenohComponents: components read before the handshake "
                               "(use `with ZenohComponents(...)` or call wait_ready())")
        return self._components

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """End every process (terminate, then kill after a grace period) and the session."""
        if self._watchdog is not None:
            self._watchdog.close()
            self._watchdog = None
        reap([*self._children.values(), *self._prestarted.values()], TERMINATE_GRACE_S)
        self._children.clear()
        self._prestarted.clear()
        if self.session is not None:
            if self._live is not None:
                self._live.close()
                self._live = None
            self.session.close()
            self.session = None
        if self._dictionary is not None:
            self._dictionary.close()
            self._dictionary = None

    @property
    def live_credential(self) -> Credential | None:
        """What a watcher presents to this master (None: it accepts without one)."""
        return self.credential

    def _accepted(self) -> list[Credential]:
        """The credentials the master's session accepts (a subclass adds a shared one)."""
        return [self.credential]

    def _session_config(self, endpoint: str) -> zenoh.Config:
        """Config of the master session listening on `endpoint`: only peers with the
        run's credential, only the run's keys (a subclass may add TLS)."""
        assert self._dictionary is not None
        security = auth.security_settings(self.credential, str(self._dictionary.path),
                                          self.run_id)
        return config.master_config(endpoint, self._connect, security)

    def _spawn(self, spec: PythonComponentLaunch) -> ChildProcess:
        """Start the process of one component (a subclass may start it elsewhere)."""
        return ChildProcess(spec, self.run_id, self.endpoint, credential=self.credential,
                            one_runtime_thread=self.one_runtime_thread)

    @property
    def pids(self) -> dict[str, int]:
        """Process id of each component's process."""
        return {name: child.pid for name, child in self._children.items()}

    def local_pids(self) -> list[int]:
        """Process ids of the component processes on this machine (not a worker's)."""
        return [child.pid for child in self._children.values() if child.is_local]

    def _open_session(self) -> None:
        """Open the master session, listening on `endpoint` or on a free port."""
        attempts = 1 if self.endpoint else OPEN_ATTEMPTS
        self._dictionary = Dictionary(self._accepted())
        for attempt in range(attempts):
            endpoint = self.endpoint or config.free_tcp_endpoint()
            try:
                with runtime.first_session(self.one_runtime_thread):
                    self.session = zenoh.open(self._session_config(endpoint))
            except zenoh.ZError as exc:
                if attempt + 1 == attempts:
                    raise UserError(f"run {self.run_id!r}: cannot listen on "
                                    f"{endpoint}: {exc}") from exc
                continue
            self.endpoint = endpoint
            break
        self._token = self.session.liveliness().declare_token(config.master_alive_key(self.run_id))

    # ----------------------------------------------------------------- handshake
    def _handshake(self) -> dict[str, RemoteComponent]:
        """Send HELLO to every silent component until all have sent their ports."""
        pending = {spec.name: spec for spec in self.specs}
        ready: dict[str, RemoteComponent] = {}
        channels = {name: (self.session.declare_publisher(config.request_key(self.run_id, name),
                                                          express=True),
                           self.session.declare_subscriber(config.reply_key(self.run_id, name)))
                    for name in pending}
        hello = HEADER.pack(Kind.HELLO, 0, -1, 0.0)
        end = time.monotonic() + self._startup_timeout_s
        while pending:
            for name in pending:
                self._check_alive_at_start(name)
                channels[name][0].put(hello)
            self._collect_hellos(pending, channels, ready, time.monotonic() + HELLO_RETRY_S)
            if pending and time.monotonic() > end:
                name = next(iter(pending))
                raise StartFault(name, None, 0.0, f"no handshake within "
                                       f"{self._startup_timeout_s:g} s after its process started")
        # declaration order, not the order the answers happened to arrive in
        return {spec.name: ready[spec.name] for spec in self.specs}

    def _collect_hellos(self, pending: dict[str, PythonComponentLaunch],
                        channels: dict[str, tuple[Any, Any]], ready: dict[str, RemoteComponent],
                        until: float) -> None:
        """Take the handshake replies that arrive before `until`."""
        from cosim.transport.zenoh.codec import ports_from_json

        while pending and time.monotonic() < until:
            got = False
            for name in list(pending):
                sample = channels[name][1].try_recv()
                if sample is None:
                    continue
                got = True
                data = sample.payload.to_bytes()
                kind = _kind_of(name, data, None, 0.0)
                if kind == Kind.ERROR:
                    raise _build_error(name, _json_fields(name, data, None, 0.0, "cause"))
                if kind == Kind.PORTS:
                    document = _json_fields(name, data, None, 0.0, "inputs", "outputs", "pid")
                    try:
                        inputs = ports_from_json(document["inputs"])
                        outputs = ports_from_json(document["outputs"])
                        pid = int(document["pid"])
                        startup = {str(k): v for k, v in dict(document.get("startup_s") or {}).items()}
                    except (KeyError, TypeError, ValueError, AttributeError) as exc:
                        raise malformed(name, None, 0.0, f"its port declarations do not parse: "
                                        f"{type(exc).__name__}: {exc}") from None
                    ready[name] = RemoteComponent(
                        self, pending.pop(name), inputs, outputs, pid,
                        channels[name], bool(document.get("uses_outputs")))
                    self.process_startup_s[name] = startup
            if not got:
                time.sleep(0.002)

    def _check_alive_at_start(self, name: str) -> None:
        child = self._children[name]
        if child.exit_code() is not None:
            raise StartFault(name, None, 0.0, f"{child.describe_exit()} before its handshake")

    # ----------------------------------------------------------------- exchanges
    def exchange_outputs(self, remote: RemoteComponent, kind: int, tick: int | None,
                         t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Send START or STEP with `inputs` to `remote`; return its decoded outputs."""
        if kind == Kind.START:  # every array afresh, both ways (see codec.Layout)
            remote.in_layout.forget()
            remote.out_layout.forget()
        return self._coded_exchange(remote, remote.in_layout.encode, remote.out_layout.decode,
                                    kind, tick, t, inputs)

    def exchange_values(self, remote: RemoteComponent, tick: int, t: float,
                        inputs: Sequence[Value]) -> tuple[float, ...]:
        """`exchange_outputs` of a STEP on the values lane: inputs and outputs in declared order."""
        return self._coded_exchange(remote, remote.in_layout.encode_values,
                                    remote.out_layout.decode_values, Kind.STEP, tick, t, inputs)

    def _coded_exchange(self, remote: RemoteComponent, encode: Any, decode: Any, kind: int,
                        tick: int | None, t: float, inputs: Any) -> Any:
        """Encode the request, exchange it, decode the reply; a codec problem is the
        component's failure at this tick."""
        try:
            request = encode(kind, self._seq + 1, header_tick(tick), t, inputs)
        except CodecError as exc:
            raise ComponentFailure(remote.name, tick, t, str(exc)) from None
        data = self._exchange(remote, request, tick, t)
        try:
            return decode(data)
        except CodecError as exc:
            raise self._fail(malformed(remote.name, tick, t, str(exc))) from None

    def exchange_use(self, remote: RemoteComponent, names: Set[str]) -> None:
        """Send USE with `names` to `remote` and wait until its use_outputs returned."""
        request = encode_json(Kind.USE, self._seq + 1, -1, 0.0, {"outputs": sorted(names)})
        self._exchange(remote, request, None, 0.0)

    def exchange_stop(self, remote: RemoteComponent) -> dict[str, float]:
        """Send STOP to `remote`; return its metrics ({} if it already failed: that
        failure has been raised once, the master stops the others after it)."""
        assert self._watchdog is not None
        self._watchdog.finished.add(remote.name)  # its exit from now on is expected
        if remote.name in self._failed:
            return {}
        request = HEADER.pack(Kind.STOP, self._seq + 1, -1, 0.0)
        # a failure here has no tick: the master's stop_all names the run's last one
        data = self._exchange(remote, request, None, 0.0)
        try:
            return {str(k): float(v) for k, v in decode_json(data).items()}
        except (ValueError, TypeError, AttributeError):  # JSON, Unicode errors are ValueErrors
            raise malformed(remote.name, None, 0.0, "its metrics are not a JSON object of "
                            "numbers") from None

    def _exchange(self, remote: RemoteComponent, request: bytes, tick: int | None,
                  t: float) -> bytes:
        """Put one request and block until its reply; raise ComponentFailure on any failure."""
        if remote.name in self._failed:
            raise self._failed[remote.name]
        watchdog = self._watchdog
        assert watchdog is not None, "ZenohComponents used outside its `with` block"
        self._seq += 1
        seq = self._seq
        watchdog.arm(seq, remote.name)
        if watchdog.dead:
            self._raise_if_dead(tick, t)
        remote.publisher.put(request)
        recv = remote.replies.recv
        while True:
            data = recv().payload.to_bytes()
            try:
                kind, reply_seq = HEADER.unpack_from(data)[:2]
            except struct.error:
                watchdog.disarm()
                raise self._fail(malformed(remote.name, tick, t, _short(data))) from None
            if reply_seq == seq and (kind == Kind.OUTPUTS or kind == Kind.METRICS
                                     or kind == Kind.USED):
                watchdog.disarm()
                return data
            try:
                failure = self._failure_in(kind, reply_seq, seq, data, remote, tick, t)
            except ComponentFailure as malformed_reply:
                failure = malformed_reply
            if failure is not None:
                watchdog.disarm()
                raise self._fail(failure)

    def _failure_in(self, kind: int, reply_seq: int, seq: int, data: bytes,
                    remote: RemoteComponent, tick: int | None, t: float) -> ComponentFailure | None:
        """The failure a non-matching message reports, or None for a stale one to skip
        (raises the malformed-reply failure of one whose JSON is not what its kind says)."""
        if kind not in REPLY_KINDS:
            return malformed(remote.name, tick, t, f"unknown message kind {kind}")
        if kind in (Kind.ERROR, Kind.TIMEOUT) and reply_seq == seq:
            return ComponentFailure(remote.name, tick, t,
                                    _json_fields(remote.name, data, tick, t, "cause")["cause"])
        if kind == Kind.DIED:
            document = _json_fields(remote.name, data, tick, t, "component", "cause")
            name = document["component"]
            assert self._watchdog is not None
            if name not in self._children:
                return malformed(remote.name, tick, t, f"a death notice of {name!r}, "
                                 f"which is no component of this run")
            if name not in self._watchdog.finished:
                return ComponentFailure(name, tick, t, document["cause"])
        return None

    def _raise_if_dead(self, tick: int | None, t: float) -> None:
        """Raise the failure of a component that died (and was not stopped) since."""
        assert self._watchdog is not None
        for name, cause in list(self._watchdog.dead.items()):
            if name not in self._watchdog.finished:
                self._watchdog.disarm()
                raise self._fail(ComponentFailure(name, tick, t, cause))

    def _fail(self, failure: ComponentFailure) -> ComponentFailure:
        self._failed[failure.component] = failure
        if self._watchdog is not None:
            self._watchdog.finished.add(failure.component)  # reported once, not again
        return failure

    # ----------------------------------------------------------------- live view
    @property
    def live(self) -> "LivePublisher | None":
        """The run's live publisher (after `wait_ready`): `live.matching` is a plain
        attribute, cheap enough to test every tick before building a vector."""
        return self._live

    @property
    def live_matching(self) -> bool:
        """True when some watcher subscribes to this run's live signals."""
        return self._live is not None and self._live.matching

    def publish(self, tick: int, t: float, names: list[str], values: np.ndarray) -> None:
        """Publish the whole signal vector of a tick to live watchers (no-op if none).

        Args:
            tick: the master tick.
            t: its simulation time.
            names: one name per value, e.g. "controller.delta" (pass the same list each tick).
            values: float64 vector of every signal at this tick.
        """
        if self._live is not None:
            self._live.publish(tick, t, names, values)


def malformed(component: str, tick: int | None, t: float, problem: str) -> ComponentFailure:
    """The failure of a component whose reply is not a well-formed protocol message.

    Args:
        component: the component whose reply key it came on.
        tick, t: the exchange it answered (None: start-up).
        problem: what is wrong with it, e.g. "7 bytes, shorter than the 32-byte header".
    """
    return ComponentFailure(component, tick, t, f"malformed reply: {problem}",
                            {"kind": "malformed_reply"})


def _short(data: bytes) -> str:
    return f"{len(data)} bytes, shorter than the {HEADER.size}-byte message header"


def _kind_of(component: str, data: bytes, tick: int | None, t: float) -> int:
    """The kind of a reply; ComponentFailure when it is short or of an unknown kind."""
    try:
        kind = HEADER.unpack_from(data)[0]
    except struct.error:
        raise malformed(component, tick, t, _short(data)) from None
    if kind not in REPLY_KINDS:
        raise malformed(component, tick, t, f"unknown message kind {kind}")
    return kind


def _json_fields(component: str, data: bytes, tick: int | None, t: float,
                 *keys: str) -> dict[str, Any]:
    """The JSON object of a control reply, which must hold `keys` ("cause" a string);
    ComponentFailure (malformed reply) otherwise."""
    try:
        document = decode_json(data)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise malformed(component, tick, t, f"its JSON does not parse: {exc}") from None
    if not isinstance(document, dict):
        raise malformed(component, tick, t, f"its JSON is a {type(document).__name__}, "
                        f"not an object")
    missing = [key for key in keys if key not in document]
    if missing:
        raise malformed(component, tick, t, f"its JSON lacks {', '.join(map(repr, missing))}")
    for key in ("cause", "component"):
        if key in keys and not isinstance(document[key], str):
            raise malformed(component, tick, t, f"its JSON {key!r} is not a string")
    return document


def _build_error(component: str, document: dict[str, Any]) -> UserError:
    """The UserError of a component process that could not build its component
    (a ParameterProblem when it names the rejected parameter)."""
    if "parameter" in document and "problem" in document:
        from cosim.transport.inproc import ParameterProblem

        return ParameterProblem(component, str(document["parameter"]), str(document["problem"]))
    return UserError(document["cause"])
