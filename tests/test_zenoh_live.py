"""Live view: a watcher in another process sees every published tick, bit for bit."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from cosim.zenoh_transport import ZenohComponents
from cosim.zenoh_transport.config import free_tcp_endpoint

pytestmark = [pytest.mark.integration, pytest.mark.timeout(60)]

WATCHER = """
import json, sys
from cosim.zenoh_transport.live import watch
for tick, t, values in watch(sys.argv[1], sys.argv[2]):
    print(json.dumps([tick, t.hex(), {k: v.hex() for k, v in values.items()}]), flush=True)
"""


def start_watcher(run_id: str, endpoint: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", WATCHER, run_id, endpoint],
                            stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": os.getcwd()})


def wait_for_watcher(hosted: ZenohComponents) -> None:
    end = time.monotonic() + 30
    while not hosted.live_matching:
        assert time.monotonic() < end, "the watcher never subscribed"
        time.sleep(0.02)


def test_watcher_sees_every_tick_exactly():
    run_id, endpoint = f"t-live-{os.getpid()}", free_tcp_endpoint()
    names = ["vehicle.x", "vehicle.y", "controller.delta"]
    rng = np.random.default_rng(3)
    published = []
    watcher = start_watcher(run_id, endpoint)
    try:
        with ZenohComponents([], run_id, endpoint=endpoint) as hosted:
            hosted.publish(0, 0.0, names, np.zeros(3))  # nobody listens yet: a no-op
            wait_for_watcher(hosted)
            for k in range(1, 61):
                values = rng.standard_normal(3) * 1e3
                hosted.publish(k, k * 0.01, names, values)
                published.append([k, (k * 0.01).hex(),
                                  {n: float(v).hex() for n, v in zip(names, values)}])
        out, _ = watcher.communicate(timeout=30)  # the run's end marker ends the watch
    finally:
        watcher.kill()
    seen = [json.loads(line) for line in out.splitlines()]
    assert seen == published


def test_publish_checks_names_against_values_when_watched():
    run_id, endpoint = f"t-live2-{os.getpid()}", free_tcp_endpoint()
    watcher = start_watcher(run_id, endpoint)
    try:
        with ZenohComponents([], run_id, endpoint=endpoint) as hosted:
            wait_for_watcher(hosted)
            with pytest.raises(ValueError, match="2 values for 3 names"):
                hosted.publish(1, 0.01, ["a", "b", "c"], np.zeros(2))
    finally:
        watcher.kill()
        watcher.wait()


def test_watch_rejects_a_bad_run_id():
    from cosim.zenoh_transport.live import watch
    with pytest.raises(ValueError, match="run_id"):
        next(watch("bad/id", "tcp/127.0.0.1:1"))
