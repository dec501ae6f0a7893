"""Runs over three "hosts" made of Linux network namespaces joined by a bridge:
the master in one, worker "wa" in a second, worker "wb" in a third, every
process started with `ip netns exec`. The recorded signals must be bit-identical
to the same scenario run in-process; a cut link, a killed worker host and a
frozen one each end the run with a message naming the worker, the component and
the tick, and the surviving worker serves the next run; two runs at once do not
mix; the same run works over TLS. Skipped only where namespaces cannot be made.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cosim.cli.app import main
from cosim.results.recorder import read_signals
from tests.helpers.credentials import auth_deploy_file, shared_credentials_file
from tests.helpers import netns
from tests.helpers.lines import line_reader, wait_for_line
from tests.helpers.paths import REPO_ROOT

pytestmark = [pytest.mark.integration, pytest.mark.netns,
              pytest.mark.skipif(netns.unavailable() is not None,
                                 reason=f"network namespaces: {netns.unavailable()}")]

ROOT = REPO_ROOT
PORT = 7447
DEADLINE_S = 2.0
SCENARIO = """\
name: distributed
duration: {duration}
tick: 0.01
components:
  mixer:
    python: tests.helpers.components:Mixer
    parameters: {{gain: 1.5}}
    host: wa
  echo:
    python: tests.helpers.components:Echo
sources:
  ramp: {{kind: ramp, start: 0.0, end: 2.0, t_start: 0.0, t_end: 1.0}}
connections:
  - {{from: ramp.value, to: mixer.u}}
  - {{from: mixer.y, to: echo.u}}
"""


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT)}


class Host:
    """A worker process inside a namespace (its own process group: the "host")."""

    # A start that does not get ready is killed (never leaked: it would hold the port and
    # fail every later test) and tried once more. (The rare "hung before ready" of the
    # early sessions was the test's buffered readline hiding the line: tests.helpers.lines.)
    START_TRIES, START_TIMEOUT_S = 2, 30

    def __init__(self, lab: netns.NetLab, host: str, name: str, *extra: str) -> None:
        self.name = name
        argv = [sys.executable, "-m", "cosim.cli.app", "worker", "--name", name,
                "--allow", "tests.helpers.components", "--allow", "cosim.sources",
                "--allow", "controllers.", "--allow-fmu", *extra]
        failures = []
        for _ in range(self.START_TRIES):
            self.proc = subprocess.Popen(lab.exec(host, argv), cwd=ROOT, env=_env(),
                                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                         start_new_session=True, text=True)
            try:
                wait_for_line(self.proc, f"worker '{name}' ready", self.START_TIMEOUT_S)
                return
            except AssertionError as exc:
                failures.append(str(exc) + self._stack_dump())
                self.signal(signal.SIGKILL)
                self.proc.wait()
                self.proc.stdout.close()
        raise AssertionError(f"worker {name!r} did not start in {self.START_TRIES} tries: "
                             + " | ".join(failures))

    def _stack_dump(self) -> str:
        """Where a stuck worker is: its threads' stacks (the worker prints them on SIGUSR1)."""
        if self.proc.poll() is not None:
            return ""
        os.kill(self.proc.pid, signal.SIGUSR1)
        reader, lines, end = line_reader(self.proc), [], time.monotonic() + 2.0
        while (line := reader.next_line(end)) is not None:
            lines.append(line)
        return " stacks: " + "".join(lines)

    def signal(self, sig: int) -> None:
        """Send `sig` to the worker and every component process it started."""
        os.killpg(self.proc.pid, sig)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.signal(signal.SIGCONT)
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.signal(signal.SIGKILL)
                self.proc.wait()
        self.proc.stdout.close()


@pytest.fixture(scope="module")
def lab():
    with netns.NetLab(["a", "b"]) as made:
        yield made


@pytest.fixture(scope="module")
def _workers(lab):
    started: dict[str, Host] = {}
    yield started
    for host in started.values():
        host.close()


