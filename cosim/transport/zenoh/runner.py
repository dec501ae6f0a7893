"""Entry point of one component process, driven in lockstep by the master over Zenoh.

    python -m cosim.transport.zenoh.runner --name controller --spec-stdin

It loads its modules, then reads one JSON line on stdin: class path,
parameters, period, and its session (run id, the master's endpoint, the run's
credential or a worker's full Zenoh config), so nothing but its name is on its
command line. A master may start it before it knows the class (`cosim run`
starts it while it loads the scenario). For manual use, `--run-id`,
`--connect`, `--class` and `--params` give the same on the command line (a
plain session, without a credential).

The process joins the master's endpoint as a peer, declares a liveliness
token, builds the component (with Python's collector paused until then:
cosim.startup_gc), then answers requests in a blocking receive
loop in the main thread: HELLO (its port declarations, and whether its class
hears `use_outputs`), USE (the outputs the run reads, before START), START,
STEP and STOP.
Exceptions and bad outputs go back to the master as an ERROR reply. The
process ignores SIGINT (the master decides when it ends), exits at once when
the master's liveliness token disappears, and exits with status 3 when no
master asks for its handshake within the handshake timeout (an orphan of a
master that never came).
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import signal
import sys
import threading
import time
from collections.abc import Sequence
from typing import Any

import zenoh

from cosim import startup_gc
from cosim.component import Component, values_step
from cosim.errors import UserError
from cosim.transport.inproc import (USER_CODE_ERRORS, ParameterProblem, PythonComponentLaunch,
                                    construct_component, describe_exception)
from cosim.engine import one_cpu
from cosim.engine.startup import process_age_s
from cosim.transport.launch import steps_from_json
from cosim.engine.values import lane_result_problem
from cosim.transport.zenoh import auth, config
from cosim.transport.zenoh.auth import Credential
from cosim.transport.zenoh.codec import (CodecError, Kind, Layout, HEADER, decode_json,
                                         encode_json, ports_to_json)

MASTER_POLL_S = 0.1
HANDSHAKE_TIMEOUT_S = 30.0
# This process ignores SIGINT (the master handles Ctrl-C): a KeyboardInterrupt here came
# from the component's own code, and fails the component like any of its errors.
COMPONENT_ERRORS = (*USER_CODE_ERRORS, KeyboardInterrupt)
ORPHAN_EXIT = 3
_STEP, _OUTPUTS = Kind.STEP, Kind.OUTPUTS


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Command line of the runner (see the module docstring).

    Args:
        argv: arguments without the program name; None for sys.argv[1:].
    """
    parser = argparse.ArgumentParser(prog="cosim.transport.zenoh.runner")
    parser.add_argument("--name", required=True, help="component name in the scenario")
    parser.add_argument("--run-id", default="", help="run id scoping every key")
    parser.add_argument("--connect", default="", help="the master's Zenoh endpoint")
    parser.add_argument("--class", dest="class_path", help="module:Class")
    parser.add_argument("--params", default="{}", help="constructor parameters as JSON")
    parser.add_argument("--period-ticks", type=int, default=1, help="for ps and logs only")
    parser.add_argument("--zenoh-config", default=None,
                        help="full session config as JSON (a worker's TLS/ACL); replaces the "
                             "default peer config, --connect then only names the master")
    parser.add_argument("--spec-stdin", action="store_true",
                        help="read class, parameters and period as one JSON line on stdin "
                             "(a process started before the master knew them)")
    parser.add_argument("--preload", default=None,
                        help="with --spec-stdin: a module to import while waiting for the spec")
    args = parser.parse_args(argv)
    if not args.class_path and not args.spec_stdin:
        parser.error("give --class or --spec-stdin")
    if args.class_path and not (args.run_id and args.connect):
        parser.error("--class needs --run-id and --connect")
    args.credential, args.session_config = None, None
    args.handshake_timeout_s = HANDSHAKE_TIMEOUT_S
    return args


