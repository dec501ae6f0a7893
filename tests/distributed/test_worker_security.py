"""Whom a worker serves, on loopback: an unauthenticated start is refused, a peer
without the credential cannot even reach the worker, orphans of a master that
never came or that vanished are reaped, a stop from another run is refused, and
`--max-components` caps what it hosts."""

from __future__ import annotations

import os
import time

import pytest
import zenoh

from cosim.distributed import protocol as proto
from cosim.distributed.client import ask_worker
from cosim.distributed.deploy import DeploySettings, zenoh_config
from cosim.distributed.worker import Worker
from cosim.transport.zenoh.config import free_tcp_endpoint, master_alive_key
from tests.distributed.test_worker import TEST_ALLOW, WorkerThread
from tests.helpers.credentials import shared_auth

pytestmark = [pytest.mark.integration, pytest.mark.timeout(120)]

ORPHAN_S = 1.0  # the test's orphan timeout (default 30 s)


def start_request(run_id: str, token: str, endpoint: str, component: str = "mix") -> dict:
    return {"op": "start", "run_id": run_id, "run_token": token, "component": component,
            "class_path": "tests.helpers.components:Mixer", "parameters": {},
            "connect": [endpoint]}


def alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rpartition(")")[2].split()[0] != "Z"
    except OSError:
        return False


def wait_gone(pid: int, bound_s: float = 30.0) -> bool:
    """Whether `pid` ends before `bound_s` (a bound against hanging, not a timing)."""
    end = time.monotonic() + bound_s
    while alive(pid) and time.monotonic() < end:
        time.sleep(0.05)
    return not alive(pid)


@pytest.fixture
def guarded():
    """A worker with the shared credential and a short orphan timeout, and a session
    that holds the credential (a master)."""
    endpoint = free_tcp_endpoint()
    settings = DeploySettings(listen=[endpoint], auth=shared_auth())
    agent = WorkerThread("wsec", settings)
    agent.worker.orphan_timeout_s = ORPHAN_S
    master = zenoh.open(zenoh_config(DeploySettings(auth=shared_auth()), "peer", [], [endpoint]))
    yield agent, master, endpoint
    master.close()
    agent.close()


def test_a_worker_without_a_way_to_authenticate_refuses_starts_unless_insecure():
    strict = Worker("wplain", DeploySettings(), TEST_ALLOW)
    reply = strict.handle(proto.encode(start_request("r1", "t", "tcp/127.0.0.1:1")))
    assert reply["ok"] is False
    assert "worker 'wplain'" in reply["error"] and "cannot authenticate masters" in reply["error"]
    assert "--insecure" in reply["error"] and strict.info()["running"] == 0
    loose = Worker("wloose", DeploySettings(), TEST_ALLOW, insecure=True, max_components=1,
                   orphan_timeout_s=ORPHAN_S)
    try:
        first = loose.handle(proto.encode(start_request("r1", "t", "tcp/127.0.0.1:1")))
        assert first["ok"] is True
        second = loose.handle(proto.encode(start_request("r1", "t", "tcp/127.0.0.1:1", "other")))
        assert second["ok"] is False
        assert "refuses component 'other': it already hosts 1 components " \
               "(--max-components 1)" in second["error"]
        # nobody ever asks for its handshake: the component ends by itself
        assert wait_gone(first["pid"])
    finally:
        loose._stop_all()


def test_a_peer_without_the_credential_cannot_reach_the_worker(guarded):
    agent, master, endpoint = guarded
    assert ask_worker(master, "wsec", {"op": "info"}, 2.0)["name"] == "wsec"  # the control
    intruder = zenoh.open(zenoh_config(DeploySettings(), "peer", [], [endpoint]))
    try:
        replies = [ask_worker(intruder, "wsec", request, 1.0) for request in
                   ({"op": "info"}, start_request("r-x", "t", endpoint))]
    finally:
        intruder.close()
    assert replies == [None, None] and agent.worker.info()["running"] == 0


def test_an_orphan_whose_master_never_came_is_reaped(guarded):
    agent, master, _ = guarded
    reply = ask_worker(master, "wsec", start_request("ghost", "t", free_tcp_endpoint()), 5.0)
    assert reply["ok"] is True and alive(reply["pid"])
    assert wait_gone(reply["pid"])
    end = time.monotonic() + 10
    while agent.worker.info()["running"] and time.monotonic() < end:
        time.sleep(0.05)
    assert agent.worker.info()["running"] == 0


def test_a_component_whose_master_vanishes_is_reaped_and_a_foreign_stop_is_refused(guarded):
    agent, master, endpoint = guarded
    agent.worker.orphan_timeout_s = 120.0  # only the master's disappearance can end it here
    run_id = f"t-vanish-{os.getpid()}"
    token = master.liveliness().declare_token(master_alive_key(run_id))
    reply = ask_worker(master, "wsec", start_request(run_id, "right", free_tcp_endpoint()), 5.0)
    assert reply["ok"] is True
    pid = reply["pid"]
    foreign = ask_worker(master, "wsec", {"op": "stop", "run_id": run_id, "component": "mix",
                                         "run_token": "another run"}, 5.0)
    assert foreign["ok"] is False
    assert "refuses to stop component 'mix' of run" in foreign["error"]
    assert "not come from the run that started it" in foreign["error"] and alive(pid)
    token.undeclare()  # the master disappears
    assert wait_gone(pid)
