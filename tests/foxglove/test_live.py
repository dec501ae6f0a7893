"""`cosim run --foxglove`: a WebSocket client receives the live run; the signals do not change."""

from __future__ import annotations

import json
import struct
import threading
import time
from pathlib import Path

import pytest
from websockets.sync.client import connect

from cosim.cli.app import main
from cosim.errors import UserError
from cosim.execution.run import run_scenario
from cosim.foxglove.live import FoxgloveLive, static_scene
from cosim.scenario.loader import load_scenario
from tests.helpers.paths import SCENARIOS_DIR

SUBPROTOCOL = "foxglove.sdk.v1"   # the SDK server speaks this (the v1 protocol under a new name)
WAIT_S = 30.0   # a bound on every wait, never an assertion on time
UNKNOWN_CHANNEL = "Unknown channel ID: "  # the server's status for a refused subscription


class Gate:
    """Test observer after the live one: slows the run (never beyond WAIT_S) until the client got data."""

    def __init__(self) -> None:
        self.received = threading.Event()
        self.started = time.monotonic()

    def begin(self, master) -> None:
        self.started = time.monotonic()

    def after_tick(self, tick, t, values, arrays) -> None:
        if not self.received.is_set() and time.monotonic() - self.started < WAIT_S:
            self.received.wait(0.01)


def client(url: str, gate: Gate, found: dict) -> None:
    """Subscribe to /tf, /signals/vehicle and /scene/road; collect what arrives."""
    # close_timeout: the server does not answer the closing handshake, so closing waits that long
    with connect(url, subprotocols=[SUBPROTOCOL], open_timeout=WAIT_S, close_timeout=1) as ws:
        channels: dict[int, dict] = {}
        deadline = time.monotonic() + WAIT_S
        subscribed: dict[int, str] = {}  # subscription id -> topic
        while time.monotonic() < deadline and not gate.received.is_set():
            frame = ws.recv(timeout=WAIT_S)
            if isinstance(frame, str):
                op = json.loads(frame)
                found.setdefault("ops", []).append(op["op"])
                for ch in op.get("channels", []) if op["op"] == "advertise" else []:
                    channels[ch["id"]] = ch
                if op["op"] == "status" and op.get("message", "").startswith(UNKNOWN_CHANNEL):
                    # the SDK's server sends an advertisement before it registers the channel
                    # for the client: a subscription in between is refused; subscribe again
                    refused = int(op["message"][len(UNKNOWN_CHANNEL):])
                    subscribed.pop(100 + refused, None)
                wanted = [c for c in channels.values() if c["topic"] in ("/tf", "/signals/vehicle", "/scene/road")
                          and c["topic"] not in subscribed.values()]  # once each: a repeat draws a status
                if wanted:
                    subs = [{"id": 100 + c["id"], "channelId": c["id"]} for c in wanted]
                    subscribed.update({s["id"]: channels[s["channelId"]]["topic"] for s in subs})
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                found["channels"] = {c["topic"]: c["schemaName"] for c in channels.values()}
            elif frame[0] == 1:   # message data: opcode, subscription id, log time, payload
                sub, log_time = struct.unpack_from("<IQ", frame, 1)
                found.setdefault(subscribed[sub], []).append((log_time, frame[13:]))
                if all(found.get(t) for t in ("/tf", "/signals/vehicle", "/scene/road")):
                    gate.received.set()
    gate.received.set()


def run_lane_change(out: Path, observers=()) -> bytes:
    scenario = load_scenario(SCENARIOS_DIR / "lane_change.yaml", ["duration=4"])
    assert run_scenario(scenario, out, transport="inproc", progress=False, observers=observers).status == "ok"
    return (out / "signals.csv").read_bytes()


def test_client_gets_advertisements_and_messages_and_signals_are_unchanged(tmp_path):
    plain = run_lane_change(tmp_path / "plain")
    scenario = load_scenario(SCENARIOS_DIR / "lane_change.yaml", ["duration=4"])
    gate, found = Gate(), {}
    with FoxgloveLive(port=0, static=static_scene(scenario)) as live:
        assert live.url.startswith("ws://127.0.0.1:")
        thread = threading.Thread(target=client, args=(live.url, gate, found), daemon=True)
        thread.start()
        served = run_lane_change(tmp_path / "served", [live, gate])
        thread.join(WAIT_S)
    assert served == plain                                  # bit-identical signals
    assert found["ops"][0] == "serverInfo" and "advertise" in found["ops"]
    assert found["channels"]["/tf"] == "foxglove.FrameTransform"
    assert found["channels"]["/scene/planner.ref"] == "foxglove.SceneUpdate"
    log_time, payload = found["/signals/vehicle"][0]
    message = json.loads(payload)
    assert {"t", "x", "y", "psi", "vx"} <= set(message) and log_time == round(message["t"] * 1e9)
    assert found["/tf"] and found["/scene/road"]


def test_loopback_only_and_port_errors(tmp_path):
    with pytest.raises(UserError, match="listens on loopback only"):
        FoxgloveLive(port=0, host="0.0.0.0")
    with FoxgloveLive(port=0) as first:
        with pytest.raises(UserError, match=f"cannot listen on 127.0.0.1:{first.port}"):
            FoxgloveLive(port=first.port).start()


def test_cli_foxglove_without_client_runs_and_says_where(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", str(SCENARIOS_DIR / "lane_change.yaml"), "--out", str(out), "--transport",
                 "inproc", "--no-figures", "--set", "duration=1", "--foxglove", "0"])
    assert code == 0
    assert "foxglove: ws://127.0.0.1:" in capsys.readouterr().out
    assert main(["run", str(SCENARIOS_DIR / "lane_change.yaml"), "--foxglove-host", "192.0.2.1",
                 "--foxglove"]) == 2


def test_connections_that_are_no_foxglove_client_do_not_fill_the_terminal(capfd):
    import logging
    import socket

    with FoxgloveLive(port=0) as live:
        for _ in range(3):  # a port scan, a browser: each refused by the SDK with an error log
            with socket.create_connection(("127.0.0.1", live.port)) as probe:
                probe.sendall(b"GET / HTTP/1.0\r\n\r\n")
        time.sleep(0.5)
        logging.getLogger("foxglove.server").error("a real problem")  # still shown
    err = capfd.readouterr().err
    assert "Dropping client" not in err
    assert "foxglove: a real problem" in err
