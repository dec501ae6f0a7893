"""An FMU in a local process of its own (`isolate: true`), driven over two pipes.

`IsolatedFmu` is the master's HostedComponent: it starts
`python -m cosim.fmu.isolated` at once (its imports overlap the master's
start-up) and exchanges fixed binary frames with it; the process hosts the
FMU through the same host as the master does in-process (`FmuComponent`, or
`ModelExchangeComponent` with its solver), so the results are bit-identical.
A crash of the FMU (segfault, abort, exit) kills only that process: the
master reads the end of the pipe, takes its exit status and fails the run
with the usual one-line message; a call that does not return within the
deadline (its start and stop included) gets the process killed at once and
the same kind of message; a failure of its stop names the last tick, as in
the master's process. The process dies with the master (PR_SET_PDEATHSIG)
and ignores Ctrl-C (the master decides). Before it extracts the FMU (in its
start) it tells the master the folder, so that the master removes it
whatever becomes of the process.

Why pipes and not Zenoh: the process is always local and private to this
master (no key space, no credentials, nothing on the network); pipes work
under `--transport inproc` too; and one exchange costs a pipe round trip
(tens of microseconds) rather than a Zenoh one (about 100 us, DESIGN.md).

Frames, both ways: 4-byte length, 1-byte kind, payload. Master to process:
b"C" config (JSON, once), b"I" t0 + inputs, b"S" tick, t + inputs, b"Q" stop.
Process to master: b"R" ready, b"D" the folder it extracts the FMU into (before
the reply to b"I"), b"O" outputs, b"T" outputs + reason (the FMU asked to
terminate), b"M" metrics (JSON), b"E" failure (JSON: tick, time, cause, details).
"""

from __future__ import annotations

import ctypes
import json
import os
import select
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from cosim.component import Port, Value
from cosim.errors import ComponentFailure, StopRequested

LENGTH = struct.Struct("=I")
STEP = struct.Struct("=qd")
READY_TIMEOUT_S = 60.0  # process start-up (imports, unzipping): not an FMI call
STOP_WAIT_S = 1.0  # for the process to exit after its stop replied (else it is killed)
POLL_SLICE_MS = 100