class _Server:
    """Answers the master's requests for one component."""

    def __init__(self, launch: PythonComponentLaunch, ages: dict[str, float | None],
                 greeted: threading.Event) -> None:
        self.launch = launch
        self.greeted = greeted  # set by the first HELLO: a master is there
        self.ages = ages  # start-up marks: seconds since this process started
        self.component: Component | None = None
        self.build_error = ""
        self.build_detail: dict[str, str] = {}  # the parameter a constructor rejected, if known
        try:
            # its thread waits between steps: a compiled part may load beside them, on a CPU
            # beside the lockstep chain's (not on a sweep worker's one CPU: there it would
            # share that CPU with the chain, and the whole run would take longer)
            self.component = construct_component(launch, load_beside=bool(one_cpu.cpus_beside()))
        except ParameterProblem as exc:
            self.build_error = str(exc)
            self.build_detail = {"parameter": exc.parameter, "problem": exc.problem}
        except UserError as exc:
            self.build_error = str(exc)
        except COMPONENT_ERRORS as exc:  # user code in __init__: report, do not crash
            self.build_error = (f"component {launch.name!r}: constructor failed: "
                                f"{describe_exception(exc)}")
        if self.component is not None:
            self.in_layout = Layout(self.component.inputs, "input")
            self.out_layout = Layout(self.component.outputs)
            # bound once: the step path below is the per-tick hot path; a component with
            # `step_values` (scalar outputs) is stepped on the values in declared order
            lane = values_step(self.component)
            self._lane_count: int | None = None  # outputs a step_values result must hold
            if lane is not None:
                self._decode, self._encode = self.in_layout.decode_values, self.out_layout.encode_values
                self._step_component = lane
                self._lane_count = len(self.component.outputs)
            else:
                self._decode, self._encode = self.in_layout.decode, self.out_layout.encode
                self._step_component = self.component.step

    def handle(self, data: bytes) -> tuple[bytes | None, bool]:
        """The reply to one request, and whether the process should end after it."""
        kind, seq, tick, t = HEADER.unpack_from(data)
        if kind == _STEP and self.component is not None:
            try:
                outputs = self._step_component(t, self._decode(data))
            except COMPONENT_ERRORS as exc:  # user code: the master reports it with tick and time
                cause = describe_exception(exc)
                return encode_json(Kind.ERROR, seq, tick, t, {"cause": cause}), False
            if self._lane_count is not None and (problem := lane_result_problem(outputs, self._lane_count)):
                return encode_json(Kind.ERROR, seq, tick, t, {"cause": problem}), False
            try:
                return self._encode(_OUTPUTS, seq, tick, t, outputs, True), False
            except CodecError as exc:
                return encode_json(Kind.ERROR, seq, tick, t, {"cause": str(exc)}), False
        if kind == Kind.HELLO:
            return self._hello(seq), False
        if self.component is None:
            return encode_json(Kind.ERROR, seq, tick, t, {"cause": self.build_error}), True
        if kind == Kind.START:
            return self._step(kind, seq, tick, t, data), False
        if kind == Kind.USE:
            return self._use(seq, data), False
        if kind == Kind.STOP:
            return self._stop(seq, tick, t), True
        return None, False

    def _hello(self, seq: int) -> bytes:
        self.greeted.set()
        if self.component is None:
            return encode_json(Kind.ERROR, seq, -1, 0.0, {"cause": self.build_error, "build": True,
                                                     **self.build_detail})
        return encode_json(Kind.PORTS, seq, -1, 0.0, {
            "inputs": ports_to_json(self.component.inputs),
            "outputs": ports_to_json(self.component.outputs), "pid": os.getpid(),
            "uses_outputs": type(self.component).use_outputs is not Component.use_outputs,
            "startup_s": {**self.ages, "ready": process_age_s(), "cpu": time.process_time()}})

    def _step(self, kind: int, seq: int, tick: int, t: float, data: bytes) -> bytes:
        assert self.component is not None
        if kind == Kind.START:  # every array afresh, both ways (see codec.Layout)
            self.in_layout.forget()
            self.out_layout.forget()
        try:
            inputs = self.in_layout.decode(data)
            if kind == Kind.START:
                outputs = self.component.initialize(t, inputs)
            else:
                outputs = self.component.step(t, inputs)
        except COMPONENT_ERRORS as exc:  # user code: the master reports it with tick and time
            return encode_json(Kind.ERROR, seq, tick, t, {"cause": describe_exception(exc)})
        try:
            return self.out_layout.encode(Kind.OUTPUTS, seq, tick, t, outputs, finite=True)
        except CodecError as exc:
            return encode_json(Kind.ERROR, seq, tick, t, {"cause": str(exc)})

    def _use(self, seq: int, data: bytes) -> bytes:
        assert self.component is not None
        try:
            self.component.use_outputs(frozenset(decode_json(data)["outputs"]))
        except COMPONENT_ERRORS as exc:
            cause = f"use_outputs() failed: {describe_exception(exc)}"
            return encode_json(Kind.ERROR, seq, -1, 0.0, {"cause": cause})
        return encode_json(Kind.USED, seq, -1, 0.0, {})

    def _stop(self, seq: int, tick: int, t: float) -> bytes:
        assert self.component is not None
        try:
            metrics = self.component.finish() or {}
            document: dict[str, Any] = {str(k): float(v) for k, v in metrics.items()}
        except COMPONENT_ERRORS as exc:
            cause = f"finish() failed: {describe_exception(exc)}"
            return encode_json(Kind.ERROR, seq, tick, t, {"cause": cause})
        return encode_json(Kind.METRICS, seq, tick, t, document)