@pytest.fixture
def hosts(lab, _workers):
    """Workers wa and wb, shared by the tests; one a test killed is started again."""
    for host, name in (("a", "wa"), ("b", "wb")):
        if name in _workers and _workers[name].proc.poll() is not None:
            _workers.pop(name).close()
        if name not in _workers:
            _workers[name] = Host(lab, host, name, "--listen", f"tcp/{lab.address(host)}:{PORT}",
                                  "--deploy", str(AUTH_DEPLOY()))
    return _workers


@pytest.fixture(scope="module")
def expected_short(tmp_path_factory) -> bytes:
    """signals.csv of the short test scenario run in-process."""
    folder = tmp_path_factory.mktemp("local")
    return local_run(write_scenario(folder), folder / "run")


def AUTH_DEPLOY() -> Path:  # noqa: N802 - a constant, made on first use
    """The deployment file with the workers' shared credential (masters and workers)."""
    return auth_deploy_file(shared_credentials_file().parent)


def master_argv(lab: netns.NetLab, scenario: Path, out: Path, *extra: str) -> list[str]:
    argv = [sys.executable, "-m", "cosim.cli.app", "run", str(scenario), "--out", str(out),
            "--no-figures", "--deadline", str(DEADLINE_S),
            "--listen", f"tcp/{lab.address('master')}:0",
            "--connect", f"tcp/{lab.address('a')}:{PORT}",
            "--connect", f"tcp/{lab.address('b')}:{PORT}", "--deploy", str(AUTH_DEPLOY()),
            *extra]
    return lab.exec("master", argv)


