"""Malformed messages on a component's reply key (short, of an unknown kind, of the
wrong size, bad JSON) fail the run as that component's failure at that tick,
"malformed reply: ...", never with a traceback of the master; and the codec
refuses a mask byte that is neither 0 nor 1."""

from __future__ import annotations

import os

import numpy as np
import pytest

from cosim.component import Port
from cosim.errors import ComponentFailure
from cosim.transport.zenoh import ZenohComponents, config
from cosim.transport.zenoh.codec import HEADER, CodecError, Kind, Layout, encode_json
from tests.helpers.components import launch, run_processes

pytestmark = [pytest.mark.integration, pytest.mark.timeout(60)]
TICK = 0.01
W = np.array([0.25, 0.5, -1.0])


def forged_failure(make_message, at_tick=3):
    """Run a Mixer; before tick `at_tick`, put make_message(next seq, tick) on its reply
    key; return the ComponentFailure (and check no process is left)."""
    run_id = f"t-malformed-{os.getpid()}"
    with pytest.raises(ComponentFailure) as caught:
        with ZenohComponents([launch("mixer", "Mixer")], run_id, deadline_s=30.0) as hosted:
            comp = hosted.components["mixer"]
            comp.start(0.0, {"u": 1.0, "w": W})
            for k in range(1, 6):
                if k == at_tick:
                    hosted.session.put(config.reply_key(run_id, "mixer"),
                                       make_message(hosted._seq + 1, k))
                comp.step(k, k * TICK, {"u": 1.0, "w": W})
    assert run_processes(run_id) == []
    return caught.value


@pytest.mark.parametrize("make_message, cause", [
    (lambda seq, k: b"garbage",
     "malformed reply: 7 bytes, shorter than the 32-byte message header"),
    (lambda seq, k: HEADER.pack(99, seq, k, k * TICK),
     "malformed reply: unknown message kind 99"),
    (lambda seq, k: HEADER.pack(Kind.OUTPUTS, seq, k, k * TICK) + bytes(8),
     "malformed reply: message of 40 bytes, shorter than the 56 of ports "
     "['y', 'z', 'count'] without arrays"),
    (lambda seq, k: HEADER.pack(Kind.ERROR, seq, k, k * TICK) + b"\xff{",
     "malformed reply: its JSON does not parse: 'utf-8' codec can't decode byte 0xff in "
     "position 0: invalid start byte"),
    (lambda seq, k: encode_json(Kind.ERROR, seq, k, k * TICK, ["cause"]),
     "malformed reply: its JSON is a list, not an object"),
    (lambda seq, k: encode_json(Kind.ERROR, seq, k, k * TICK, {"cause": 5}),
     "malformed reply: its JSON 'cause' is not a string"),
    (lambda seq, k: encode_json(Kind.DIED, seq, k, k * TICK, {"component": "ghost",
                                                               "cause": "x"}),
     "malformed reply: a death notice of 'ghost', which is no component of this run"),
])
def test_malformed_reply_fails_the_component_at_its_tick(make_message, cause):
    failure = forged_failure(make_message)
    assert (failure.component, failure.tick, failure.time) == ("mixer", 3, 3 * TICK)
    assert failure.cause == cause
    assert failure.details == {"kind": "malformed_reply"}
    assert str(failure) == f"component 'mixer' failed at tick 3 (t=0.03 s): {cause}"


def test_stale_well_formed_replies_are_still_skipped():
    """A reply of a valid kind with another seq is stale, not malformed: the run goes on."""
    run_id = f"t-stale-{os.getpid()}"
    with ZenohComponents([launch("mixer", "Mixer")], run_id, deadline_s=30.0) as hosted:
        comp = hosted.components["mixer"]
        comp.start(0.0, {"u": 1.0, "w": W})
        hosted.session.put(config.reply_key(run_id, "mixer"),
                           HEADER.pack(Kind.OUTPUTS, 10**6, 1, TICK))
        outputs = comp.step(1, TICK, {"u": 1.0, "w": W})
        assert outputs["count"] == 2.0  # start, then this step: the real reply
    assert run_processes(run_id) == []


def test_mask_byte_must_be_zero_or_one():
    ports = (Port("a"), Port("b", size=2))
    sender, receiver = Layout(ports), Layout(ports)
    message = bytearray(sender.encode(Kind.OUTPUTS, 1, 1, 0.0, {"a": 1.0, "b": [2.0, 3.0]}))
    assert receiver.decode(bytes(message))["a"] == 1.0
    message[HEADER.size] = 7
    with pytest.raises(CodecError) as error:
        receiver.decode(bytes(message))
    assert str(error.value) == "mask byte 7 of output 'b' is neither 0 (held) nor 1 (sent)"


class _Sample:
    def __init__(self, data: bytes) -> None:
        self.payload = self
        self._data = data

    def to_bytes(self) -> bytes:
        return self._data


class _Replies:
    def __init__(self, *messages: bytes) -> None:
        self._messages = list(messages)

    def try_recv(self):
        return _Sample(self._messages.pop(0)) if self._messages else None


@pytest.mark.parametrize("message, cause", [
    (b"\x0b", "malformed reply: 1 bytes, shorter than the 32-byte message header"),
    (HEADER.pack(77, 0, -1, 0.0), "malformed reply: unknown message kind 77"),
    (encode_json(Kind.PORTS, 0, -1, 0.0, {"inputs": []}),
     "malformed reply: its JSON lacks 'outputs', 'pid'"),
    (encode_json(Kind.PORTS, 0, -1, 0.0, {"inputs": [{"name": "u"}], "outputs": [], "pid": 1}),
     "malformed reply: its port declarations do not parse: KeyError: 'size'"),
    (encode_json(Kind.ERROR, 0, -1, 0.0, {}), "malformed reply: its JSON lacks 'cause'"),
])
def test_malformed_handshake_reply_fails_during_initialization(message, cause):
    spec = launch("mixer", "Mixer")
    hosted = ZenohComponents([spec], "t-malformed-hello")
    with pytest.raises(ComponentFailure) as error:
        hosted._collect_hellos({"mixer": spec}, {"mixer": (None, _Replies(message))}, {},
                               float("inf"))
    assert (error.value.component, error.value.tick, error.value.cause) == ("mixer", None, cause)
    assert str(error.value) == f"component 'mixer' failed during initialization (t=0 s): {cause}"


def test_malformed_metrics_at_stop_are_a_malformed_reply():
    """Its stop has no tick: the master's stop_all places it at the run's last one."""
    run_id = f"t-malformed-stop-{os.getpid()}"
    with ZenohComponents([launch("mixer", "Mixer")], run_id, deadline_s=30.0) as hosted:
        comp = hosted.components["mixer"]
        comp.start(0.0, {"u": 1.0, "w": W})
        hosted.session.put(config.reply_key(run_id, "mixer"),
                           encode_json(Kind.METRICS, hosted._seq + 1, -1, 0.0, {"steps": "x"}))
        with pytest.raises(ComponentFailure) as caught:
            comp.stop()
    assert (caught.value.tick, caught.value.details) == (None, {"kind": "malformed_reply"})
    assert caught.value.cause == "malformed reply: its metrics are not a JSON object of numbers"
    assert run_processes(run_id) == []