def _exit_when_master_gone(session: zenoh.Session, run_id: str) -> None:
    """Start a thread that ends this process when the master's liveliness token goes away."""
    watcher = session.liveliness().declare_subscriber(config.master_alive_key(run_id), history=True)

    def poll() -> None:
        while True:
            sample = watcher.try_recv()
            if sample is None:
                time.sleep(MASTER_POLL_S)
            elif sample.kind == zenoh.SampleKind.DELETE:
                os._exit(0)  # the master is gone: nobody will ever stop us

    threading.Thread(target=poll, name="master-watch", daemon=True).start()


def _exit_without_handshake(greeted: threading.Event, timeout_s: float) -> None:
    """Start a thread that ends this process when no HELLO came within `timeout_s`."""

    def wait() -> None:
        if not greeted.wait(timeout_s):
            print(f"no master asked for the handshake within {timeout_s:g} s: exiting",
                  file=sys.stderr, flush=True)
            os._exit(ORPHAN_EXIT)

    threading.Thread(target=wait, name="handshake-timeout", daemon=True).start()


def _session_config(args: argparse.Namespace) -> zenoh.Config:
    """The session: a worker's full config, else a peer joining the master with the
    run's credential (if any)."""
    if args.session_config:
        return zenoh.Config.from_json5(json.dumps(args.session_config))
    if args.zenoh_config:
        return zenoh.Config.from_json5(args.zenoh_config)
    return config.client_peer_config(args.connect, auth.security_settings(args.credential))


def _launch(args: argparse.Namespace) -> PythonComponentLaunch | None:
    """What to host: from the command line, or from one JSON line on stdin (None at EOF)."""
    if not args.spec_stdin:
        return PythonComponentLaunch(name=args.name, class_path=args.class_path,
                                     parameters=json.loads(args.params),
                                     period_ticks=args.period_ticks)
    if args.preload:
        try:
            importlib.import_module(args.preload)
        except COMPONENT_ERRORS:  # a guess: the real import names any problem
            pass
    line = sys.stdin.readline()
    if not line.strip():
        return None
    spec = json.loads(line)
    args.run_id = config.check_key_chunk(str(spec.get("run_id") or args.run_id), "run_id")
    args.connect = str(spec.get("connect") or args.connect)
    args.credential = Credential.from_json(spec.get("auth"))
    args.session_config = spec.get("zenoh_config")
    args.handshake_timeout_s = float(spec.get("handshake_timeout_s") or HANDSHAKE_TIMEOUT_S)
    return PythonComponentLaunch(name=args.name, class_path=str(spec["class_path"]),
                                 parameters=dict(spec["parameters"]),
                                 period_ticks=int(spec["period_ticks"]),
                                 steps=steps_from_json(spec.get("steps")))


def serve(args: argparse.Namespace) -> int:
    """Open the session, build the component, answer requests until STOP."""
    ages = {"imported": process_age_s()}
    launch = _launch(args)
    if launch is None:
        return 0  # prestarted, then not needed: the master closed our stdin
    ages["spec"] = process_age_s()  # = "imported" unless prestarted (then: spec received)
    with zenoh.open(_session_config(args)) as session:
        _exit_when_master_gone(session, args.run_id)
        greeted = threading.Event()
        token = session.liveliness().declare_token(config.alive_key(args.run_id, args.name))
        ages["session"] = process_age_s()
        # Build first, then subscribe: the master's HELLO retries sent while a slow
        # constructor runs are not delivered, so they cannot fill the request queue.
        server = _Server(launch, ages, greeted)
        ages["built"] = process_age_s()
        # from here a master's HELLO can arrive: the constructor's time is the master's
        # start-up timeout to judge (a master gone meanwhile is noticed by its token)
        _exit_without_handshake(greeted, args.handshake_timeout_s)
        startup_gc.resume(freeze=True)  # built: what it made lives as long as the process
        requests = session.declare_subscriber(config.request_key(args.run_id, args.name))
        publisher = session.declare_publisher(config.reply_key(args.run_id, args.name),
                                              express=True)
        done = False
        while not done:
            data = requests.recv().payload.to_bytes()
            reply, done = server.handle(data)
            if reply is not None:
                publisher.put(reply)
        token.undeclare()
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run one component process; see the module docstring.

    Args:
        argv: command-line arguments without the program name (None: sys.argv).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    startup_gc.pause()  # until the component is built (serve), or the process ends
    if os.getcwd() not in sys.path:
        sys.path.insert(0, os.getcwd())
    args = parse_args(argv)
    try:
        return serve(args)
    finally:
        startup_gc.resume()


if __name__ == "__main__":
    sys.exit(main())