class IsolatedFmu:
    """HostedComponent of an FMU in its own local process (see the module).

    Args:
        name: component name in the scenario.
        path: the .fmu file.
        interface: its `cosim.fmu.interface.FmuInterface` (ports known before start).
        variables: the scenario's name map (canonical -> FMU variable).
        parameters: canonical parameter values, already checked.
        period_ticks: master ticks between two steps.
        deadline_s: seconds an FMI call (one exchange) may take.
        log_file: run.log, or None (see `FmuComponent`).
        solver: a Model Exchange FMU's resolved `solver:` settings (see
            `ModelExchangeComponent`); None: co-simulation.
        kind: the scenario's `interface:` (which interface of the FMU to describe).
    """

    direct_feedthrough = False

    def __init__(self, name: str, path: str | Path, interface: Any, variables: Mapping[str, str],
                 parameters: Mapping[str, float], period_ticks: int, deadline_s: float,
                 log_file: str | Path | None = None, solver: Mapping[str, Any] | None = None,
                 kind: str | None = None) -> None:
        self.name, self.interface, self.period_ticks = name, interface, int(period_ticks)
        self.inputs: tuple[Port, ...] = tuple(interface.inputs)
        self.outputs: tuple[Port, ...] = tuple(interface.outputs)
        self.deadline_s = float(deadline_s)
        self._in, self._outs = _Flat(self.inputs), _Flat(self.outputs)
        self._out = struct.Struct(f"={self._outs.count}d")
        self._step_frame = struct.Struct(f"=Icqd{self._in.count}d")
        self._ready = False
        self._busy = False  # a request is out and its reply not read
        self._tick, self._t = 0, 0.0  # the last tick completed, and its time (named by a stop)
        self._folder: str | None = None  # where the process extracts the FMU (it said so)
        config = {"name": name, "path": str(path), "variables": dict(variables),
                  "parameters": {k: float(v) for k, v in parameters.items()},
                  "period_ticks": self.period_ticks,
                  "log_file": str(log_file) if log_file is not None else None,
                  "solver": dict(solver) if solver is not None else None, "kind": kind}
        self._spawn(config)

    def _spawn(self, config: dict[str, Any]) -> None:
        child_rx, master_tx = os.pipe()
        master_rx, child_tx = os.pipe()
        self.process = subprocess.Popen(
            [sys.executable, "-m", "cosim.fmu.isolated", str(child_rx), str(child_tx)],
            pass_fds=(child_rx, child_tx), stdin=subprocess.DEVNULL)
        os.close(child_rx)
        os.close(child_tx)
        self.pid = self.process.pid
        self._tx, self._rx = master_tx, master_rx
        self._poll = select.poll()
        self._poll.register(master_rx, select.POLLIN)
        _send(self._tx, b"C", json.dumps(config).encode())

    def wait_ready(self) -> None:
        """Wait for the process to have loaded the FMU (imports, unzipping: not an FMI
        call, so not under the call deadline; the run does it before tick 0's calls)."""
        if not self._ready:
            self._receive("start-up", None, 0.0, READY_TIMEOUT_S)
            self._ready = True

    def start(self, t0: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Wait for the process (if `wait_ready` was not called), then initialize the FMU
        there at t0."""
        self.wait_ready()
        values = self._in.flatten(inputs)
        self._t = t0
        self._request("start", None, t0, b"I", struct.pack(f"=d{len(values)}d", t0, *values))
        return self._outputs(self._receive("start", None, t0, self.deadline_s), None, t0)

    def step(self, tick: int, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """One doStep in the process: a request frame, a reply frame."""
        frame = self._step_frame
        try:
            os.write(self._tx, frame.pack(frame.size - 4, b"S", tick, t,
                                          *self._in.flatten(inputs)))
        except BrokenPipeError:
            raise self._died("step", tick, t) from None
        self._busy = True
        outputs = self._outputs(self._receive("step", tick, t, self.deadline_s), tick, t)
        self._tick, self._t = tick, t
        return outputs

    def stop(self) -> dict[str, float]:
        """Stop the FMU in the process (under the call deadline) and let it exit; killed at
        once if it is stuck, busy or not ready. A failure names the last tick completed."""
        metrics: dict[str, float] = {}
        replied = False
        try:
            if self.process.poll() is None and self._ready and not self._busy:
                self._request("stop", self._tick, self._t, b"Q", b"")
                kind, payload = self._receive("stop", self._tick, self._t, self.deadline_s,
                                              raw=True)
                replied = True
                metrics = json.loads(payload) if kind == b"M" else {}
        finally:
            self._end_process(STOP_WAIT_S if replied else 0.0)
        return metrics

    def _request(self, call: str, tick: int | None, t: float, kind: bytes,
                 payload: bytes) -> None:
        """Send a request frame (its reply is then due); a process already gone raises
        the ComponentFailure of its death."""
        try:
            _send(self._tx, kind, payload)
        except BrokenPipeError:
            raise self._died(call, tick, t) from None
        self._busy = True

    def _outputs(self, reply: tuple[bytes, bytes], tick: int | None, t: float) -> dict[str, Value]:
        kind, payload = reply
        values = self._outs.mapping(self._out.unpack_from(payload))
        if kind == b"T":
            reason = payload[self._out.size:].decode("utf-8", "replace")
            raise StopRequested(self.name, tick or 0, t, values, reason)
        return values

    def _receive(self, call: str, tick: int | None, t: float, timeout_s: float,
                 raw: bool = False) -> tuple[bytes, bytes]:
        """The next frame; a failure, a death or a timeout of the process raises ComponentFailure
        (the process then killed at once). A b"D" frame (the extraction folder) is noted
        and the next one read, within the same time."""
        end = time.monotonic() + timeout_s
        while True:
            if not self._wait_readable(max(end - time.monotonic(), 0.0)):
                self._end_process()
                raise ComponentFailure(self.name, tick, t, f"no return from its {call} within the "
                                       f"deadline of {timeout_s:g} s (its isolated process was "
                                       f"ended){_after(call, tick)}",
                                       {"kind": "deadline", "deadline_s": timeout_s})
            frame = _read_frame(self._rx)
            if frame is None:
                raise self._died(call, tick, t)
            if frame[0] != b"D":
                break
            self._folder = frame[1].decode()
        self._busy = False
        kind, payload = frame
        if kind == b"E":
            error = json.loads(payload)
            raise ComponentFailure(self.name, error["tick"], error["time"], error["cause"],
                                   error.get("details"))
        if raw or kind in (b"O", b"T", b"R"):
            return kind, payload
        raise ComponentFailure(self.name, tick, t, f"unexpected reply {kind!r} from its "
                               f"isolated process")

    def _wait_readable(self, timeout_s: float) -> bool:
        """Whether a reply came within `timeout_s`; waits in short slices, so that a
        Ctrl-C received by another thread (Zenoh's) is raised here without delay."""
        if self._poll.poll(0.0) or self._poll.poll(POLL_SLICE_MS):
            return True
        end = time.monotonic() + timeout_s
        while (left := end - time.monotonic()) > 0:
            if self._poll.poll(min(left * 1000.0, POLL_SLICE_MS)):
                return True
        return False

    def _died(self, call: str, tick: int | None, t: float) -> ComponentFailure:
        """The failure of a process whose pipe ended (it died, or closed the pipe: killed)."""
        self._end_process(STOP_WAIT_S)
        code = self.process.returncode
        where = f"in its {call}{_after(call, tick)}"
        if code < 0:
            name = signal.Signals(-code).name
            return ComponentFailure(self.name, tick, t, f"its isolated process was killed by "
                                    f"{name} {where}", {"kind": "signal", "signal": name})
        return ComponentFailure(self.name, tick, t, f"its isolated process exited with status "
                                f"{code} {where}", {"kind": "exit", "exit_code": code})

    def _end_process(self, wait_s: float = 0.0) -> None:
        """Close the pipe to the process (a process waiting for a request ends), give it
        `wait_s` to exit, else kill it; reap it, close the other pipe, remove the folder it
        extracted the FMU into (safe to call twice)."""
        if self._tx >= 0:
            os.close(self._tx)
            self._tx = -1
        if self.process.poll() is None:
            try:
                self.process.wait(timeout=wait_s)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        if self._rx >= 0:
            os.close(self._rx)
            self._rx = -1
        if self._folder is not None:
            shutil.rmtree(self._folder, ignore_errors=True)
            self._folder = None


def _after(call: str, tick: int | None) -> str:
    """" after tick N" for a stop (it comes after the last tick completed), else ""."""
    return f" after tick {tick}" if call == "stop" and tick is not None else ""


class _Flat:
    """Port values <-> the flat float64 run of a frame (an array port: `size` values in a row).

    Args:
        ports: the ports, in frame order.
    """

    def __init__(self, ports: tuple[Port, ...]) -> None:
        self.names = [p.name for p in ports]
        self.sizes = [p.size for p in ports]
        self.count = sum(self.sizes)
        self.scalar = all(size == 1 for size in self.sizes)

    def flatten(self, values: Mapping[str, Value]) -> list[float]:
        """The values of the ports, in a row."""
        if self.scalar:
            return [values[n] for n in self.names]
        return [x for n in self.names for x in np.ravel(values[n]).tolist()]

    def mapping(self, flat: Any) -> dict[str, Value]:
        """Port name -> value (arrays as float64 numpy arrays) from a flat row."""
        if self.scalar:
            return dict(zip(self.names, flat))
        out: dict[str, Value] = {}
        at = 0
        for name, size in zip(self.names, self.sizes):
            out[name] = flat[at] if size == 1 else np.array(flat[at:at + size], dtype=np.float64)
            at += size
        return out


def _send(fd: int, kind: bytes, payload: bytes) -> None:
    data = LENGTH.pack(len(payload) + 1) + kind + payload
    while data:
        data = data[os.write(fd, data):]


def _read_exactly(fd: int, size: int) -> bytes | None:
    chunks, left = [], size
    while left:
        chunk = os.read(fd, left)
        if not chunk:
            return None
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def _read_frame(fd: int) -> tuple[bytes, bytes] | None:
    """(kind, payload) of the next frame, or None at the end of the pipe."""
    head = _read_exactly(fd, LENGTH.size)
    if head is None:
        return None
    body = _read_exactly(fd, LENGTH.unpack(head)[0])
    return None if body is None else (body[:1], body[1:])


# ---- the process side -------------------------------------------------------------------

def _die_with_parent() -> None:
    """Linux: get SIGKILL when the master dies (the FMU may be stuck in native code)."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def serve(rx: int, tx: int) -> int:
    """Host one FMU for the master at the other end of the pipes; the exit status."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent()
    frame = _read_frame(rx)
    if frame is None or frame[0] != b"C":
        return 2
    config = json.loads(frame[1])
    fmu = _host(config)
    _send(tx, b"R", b"")
    return _loop(fmu, rx, tx)


def _host(config: dict[str, Any]) -> Any:
    """The in-process host of the FMU the config names (as the master would host it)."""
    from cosim.fmu.interface import describe_fmu
    from cosim.fmu.in_process import in_process_host

    interface = describe_fmu(Path(config["path"]), config["variables"], kind=config["kind"])
    return in_process_host(config["name"], config["path"], interface, config["parameters"],
                           config["period_ticks"], config["log_file"], config["solver"])


def _loop(fmu: Any, rx: int, tx: int) -> int:
    ins, outs = _Flat(fmu.inputs), _Flat(fmu.outputs)
    n_in = ins.count
    step_in = struct.Struct(f"=qd{n_in}d")
    reply = struct.Struct(f"=Ic{outs.count}d")
    while (frame := _read_frame(rx)) is not None:
        kind, payload = frame
        tick, t = None, 0.0
        try:
            if kind == b"S":
                tick, t, *values = step_in.unpack(payload)
                out = fmu.step(tick, t, ins.mapping(values))
            elif kind == b"I":
                t, *values = struct.unpack(f"=d{n_in}d", payload)
                fmu.unzip_dir = tempfile.mkdtemp()  # the master removes it if this process dies
                _send(tx, b"D", fmu.unzip_dir.encode())
                out = fmu.start(t, ins.mapping(values))
            else:  # b"Q": the reply (metrics or failure), then this process ends
                _send(tx, b"M", json.dumps(fmu.stop()).encode())
                return 0
        except StopRequested as request:
            data = reply.pack(reply.size - 4 + len(request.reason.encode()), b"T",
                              *outs.flatten(request.outputs))
            os.write(tx, data + request.reason.encode())
            continue
        except Exception as exc:  # noqa: BLE001 - every failure goes back to the master
            error = exc if isinstance(exc, ComponentFailure) else None
            _send(tx, b"E", json.dumps({"tick": error.tick if error else tick,
                                        "time": error.time if error else t,
                                        "cause": error.cause if error else repr(exc),
                                        "details": error.details if error else {}}).encode())
            if kind == b"Q":
                return 0
            continue
        os.write(tx, reply.pack(reply.size - 4, b"O", *outs.flatten(out)))
    return 0


if __name__ == "__main__":
    sys.exit(serve(int(sys.argv[1]), int(sys.argv[2])))
