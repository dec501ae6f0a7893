"""Workers on this host: allow-list, requests, placement, deployment files, and
runs whose components start through a worker (bit for bit against in-process),
missing or refusing workers, exit notices, TLS. The cross-host tests with
network namespaces are in test_distributed_netns.py."""

from __future__ import annotations

import dataclasses

import os
import threading
from pathlib import Path

import numpy as np
import pytest

from cosim.cli.app import main
from cosim.distributed.deploy import DeploySettings, load_deploy, merge_endpoints, zenoh_settings
from cosim.errors import ComponentFailure, UserError
from cosim.transport.inproc import InprocComponent
from cosim.distributed.placement import parse_place, resolve_placement
from cosim.scenario.loader import load_scenario
from cosim.distributed.worker import Worker
from cosim.distributed.client import DistributedComponents, list_workers, master_endpoint
from cosim.distributed.protocol import encode, module_allowed
from cosim.transport.zenoh.config import free_tcp_endpoint
from tests.cli.test_parameter_errors import USER_CLASS
from tests.helpers.components import bits, launch, run_processes
from tests.helpers.credentials import auth_deploy_file, shared_auth
from tests.helpers.paths import REPO_ROOT

ROOT = REPO_ROOT
MAKE_CERTS = ROOT / "examples" / "tls" / "make_certs.sh"
TEST_ALLOW = ["tests.helpers.components"]


class WorkerThread:
    """A Worker serving in a thread of the test process."""

    def __init__(self, name: str, settings: DeploySettings, allow=TEST_ALLOW) -> None:
        self.worker = Worker(name, settings, allow)
        self.stop = threading.Event()
        ready = threading.Event()
        self.thread = threading.Thread(target=self.worker.serve, args=(self.stop, ready.set))
        self.thread.start()
        assert ready.wait(20), "worker did not come up"

    def close(self) -> None:
        self.stop.set()
        self.thread.join()


@pytest.fixture
def worker():
    endpoint = free_tcp_endpoint()
    agent = WorkerThread("w1", DeploySettings(listen=[endpoint], auth=shared_auth()))
    agent.endpoint = endpoint
    yield agent
    agent.close()


def settings_for(worker_endpoint: str, **extra) -> DeploySettings:
    extra.setdefault("auth", shared_auth())  # the workers' credential (a deployment file's auth:)
    return DeploySettings(listen=["tcp/127.0.0.1:0"], connect=[worker_endpoint], **extra)


# ------------------------------------------------------------------ pure parts
@pytest.mark.parametrize("class_path, allowed", [
    ("controllers.backstepping:BacksteppingController", True),
    ("controllers:X", False),                       # "controllers." means modules under it
    ("cosim.sources:Ramp", True),
    ("cosim.sources.extra:Ramp", True),
    ("cosim.sources_evil:Ramp", False),
    ("cosim.execution.run:Anything", False),
    ("os:system", False),
    ("controllers..x:Y", False),
    ("controllers.x;import os:Y", False),
    (":Y", False),
])
def test_module_allow_list(class_path, allowed):
    assert module_allowed(class_path, ("controllers.", "cosim.sources")) is allowed


def test_refused_and_malformed_requests_name_the_worker():
    agent = Worker("w7", DeploySettings(auth=shared_auth()), ["controllers."])
    start = {"op": "start", "run_id": "r1", "component": "ctl", "class_path": "os:system",
             "parameters": {}, "connect": ["tcp/127.0.0.1:1"]}
    reply = agent.handle(encode(start))
    assert reply["ok"] is False
    assert "worker 'w7'" in reply["error"] and "refuses component 'ctl'" in reply["error"]
    assert "module 'os' is not in its allow-list (controllers., cosim.sources)" in reply["error"]
    assert agent.handle(b"{not json")["error"].startswith("worker 'w7' on host")
    assert "unknown op 'fly'" in agent.handle(encode({"op": "fly"}))["error"]
    bad_run = agent.handle(encode({**start, "class_path": "controllers.x:Y", "run_id": "a/b"}))
    assert "run_id 'a/b'" in bad_run["error"]
    bad_endpoint = agent.handle(encode({**start, "class_path": "controllers.x:Y",
                                        "connect": ["nowhere"]}))
    assert "endpoint 'nowhere'" in bad_endpoint["error"]
    assert agent.info()["running"] == 0  # nothing was started


