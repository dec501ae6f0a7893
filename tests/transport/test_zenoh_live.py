"""Live view: a watcher in another process sees every published tick, bit for bit."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from cosim.transport.zenoh import ZenohComponents
from cosim.transport.zenoh.auth import new_credential, write_credential_file
from cosim.transport.zenoh.config import free_tcp_endpoint

pytestmark = [pytest.mark.integration, pytest.mark.timeout(60)]

WATCHER = """
import json, sys
from cosim.transport.zenoh.auth import read_credential_file
from cosim.transport.zenoh.live import watch
credential = read_credential_file(sys.argv[4])
for n, (tick, t, values) in enumerate(watch(sys.argv[1], sys.argv[2], credential), 1):
    print(json.dumps([tick, t.hex(), {k: v.hex() for k, v in values.items()}]), flush=True)
    if n == int(sys.argv[3]):
        break
"""


CREDENTIAL = new_credential("live-tests")  # every run of this module uses it


@pytest.fixture(scope="module")
def credential_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("auth") / "live.credential"
    write_credential_file(path, CREDENTIAL)
    return path


def start_watcher(run_id: str, endpoint: str, credential_file, count: int = -1
                  ) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", WATCHER, run_id, endpoint, str(count),
                             str(credential_file)],
                            stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": os.getcwd()})


def wait_for_watcher(hosted: ZenohComponents) -> None:
    end = time.monotonic() + 30
    while not hosted.live_matching:
        assert time.monotonic() < end, "the watcher never subscribed"
        time.sleep(0.02)


def test_watcher_sees_every_tick_exactly(credential_file):
    run_id, endpoint = f"t-live-{os.getpid()}", free_tcp_endpoint()
    names = ["vehicle.x", "vehicle.y", "controller.delta"]
    rng = np.random.default_rng(3)
    published = []
    watcher = start_watcher(run_id, endpoint, credential_file)
    try:
        with ZenohComponents([], run_id, endpoint=endpoint, credential=CREDENTIAL) as hosted:
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


def test_watching_any_run_with_a_star_and_changing_names(credential_file):
    run_id, endpoint = f"t-live-star-{os.getpid()}", free_tcp_endpoint()
    watcher = start_watcher("*", endpoint, credential_file, count=5)
    try:
        with ZenohComponents([], run_id, endpoint=endpoint, credential=CREDENTIAL) as hosted:
            wait_for_watcher(hosted)
            for k in range(1, 3):
                hosted.publish(k, k * 0.5, ["a", "b"], np.array([k, -k], dtype=float))
            out = [watcher.stdout.readline() for _ in range(2)]  # seen before the names change
            for k in range(3, 6):
                hosted.publish(k, k * 0.5, ["a", "b", "c"], np.array([k, -k, 0.0]))
            out += watcher.communicate(timeout=30)[0].splitlines()
    finally:
        watcher.kill()
    assert [json.loads(line) for line in out] == [
        [k, (k * 0.5).hex(), {"a": float(k).hex(), "b": float(-k).hex()}
         | ({"c": "0x0.0p+0"} if k >= 3 else {})] for k in range(1, 6)]


def test_publish_checks_names_against_values_when_watched(credential_file):
    run_id, endpoint = f"t-live2-{os.getpid()}", free_tcp_endpoint()
    watcher = start_watcher(run_id, endpoint, credential_file)
    try:
        with ZenohComponents([], run_id, endpoint=endpoint, credential=CREDENTIAL) as hosted:
            wait_for_watcher(hosted)
            with pytest.raises(ValueError, match="2 values for 3 names"):
                hosted.publish(1, 0.01, ["a", "b", "c"], np.zeros(2))
    finally:
        watcher.kill()
        watcher.wait()


def test_watch_rejects_a_bad_run_id():
    from cosim.transport.zenoh.live import watch
    with pytest.raises(ValueError, match="run_id"):
        next(watch("bad/id", "tcp/127.0.0.1:1"))


def test_a_watcher_joining_later_gets_the_names_by_query(credential_file):
    """The in-band names went to the first watcher only; the second one asks."""
    run_id, endpoint = f"t-live-late-{os.getpid()}", free_tcp_endpoint()
    names = ["p.a", "p.b"]
    first = start_watcher(run_id, endpoint, credential_file)
    second = None
    try:
        with ZenohComponents([], run_id, endpoint=endpoint, credential=CREDENTIAL) as hosted:
            wait_for_watcher(hosted)
            hosted.publish(1, 0.5, names, np.array([1.0, 2.0]))
            assert json.loads(first.stdout.readline())[0] == 1  # names were sent in band
            second = start_watcher(run_id, endpoint, credential_file, count=3)
            end = time.monotonic() + 30
            k = 2
            while second.poll() is None and time.monotonic() < end:
                hosted.publish(k, k * 0.5, names, np.array([k, -k], dtype=float))
                k += 1
                time.sleep(0.05)
        out = second.communicate(timeout=30)[0].splitlines()
    finally:
        first.kill()
        if second is not None:
            second.kill()
    seen = [json.loads(line) for line in out]
    assert len(seen) == 3
    for tick, t, values in seen:
        assert values == {"p.a": float(tick).hex(), "p.b": float(-tick).hex()}
        assert t == (tick * 0.5).hex()
    assert [s[0] for s in seen] == list(range(seen[0][0], seen[0][0] + 3))