def start_master(lab, scenario, out, *extra) -> subprocess.Popen:
    return subprocess.Popen(master_argv(lab, scenario, out, *extra), cwd=ROOT, env=_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def finish(proc: subprocess.Popen, timeout_s: float = 60) -> tuple[int, str]:
    """Exit code and stderr of a master process, which must end within `timeout_s`."""
    _, err = proc.communicate(timeout=timeout_s)
    return proc.returncode, err


def write_scenario(folder: Path, duration: float = 0.5) -> Path:
    path = folder / "distributed.yaml"
    path.write_text(SCENARIO.format(duration=duration))
    return path


def local_run(scenario: Path, out: Path, *extra: str) -> bytes:
    assert main(["run", str(scenario), "--out", str(out), "--transport", "inproc",
                 "--place", "mixer=local", "--no-figures", *extra]) == 0
    return (out / "signals.csv").read_bytes()


def wait_for_ticks(signals: Path, rows: int, timeout_s: float = 30) -> None:
    """Wait until the recorder has flushed at least `rows` ticks (the run is under way)."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if signals.exists() and len(signals.read_text().splitlines()) > rows:
            return
        time.sleep(0.05)
    raise AssertionError(f"{signals} did not reach {rows} rows within {timeout_s} s")


# ------------------------------------------------------------------ tests
def test_three_hosts_bit_identical_to_local_run(lab, hosts, tmp_path, expected_short):
    scenario = write_scenario(tmp_path)
    expected = expected_short
    code, err = finish(start_master(lab, scenario, tmp_path / "remote", "--place", "echo=wb"))
    assert code == 0, err
    assert (tmp_path / "remote" / "signals.csv").read_bytes() == expected
    manifest = json.loads((tmp_path / "remote" / "manifest.json").read_text())
    assert manifest["hosts"]["mixer"].startswith("wa@") and manifest["hosts"]["echo"].startswith("wb@")
    listing = subprocess.run(lab.exec("master", [
        sys.executable, "-m", "cosim.cli.app", "workers", "--timeout", "1",
        "--connect", f"tcp/{lab.address('a')}:{PORT}", "--connect", f"tcp/{lab.address('b')}:{PORT}",
        "--deploy", str(AUTH_DEPLOY())]),
        cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=60)
    assert listing.returncode == 0 and "2 worker(s)" in listing.stdout
    assert "wa" in listing.stdout and "wb" in listing.stdout


CLOSED_LOOP = """\
name: closed_loop
duration: 1.5
tick: 0.01
components:
  vehicle: {fmu: Bicycle, parameters: {vx0: 10.0}}
  controller: {python: controllers.backstepping:BacksteppingController, period: 0.01,
               parameters: {adaptive: true, lateral_law: feedforward, mu0: 0.8}}
  planner:
    python: controllers.planning:Planner
    period: 0.1
    parameters:
      road: {builder: two_lane, length: 300, radius: 150}
      lane: 0
      manoeuvre: {type: lane_change, at: 5.0, to_lane: 1, a_lat: 1.5, j_lat: 2.0}
      speed: {v_max: 12.0, a_lat_max: 2.0, a_max: 1.0, d_max: 1.5, j_max: 1.0}
connections:
  - vehicle -> controller
  - vehicle -> planner
  - planner -> controller
  - controller.delta -> vehicle.delta
  - controller.torque -> vehicle.torque
"""


@pytest.mark.parametrize("placed", [("controller=wa", "planner=wb"),
                                    ("vehicle=wa", "controller=wb")])
def test_real_closed_loop_on_two_hosts_matches_local_run(lab, hosts, tmp_path, placed):
    """The backstepping controller, the planner and the plant FMU (its file sent to
    the worker) spread over hosts: signals and trajectory arrays bit-identical."""
    scenario = tmp_path / "closed_loop.yaml"
    scenario.write_text(CLOSED_LOOP)
    assert main(["run", str(scenario), "--out", str(tmp_path / "local"), "--transport",
                 "inproc", "--no-figures"]) == 0
    place = [arg for item in placed for arg in ("--place", item)]
    code, err = finish(start_master(lab, scenario, tmp_path / "remote", *place))
    assert code == 0, err
    expected = (tmp_path / "local" / "signals.csv").read_bytes()
    assert (tmp_path / "remote" / "signals.csv").read_bytes() == expected
    _, data = read_signals(tmp_path / "remote" / "signals.csv")
    assert data.shape[0] == 151
    arrays = sorted(p.relative_to(tmp_path / "local") for p in (tmp_path / "local").rglob("arrays/*"))
    assert arrays, "the planner's trajectory windows are recorded as arrays"
    for path in arrays:
        assert (tmp_path / "remote" / path).read_bytes() == (tmp_path / "local" / path).read_bytes()
    hosts_of = json.loads((tmp_path / "remote" / "manifest.json").read_text())["hosts"]
    for item in placed:
        component, worker = item.split("=")
        assert hosts_of[component].startswith(f"{worker}@")


def test_missing_worker_fails_before_tick_0(lab, hosts, tmp_path):
    scenario = write_scenario(tmp_path)
    code, err = finish(start_master(lab, scenario, tmp_path / "r", "--place", "echo=wc"))
    assert code == 2
    assert "worker(s) 'wc' not reachable" in err and "placed: echo on 'wc'" in err
    assert "reachable workers: wa (host" in err and "wb (host" in err
    assert not (tmp_path / "r" / "signals.csv").exists()


def _fault_run(lab, tmp_path, fault, place_echo: str = "wb") -> tuple[str, Path]:
    """Start a slow (real-time paced) run, apply `fault` once ticks are recorded, and
    return the master's stderr once it has ended with status 1."""
    scenario = write_scenario(tmp_path, duration=60.0)
    out = tmp_path / "faulty"
    proc = start_master(lab, scenario, out, "--place", f"echo={place_echo}", "--realtime", "1")
    try:
        t0 = time.monotonic()
        wait_for_ticks(out / "signals.csv", 20)
        t1 = time.monotonic()
        fault()
        code, err = finish(proc, timeout_s=DEADLINE_S + 20)
        print(f"started after {t1 - t0:.1f} s, ended {time.monotonic() - t1:.1f} s after the fault")
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    print(err)  # shown when an assertion below fails
    assert code == 1, err
    return err, out


def assert_unreachable(err: str) -> None:
    """A silent worker is noticed by the per-exchange deadline or by the lease
    (both 2 s here), whichever fires first; both messages say what happened."""
    assert f"no reply within the deadline of {DEADLINE_S:g} s" in err or \
        ("worker 'wb' on host" in err and "became unreachable (host down" in err)


def _check_partial(out: Path, err: str) -> int:
    """The failed run's signals are readable up to its last complete tick; returns it."""
    manifest = json.loads((out / "manifest.json").read_text())
    _, data = read_signals(out / "signals.csv")
    assert manifest["status"] == "failed" and data.shape[0] >= 20
    return data.shape[0]


def _next_run_on(lab, tmp_path, worker: str, expected: bytes) -> None:
    scenario = write_scenario(tmp_path)
    code, err = finish(start_master(lab, scenario, tmp_path / "next", "--place", f"mixer={worker}",
                                    "--place", f"echo={worker}"))
    assert code == 0, err
    assert (tmp_path / "next" / "signals.csv").read_bytes() == expected


def test_link_cut_mid_run_names_worker_component_and_tick(lab, hosts, tmp_path,
                                                         expected_short):
    try:
        err, out = _fault_run(lab, tmp_path, lambda: lab.link_down("b"))
    finally:
        lab.link_up("b")
    assert "component 'echo' failed at tick" in err and "worker 'wb'" in err
    assert_unreachable(err)
    _check_partial(out, err)
    _next_run_on(lab, tmp_path, "wa", expected_short)


def test_killed_worker_host_mid_run(lab, hosts, tmp_path, expected_short):
    err, out = _fault_run(lab, tmp_path, lambda: hosts["wa"].signal(signal.SIGKILL))
    assert "component 'mixer' failed at tick" in err
    assert "worker 'wa' on host" in err and "became unreachable (host down" in err
    _check_partial(out, err)
    _next_run_on(lab, tmp_path, "wb", expected_short)


def test_frozen_worker_host_mid_run(lab, hosts, tmp_path):
    err, out = _fault_run(lab, tmp_path, lambda: hosts["wb"].signal(signal.SIGSTOP))
    hosts["wb"].signal(signal.SIGCONT)
    assert "component 'echo' failed at tick" in err and "worker 'wb'" in err
    assert_unreachable(err)
    _check_partial(out, err)


def test_two_concurrent_runs_do_not_mix(lab, hosts, tmp_path):
    scenario = write_scenario(tmp_path, duration=1.0)
    gains = {"one": "0.5", "two": "-3.0"}
    expected = {k: local_run(scenario, tmp_path / f"local-{k}", "--set",
                             f"components.mixer.parameters.gain={g}") for k, g in gains.items()}
    assert expected["one"] != expected["two"]
    procs = {k: start_master(lab, scenario, tmp_path / k, "--place", "echo=wb", "--set",
                             f"components.mixer.parameters.gain={g}") for k, g in gains.items()}
    for name, proc in procs.items():
        code, err = finish(proc)
        assert code == 0, err
        assert (tmp_path / name / "signals.csv").read_bytes() == expected[name]


def test_tls_run_across_hosts(lab, tmp_path, expected_short):
    certs = tmp_path / "certs"
    addresses = [lab.address(h) for h in ("master", "a", "b")]
    subprocess.run(["sh", str(ROOT / "examples" / "tls" / "make_certs.sh"), str(certs),
                    "node", *addresses], check=True, capture_output=True)
    tls = ("tls:\n  root_ca_certificate: certs/ca.pem\n  certificate: certs/node.pem\n"
           "  private_key: certs/node-key.pem\n")
    for host in ("a", "b"):
        (tmp_path / f"deploy-{host}.yaml").write_text(
            f"listen: [tls/{lab.address(host)}:{PORT + 1}]\n" + tls)
    (tmp_path / "deploy-master.yaml").write_text(
        f"listen: [tls/{lab.address('master')}:0]\n"
        f"connect: [tls/{lab.address('a')}:{PORT + 1}, tls/{lab.address('b')}:{PORT + 1}]\n" + tls)
    workers = []
    try:
        for host, name in (("a", "wa"), ("b", "wb")):
            workers.append(Host(lab, host, name, "--deploy", str(tmp_path / f"deploy-{host}.yaml")))
        scenario = write_scenario(tmp_path)
        expected = expected_short
        argv = lab.exec("master", [sys.executable, "-m", "cosim.cli.app", "run", str(scenario),
                                   "--out", str(tmp_path / "tls"), "--no-figures", "--place",
                                   "echo=wb", "--deploy", str(tmp_path / "deploy-master.yaml")])
        done = subprocess.run(argv, cwd=ROOT, env=_env(), capture_output=True, text=True,
                              timeout=60)
        assert done.returncode == 0, done.stderr
        assert (tmp_path / "tls" / "signals.csv").read_bytes() == expected
    finally:
        for worker in workers:
            worker.close()


INTRUDER = """
import json, sys, time, zenoh
from cosim.distributed.deploy import DeploySettings, zenoh_config
master, worker, run_id = sys.argv[1:4]
session = zenoh.open(zenoh_config(DeploySettings(), "peer", [], [master, worker]))
seen = session.declare_subscriber("cosim/**", zenoh.handlers.RingChannel(1024))
start = {"op": "start", "run_id": "evil", "run_token": "x", "component": "c",
         "class_path": "tests.helpers.components:Mixer", "parameters": {}, "connect": [master]}
counts = {"seen": 0, "replies": 0, "sent": 0}
end = time.monotonic() + 3.0
while time.monotonic() < end:
    for key in (f"cosim/{run_id}/ctl/echo/rep", f"cosim/{run_id}/live/data"):
        session.put(key, b"FORGED")
        counts["sent"] += 1
    for request in ({"op": "info"}, start, {"op": "stop", "run_id": run_id, "component": "echo"}):
        counts["replies"] += sum(r.ok is not None for r in session.get(
            "cosim/workers/*", payload=json.dumps(request).encode(), timeout=0.1))
    while (sample := seen.try_recv()) is not None:
        counts["seen"] += sample.payload.to_bytes() != b"FORGED"
print(json.dumps(counts), flush=True)
session.close()
"""


def test_a_host_without_the_credential_sees_injects_and_starts_nothing(lab, hosts, tmp_path,
                                                                       expected_short):
    """An intruder on host b (no credential) talks to the master of a running
    cross-host run and to worker wa for 3 s: it receives nothing, its forged
    messages change nothing (the run is bit-identical), its requests get no reply."""
    scenario = write_scenario(tmp_path, duration=0.5)
    out = tmp_path / "watched"
    proc = start_master(lab, scenario, out, "--place", "echo=wb", "--realtime", "0.1")
    try:
        manifest = out / "manifest.json"
        end = time.monotonic() + 60
        while not (manifest.is_file() and "live" in manifest.read_text()):
            assert time.monotonic() < end and proc.poll() is None, "the run never started"
            time.sleep(0.05)
        live = json.loads(manifest.read_text())["live"]
        intruder = subprocess.run(lab.exec("b", [
            sys.executable, "-c", INTRUDER, live["endpoint"], f"tcp/{lab.address('a')}:{PORT}",
            live["run_id"]]), cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=60)
        code, err = finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert intruder.returncode == 0, intruder.stderr
    counts = json.loads(intruder.stdout)
    assert counts["sent"] > 100
    assert (counts["seen"], counts["replies"]) == (0, 0)
    assert code == 0, err
    assert (out / "signals.csv").read_bytes() == expected_short