SCENARIO = """\
name: placed
duration: 0.3
tick: 0.01
components:
  mixer:
    python: tests.helpers.components:Mixer
    parameters: {gain: 1.5}
    host: w1
  echo:
    python: tests.helpers.components:Echo
sources:
  ramp: {kind: ramp, start: 0.0, end: 2.0, t_start: 0.0, t_end: 1.0}
connections:
  - {from: ramp.value, to: mixer.u}
  - {from: mixer.y, to: echo.u}
"""


def test_placement_from_yaml_and_command_line(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(SCENARIO)
    scenario = load_scenario(path)
    assert resolve_placement(scenario) == {"mixer": "w1"}
    assert resolve_placement(scenario, ["echo=w2", "ramp=w3"]) == \
        {"mixer": "w1", "echo": "w2", "ramp": "w3"}
    assert resolve_placement(scenario, ["mixer=w9"]) == {"mixer": "w9"}   # command line wins
    assert resolve_placement(scenario, ["mixer=local"]) == {}
    with pytest.raises(UserError, match=r"no component 'plant' in scenario 'placed' "
                                        r"\(components: echo, mixer, ramp\)"):
        resolve_placement(scenario, ["plant=w1"])
    for bad in ("mixer", "=w1", "mixer=a/b"):
        with pytest.raises(UserError, match=f"--place '{bad}'"):
            parse_place([bad])
    with pytest.raises(UserError, match="placed twice"):
        parse_place(["mixer=a", "mixer=b"])


def test_deployment_file_paths_and_errors(tmp_path, certs):
    (tmp_path / "certs").mkdir()
    for name, source in (("ca.pem", "ca.pem"), ("n.pem", "node.pem"), ("n-key.pem", "node-key.pem")):
        (tmp_path / "certs" / name).write_bytes((certs / "good" / source).read_bytes())
    (tmp_path / "certs" / "n-key.pem").chmod(0o600)
    good = tmp_path / "deploy.yaml"
    good.write_text("listen: [tls/10.0.0.1:7447]\nconnect: [tls/10.0.0.2:7447]\n"
                    "tls: {root_ca_certificate: certs/ca.pem, certificate: certs/n.pem, "
                    "private_key: certs/n-key.pem}\naccess_control: {enabled: false}\n")
    settings = load_deploy(good)
    assert settings.tls.certificate == str((tmp_path / "certs" / "n.pem").resolve())
    document = zenoh_settings(settings, "peer", settings.listen, settings.connect)
    tls = document["transport"]["link"]["tls"]
    assert tls["listen_private_key"] == tls["connect_private_key"] == \
        str((tmp_path / "certs" / "n-key.pem").resolve())
    assert tls["enable_mtls"] is True and document["access_control"] == {"enabled": False}
    merged = merge_endpoints(settings, ["tcp/1.2.3.4:5"], ["tls/10.0.0.2:7447"])
    assert merged.listen == ["tcp/1.2.3.4:5", "tls/10.0.0.1:7447"]
    assert merged.connect == ["tls/10.0.0.2:7447"]
    bad = tmp_path / "bad.yaml"
    bad.write_text("listen: [10.0.0.1:7447]\ncolour: red\n")
    with pytest.raises(UserError) as error:
        load_deploy(bad)
    assert f"{bad}:1: listen" in str(error.value) and "10.0.0.1:7447" in str(error.value)
    assert f"{bad}:2: colour" in str(error.value)
    missing = tmp_path / "missing.yaml"
    missing.write_text("tls: {root_ca_certificate: no.pem, certificate: certs/n.pem, "
                       "private_key: certs/n-key.pem}\n")
    with pytest.raises(UserError, match=r"missing.yaml:1: tls.root_ca_certificate: no such file"):
        load_deploy(missing)


def test_master_endpoint_port_zero_becomes_a_free_port():
    chosen = master_endpoint("tcp/127.0.0.1:0")
    assert chosen.startswith("tcp/127.0.0.1:") and int(chosen.rsplit(":", 1)[1]) > 0
    assert master_endpoint("tls/127.0.0.1:7447") == "tls/127.0.0.1:7447"


# ------------------------------------------------------------------ with a worker
def test_component_on_worker_matches_inproc_bit_for_bit(worker):
    spec = launch("mix", "Mixer", gain=1.5)
    local = InprocComponent(spec)
    run_id = f"t-w-bits-{os.getpid()}"
    with DistributedComponents([spec, launch("echo", "Echo")], run_id, 5.0,
                               placement={"mix": "w1"},
                               settings=settings_for(worker.endpoint)) as hosted:
        assert hosted.hosts == {"mix": f"w1@{worker.worker.host}"}
        remote = hosted.components["mix"]
        rng = np.random.default_rng(3)
        first = {"u": 0.5, "w": rng.standard_normal(3)}
        assert bits(remote.start(0.0, first)) == bits(local.start(0.0, first))
        for k in range(1, 150):
            inputs = {"u": rng.standard_normal(), "w": rng.standard_normal(3)}
            assert bits(remote.step(k, k * 0.01, inputs)) == bits(local.step(k, k * 0.01, inputs))
        assert remote.stop() == local.stop()
        assert hosted.components["echo"].start(0.0, {"u": 1.0}) == {"y": 2.0}
    assert run_processes(run_id) == []


def test_a_component_on_a_worker_is_told_its_steps(worker):
    there = dataclasses.replace(launch("there", "StepsSeen"), steps=4321)
    here = dataclasses.replace(launch("here", "StepsSeen"), steps=12)  # this host's own process
    with DistributedComponents([there, here], f"t-w-steps-{os.getpid()}", 5.0,
                               placement={"there": "w1"},
                               settings=settings_for(worker.endpoint)) as hosted:
        assert hosted.components["there"].start(0.0, {}) == {"steps": 4321.0}
        assert hosted.components["here"].start(0.0, {}) == {"steps": 12.0}


def test_missing_worker_fails_before_start_naming_it_and_the_reachable_ones(worker):
    settings = settings_for(worker.endpoint, discovery_timeout_s=0.5)
    with pytest.raises(UserError) as error:
        with DistributedComponents([launch("mix", "Mixer")], "t-missing", 2.0,
                                   placement={"mix": "w404"}, settings=settings):
            pass
    text = str(error.value)
    assert "worker(s) 'w404' not reachable" in text and "placed: mix on 'w404'" in text
    assert f"reachable workers: w1 (host {worker.worker.host!r})" in text


def test_wildcard_master_endpoint_is_refused_for_placed_components():
    settings = DeploySettings(listen=["tcp/0.0.0.0:0"], connect=["tcp/127.0.0.1:1"])
    with pytest.raises(UserError, match=r"--listen tcp/0.0.0.0:0: the workers' component "
                                        r"processes connect back"):
        DistributedComponents([launch("mix", "Mixer")], "t-wild", 2.0,
                              placement={"mix": "w1"}, settings=settings)
    with pytest.raises(UserError, match="need an endpoint of this master"):
        DistributedComponents([launch("mix", "Mixer")], "t-nolisten", 2.0,
                              placement={"mix": "w1"}, settings=DeploySettings())


def test_refusal_reaches_the_master(worker):
    worker.worker.allow = ("controllers.",)
    with pytest.raises(UserError, match=r"worker 'w1' on host .* refuses component 'mix': "
                                        r"module 'tests.helpers.components' is not in its "
                                        r"allow-list"):
        with DistributedComponents([launch("mix", "Mixer")], "t-refused", 2.0,
                                   placement={"mix": "w1"}, settings=settings_for(worker.endpoint)):
            pass


def test_process_dying_on_worker_is_reported_and_worker_serves_next_run(worker):
    run_id = f"t-w-die-{os.getpid()}"
    with pytest.raises(ComponentFailure) as error:
        with DistributedComponents([launch("dies", "ExitsInInit", code=7)], run_id, 2.0,
                                   placement={"dies": "w1"}, settings=settings_for(worker.endpoint)):
            pass
    text = str(error.value)
    assert "component 'dies' failed during initialization" in text
    assert "process exited with code 7" in text and "worker 'w1'" in text
    mixer = launch("mix", "Mixer", fail_at=0.05)
    with DistributedComponents([mixer], run_id + "b", 2.0, placement={"mix": "w1"},
                               settings=settings_for(worker.endpoint)) as hosted:
        remote = hosted.components["mix"]
        remote.start(0.0, {"u": 1.0, "w": np.zeros(3)})
        with pytest.raises(ComponentFailure, match=r"'mix' failed at tick 5 .*ZeroDivisionError"
                                                   r".*; it ran on worker 'w1' on host"):
            for k in range(1, 10):
                remote.step(k, k * 0.01, {"u": 1.0, "w": np.zeros(3)})
    spec = launch("echo", "Echo")
    with DistributedComponents([spec], run_id + "c", 2.0, placement={"echo": "w1"},
                               settings=settings_for(worker.endpoint)) as hosted:
        assert hosted.components["echo"].start(0.0, {"u": 2.5}) == {"y": 3.5}
        hosted.components["echo"].stop()


def test_cli_run_with_place_matches_inproc_and_workers_lists(worker, tmp_path, capsys):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(SCENARIO)
    assert main(["run", str(scenario), "--out", str(tmp_path / "local"), "--transport",
                 "inproc", "--place", "mixer=local", "--no-figures"]) == 0
    deploy = str(auth_deploy_file(tmp_path))
    assert main(["run", str(scenario), "--out", str(tmp_path / "remote"), "--place",
                 "echo=w1", "--listen", "tcp/127.0.0.1:0", "--connect", worker.endpoint,
                 "--deploy", deploy, "--no-figures"]) == 0
    local, remote = tmp_path / "local" / "signals.csv", tmp_path / "remote" / "signals.csv"
    assert local.read_bytes() == remote.read_bytes() and len(local.read_text().splitlines()) > 30
    assert main(["workers", "--connect", worker.endpoint, "--timeout", "0.5",
                 "--deploy", deploy]) == 0
    out = capsys.readouterr().out
    assert "1 worker(s)" in out and "w1" in out and "tests.helpers.components" in out
    assert main(["run", str(scenario), "--out", str(tmp_path / "bad"), "--transport",
                 "inproc"]) == 2
    assert "components placed on workers need --transport zenoh: mixer on 'w1'" \
        in capsys.readouterr().err


# a user's class: its parameters are checked by its constructor, here on the worker
# (a shipped class's are refused at load already, cosim.scenario.known_classes)
PARAMETERS = USER_CLASS.replace("    parameters:", "    host: w1\n    parameters:")


def _record_starts(worker, monkeypatch) -> list[str]:
    """Components the worker is asked to start (proves the run went through it)."""
    started: list[str] = []
    start = worker.worker._start

    def recording(request):
        started.append(request["component"])
        return start(request)

    monkeypatch.setattr(worker.worker, "_start", recording)
    return started


@pytest.mark.parametrize("cls, bad, located", [
    ("Gain", "kk: 2.0", "components.controller.parameters.kk: unknown parameter 'kk' (did you "
                        "mean 'k'?); known: {known}"),
    ("BadParameter", "mass: -2.0", "components.controller.parameters.mass: mass must be "
                                   "positive, got -2.0"),
], ids=["unknown", "bad-value"])
def test_parameter_rejected_on_worker_names_its_yaml_line(worker, tmp_path, capsys,
                                                          monkeypatch, cls, bad, located):
    import inspect
    import json

    from tests.helpers import components

    worker.worker.allow = ("tests.helpers.",)
    started = _record_starts(worker, monkeypatch)
    path = tmp_path / "params.yaml"
    path.write_text(PARAMETERS.format(cls=cls, good="# the next one is wrong", bad=bad))
    known = ", ".join(inspect.signature(getattr(components, cls)).parameters)
    expected = f"{path}:10: " + located.format(known=known)
    out = tmp_path / "run"
    assert main(["run", str(path), "--listen", "tcp/127.0.0.1:0", "--connect", worker.endpoint,
                 "--deploy", str(auth_deploy_file(tmp_path)), "--out", str(out),
                 "--no-figures"]) == 2
    assert capsys.readouterr().err == f"error: {expected}\n"  # as in-process and local Zenoh
    manifest = json.loads((out / "manifest.json").read_text())
    assert (manifest["status"], manifest["error"]) == ("failed", expected)
    assert started == ["controller"]


def test_parameter_rejected_on_worker_raises_parameter_problem(worker, monkeypatch):
    from cosim.transport.inproc import ParameterProblem

    started = _record_starts(worker, monkeypatch)
    run_id = f"t-w-param-{os.getpid()}"
    with pytest.raises(ParameterProblem) as error:
        with DistributedComponents([launch("bad", "BadParameter", mass=-2.0)], run_id, 2.0,
                                   placement={"bad": "w1"}, settings=settings_for(worker.endpoint)):
            pass
    assert (error.value.component, error.value.parameter, error.value.problem) == \
        ("bad", "mass", "mass must be positive, got -2.0")
    assert str(error.value) == "component 'bad': parameters.mass: mass must be positive, got -2.0"
    assert started == ["bad"]
    assert run_processes(run_id) == []


# ------------------------------------------------------------------ TLS
@pytest.fixture(scope="module")
def certs(tmp_path_factory):
    import subprocess
    folder = tmp_path_factory.mktemp("certs")
    subprocess.run(["sh", str(MAKE_CERTS), str(folder / "good"), "node", "127.0.0.1"],
                   check=True, capture_output=True)
    subprocess.run(["sh", str(MAKE_CERTS), str(folder / "rogue"), "node", "127.0.0.1"],
                   check=True, capture_output=True)
    return folder


def tls_of(folder: Path):
    from cosim.distributed.deploy import TlsSettings
    return TlsSettings(root_ca_certificate=str(folder / "ca.pem"),
                       certificate=str(folder / "node.pem"),
                       private_key=str(folder / "node-key.pem"))


def test_tls_worker_serves_only_peers_with_certificates_of_its_ca(certs):
    port = free_tcp_endpoint().rsplit(":", 1)[1]
    endpoint = f"tls/127.0.0.1:{port}"
    agent = WorkerThread("wtls", DeploySettings(listen=[endpoint], tls=tls_of(certs / "good")))
    try:
        good = DeploySettings(listen=["tls/127.0.0.1:0"], connect=[endpoint],
                              tls=tls_of(certs / "good"))
        assert [w["name"] for w in list_workers(good, 0.5)] == ["wtls"]
        rogue = good.model_copy(update={"tls": tls_of(certs / "rogue")})
        assert list_workers(rogue, 0.5) == []
        plain = DeploySettings(connect=[f"tcp/127.0.0.1:{port}"])  # a client: fails at once
        with pytest.raises(UserError, match=r"cannot open a Zenoh session to \['tcp/127"):
            list_workers(plain, 0.5)
        spec = launch("mix", "Mixer", gain=-2.0)
        local = InprocComponent(spec)
        with DistributedComponents([spec, launch("echo", "Echo")], f"t-tls-{os.getpid()}", 5.0,
                                   placement={"mix": "wtls"}, settings=good) as hosted:
            assert hosted.endpoint.startswith("tls/127.0.0.1:")
            inputs = {"u": 0.75, "w": np.array([1.0, -2.0, 0.5])}
            remote = hosted.components["mix"]
            assert bits(remote.start(0.0, inputs)) == bits(local.start(0.0, inputs))
            for k in range(1, 50):
                assert bits(remote.step(k, k * 0.01, inputs)) == bits(local.step(k, k * 0.01, inputs))
            assert hosted.components["echo"].start(0.0, {"u": 1.0}) == {"y": 2.0}  # local, TLS too
    finally:
        agent.close()


def test_example_deployment_files_tls_and_access_control(tmp_path):
    """examples/distributed/*.yaml as shipped (addresses moved to 127.0.0.1): the
    master and worker-a certificates pass the ACL and run a component; a
    certificate of the same CA with an unlisted name sees nothing."""
    import subprocess
    for name in ("master", "worker-a", "intruder"):
        subprocess.run(["sh", str(MAKE_CERTS), str(tmp_path / "certs"), name, "127.0.0.1"],
                       check=True, capture_output=True)
    port = free_tcp_endpoint().rsplit(":", 1)[1]
    examples = ROOT / "examples" / "distributed"
    for name in ("master", "worker-a"):
        text = (examples / f"{name}.yaml").read_text()
        text = text.replace("tls/10.0.0.2:7447", f"tls/127.0.0.1:{port}")
        text = text.replace("tls/10.0.0.1:7447", "tls/127.0.0.1:0")
        text = text.replace(", tls/10.0.0.3:7447", "")
        (tmp_path / f"{name}.yaml").write_text(text)
    worker_settings, master_settings = (load_deploy(tmp_path / f"{n}.yaml")
                                        for n in ("worker-a", "master"))
    assert worker_settings.access_control["default_permission"] == "deny"
    agent = WorkerThread("wa", worker_settings)
    try:
        assert [w["name"] for w in list_workers(master_settings, 0.5)] == ["wa"]
        intruder = master_settings.model_copy(update={"tls": master_settings.tls.model_copy(
            update={"certificate": str(tmp_path / "certs" / "intruder.pem"),
                    "private_key": str(tmp_path / "certs" / "intruder-key.pem")})})
        assert list_workers(intruder, 0.5) == []
        spec = launch("mix", "Mixer", gain=0.5)
        local = InprocComponent(spec)
        with DistributedComponents([spec], f"t-acl-{os.getpid()}", 5.0, placement={"mix": "wa"},
                                   settings=master_settings) as hosted:
            inputs = {"u": 2.0, "w": np.array([0.25, 0.5, -1.0])}
            assert bits(hosted.components["mix"].start(0.0, inputs)) == \
                bits(local.start(0.0, inputs))
            assert hosted.components["mix"].stop() == local.stop()
    finally:
        agent.close()


def test_router_joins_master_and_worker_that_only_know_the_router():
    """The worker listens nowhere: the master finds it and starts a component
    through the router alone (`cosim router`)."""
    from cosim.distributed.router import run_router
    router_endpoint = free_tcp_endpoint()
    stop, ready = threading.Event(), threading.Event()
    router = threading.Thread(target=run_router, args=(DeploySettings(listen=[router_endpoint],
                                                                      auth=shared_auth()),
                                                       stop, ready.set))
    router.start()
    agent = None
    try:
        assert ready.wait(20)
        agent = WorkerThread("wr", DeploySettings(connect=[router_endpoint], auth=shared_auth()))
        assert agent.worker.mode == "client"
        assert [w["name"] for w in list_workers(DeploySettings(connect=[router_endpoint],
                                                               auth=shared_auth()),
                                                1.0)] == ["wr"]
        spec = launch("mix", "Mixer", gain=4.0)
        local = InprocComponent(spec)
        with DistributedComponents([spec], f"t-router-{os.getpid()}", 5.0,
                                   placement={"mix": "wr"},
                                   settings=settings_for(router_endpoint)) as hosted:
            inputs = {"u": -1.0, "w": np.array([3.0, 0.0, 1.0])}
            remote = hosted.components["mix"]
            assert bits(remote.start(0.0, inputs)) == bits(local.start(0.0, inputs))
            for k in range(1, 20):
                assert bits(remote.step(k, k * 0.01, inputs)) == bits(local.step(k, k * 0.01, inputs))
    finally:
        if agent is not None:
            agent.close()
        stop.set()
        router.join()


def test_cli_router_and_worker_processes_end_cleanly_on_sigterm():
    """`cosim router` and `cosim worker` as processes: ready lines, a worker listed
    through the router, exit status 0 on SIGTERM (what a service manager sends)."""
    import signal
    import subprocess
    import sys
    from tests.helpers.lines import wait_for_line
    endpoint = free_tcp_endpoint()
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    router = subprocess.Popen([sys.executable, "-m", "cosim.cli.app", "router", "--listen", endpoint],
                              cwd=ROOT, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True)
    worker = None
    try:
        wait_for_line(router, f"router listening on {endpoint}", 60)
        worker = subprocess.Popen([sys.executable, "-m", "cosim.cli.app", "worker", "--name", "wp",
                                   "--connect", endpoint], cwd=ROOT, env=env,
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        wait_for_line(worker, "worker 'wp' ready", 60)
        found = list_workers(DeploySettings(connect=[endpoint]), 1.0)
        assert [(w["name"], w["pid"], w["allow"]) for w in found] == \
            [("wp", worker.pid, ["controllers.", "cosim.sources"])]
        for proc in (worker, router):
            proc.send_signal(signal.SIGTERM)
            assert proc.wait(30) == 0
    finally:
        for proc in (worker, router):
            if proc is not None and proc.poll() is None:
                proc.kill()
                proc.wait()
            if proc is not None:
                proc.stdout.close()
