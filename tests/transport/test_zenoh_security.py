"""Security of a local Zenoh run on loopback: nothing of the run is on a command
line, and a process without the run's credential can neither see its signals
nor inject into it (counted: 0), while the same spy holding the credential does
both (so the counts can fail)."""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest
import zenoh

from cosim.transport.inproc import InprocComponent
from cosim.transport.zenoh import ZenohComponents, config
from cosim.transport.zenoh.auth import Credential, new_credential, security_settings
from cosim.transport.zenoh.wire import HEADER, Kind
from tests.helpers.components import bits, launch

pytestmark = [pytest.mark.integration, pytest.mark.timeout(120)]

FORGED = b"FORGED-BY-SPY"
NAMES = ["mixer.y", "mixer.s"]


class Spy:
    """Another peer on the run's endpoint: counts what it receives of the run and
    forges outputs, errors and steps on the run's control keys, in a thread."""

    def __init__(self, endpoint: str, run_id: str, credential: Credential | None,
                 listen: str = "cosim/**") -> None:
        conf = config.client_peer_config(endpoint, security_settings(credential))
        self.session = zenoh.open(conf)
        self.seen = 0
        self.sent = 0
        self._sub = self.session.declare_subscriber(listen, zenoh.handlers.RingChannel(256))
        self._keys = [config.reply_key(run_id, "mixer"), config.request_key(run_id, "mixer"),
                      config.live_data_key(run_id)]
        self._halt = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        forged = HEADER.pack(Kind.ERROR, 1, 0, 0.0) + FORGED
        while not self._halt.wait(0.005):
            for key in self._keys:
                self.session.put(key, forged)
                self.sent += 1
            while (sample := self._sub.try_recv()) is not None:
                self.seen += FORGED not in sample.payload.to_bytes()  # not its own puts

    def close(self) -> None:
        self._halt.set()
        self._thread.join()
        self.session.close()


def _forged_count(subscriber) -> int:
    count = 0
    while (sample := subscriber.try_recv()) is not None:
        count += FORGED in sample.payload.to_bytes()
    return count


def _wait_matching(hosted: ZenohComponents) -> None:
    end = time.monotonic() + 30
    while not hosted.live_matching:
        assert time.monotonic() < end, "the authorised watcher never subscribed"
        time.sleep(0.02)


def test_no_run_id_endpoint_or_credential_on_a_component_command_line():
    run_id = f"t-argv-{os.getpid()}"
    with ZenohComponents([launch("mixer", "Mixer")], run_id) as hosted:
        with open(f"/proc/{hosted.pids['mixer']}/cmdline", "rb") as f:
            argv = f.read()
        port = hosted.endpoint.rsplit(":", 1)[1]
        assert b"--name\0mixer\0" in argv
        for secret in (run_id, port, hosted.credential.password, hosted.credential.user):
            assert secret.encode() not in argv


@pytest.mark.parametrize("who", ["no credential", "wrong password", "another run's"])
def test_a_peer_without_the_credential_sees_nothing_and_injects_nothing(who):
    run_id = f"t-spy-{os.getpid()}"
    credential = new_credential(run_id)
    spy_credential = {"no credential": None,
                      "wrong password": Credential(credential.user, "not-the-password"),
                      "another run's": new_credential("other")}[who]
    spec = launch("mixer", "Mixer", gain=1.5)
    local = InprocComponent(spec)
    with ZenohComponents([spec], run_id, credential=credential) as hosted:
        spy = Spy(hosted.endpoint, run_id, spy_credential)
        watcher = zenoh.open(config.client_peer_config(hosted.endpoint,
                                                       security_settings(credential)))
        live = watcher.declare_subscriber(config.live_data_key(run_id),
                                          zenoh.handlers.RingChannel(4096))
        inbox = hosted.session.declare_subscriber(f"cosim/{run_id}/**",
                                                  zenoh.handlers.RingChannel(4096))
        try:
            _wait_matching(hosted)
            remote = hosted.components["mixer"]
            inputs = {"u": 0.5, "w": np.array([1.0, 2.0, 3.0])}
            assert bits(remote.start(0.0, inputs)) == bits(local.start(0.0, inputs))
            forged = 0
            for k in range(1, 301):
                step_in = {"u": k * 0.1, "w": np.array([k, -k, 0.5])}
                assert bits(remote.step(k, k * 0.01, step_in)) == \
                    bits(local.step(k, k * 0.01, step_in))
                hosted.publish(k, k * 0.01, NAMES, np.array([k, -k], dtype=float))
                forged += _forged_count(inbox)
            assert remote.stop() == local.stop()
            time.sleep(0.2)
            forged += _forged_count(inbox)
            watched = 0
            while live.try_recv() is not None:
                watched += 1
        finally:
            spy.close()
            watcher.close()
    assert spy.sent > 100 and watched > 0  # the spy was busy; the run did publish
    assert (spy.seen, forged) == (0, 0)


def test_the_same_spy_with_the_credential_sees_and_injects():
    """The control: what the spy counts is real, so the zeros above can fail."""
    run_id = f"t-spy-ok-{os.getpid()}"
    credential = new_credential(run_id)
    with ZenohComponents([], run_id, credential=credential) as hosted:
        inbox = hosted.session.declare_subscriber(f"cosim/{run_id}/**",
                                                  zenoh.handlers.RingChannel(4096))
        # with the credential, the run's ACL still refuses a subscription to all of cosim/**
        spy = Spy(hosted.endpoint, run_id, credential, f"cosim/{run_id}/**")
        try:
            _wait_matching(hosted)
            forged = 0
            for k in range(1, 101):
                hosted.publish(k, k * 0.01, NAMES, np.array([k, -k], dtype=float))
                forged += _forged_count(inbox)
                time.sleep(0.005)
        finally:
            spy.close()
    assert spy.seen > 0 and forged > 0
