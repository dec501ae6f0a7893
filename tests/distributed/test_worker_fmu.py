"""A plant FMU placed on a worker: the file travels checked by sha256 and runs
there bit-identical to the same FMU hosted in the master's process; workers
refuse FMUs unless started with --allow-fmu, and bytes that do not match
their hash."""

from __future__ import annotations

import base64
import os

import numpy as np
import pytest

from cosim.distributed.deploy import DeploySettings
from cosim.errors import UserError
from cosim.fmu.build import ensure_fmu
from cosim.fmu.host import FmuComponent
from cosim.fmu.interface import describe_fmu
from cosim.fmu.remote import fmu_launch, fmu_payload, sha256_of, store_fmu
from cosim.fmu.typed import hosted_fmu
from cosim.distributed.worker import Worker
from cosim.distributed.client import DistributedComponents
from cosim.distributed.protocol import encode
from cosim.transport.zenoh.config import free_tcp_endpoint
from tests.distributed.test_worker import WorkerThread, settings_for
from tests.helpers.credentials import shared_auth
from tests.helpers.components import bits, run_processes

TICK = 0.01
PARAMETERS = {"vx0": 8.0, "m": 1600.0}


@pytest.fixture(scope="module")
def bicycle():
    path = ensure_fmu("Bicycle")
    return path, describe_fmu(path)


def plant_inputs(k: int) -> dict[str, float]:
    return {"delta": 0.02 * np.sin(0.7 * k * TICK), "torque": 150.0 + 10.0 * np.cos(k * TICK),
            "wind_fx": 0.0, "wind_fy": 25.0 * (k > 50), "mu": 0.9}


def test_fmu_on_worker_matches_local_fmu_bit_for_bit(bicycle):
    path, interface = bicycle
    endpoint = free_tcp_endpoint()
    agent = WorkerThread("wf", DeploySettings(listen=[endpoint], auth=shared_auth()), allow=["controllers."])
    agent.worker.allow_fmu = True
    run_id = f"t-fmu-{os.getpid()}"
    local = FmuComponent("vehicle", path, interface, PARAMETERS, 1)
    try:
        launch = fmu_launch("vehicle", path, {}, PARAMETERS, 1)
        with DistributedComponents([launch], run_id, 5.0, placement={"vehicle": "wf"},
                                   settings=settings_for(endpoint)) as hosted:
            remote = hosted.components["vehicle"]
            assert remote.direct_feedthrough is False  # stepped first, like a local FMU
            assert remote.inputs == local.inputs and remote.outputs == local.outputs
            first = plant_inputs(0)
            assert bits(remote.start(0.0, first)) == bits(local.start(0.0, first))
            for k in range(1, 301):
                inputs = plant_inputs(k)
                assert bits(remote.step(k, k * TICK, inputs)) == bits(local.step(k, k * TICK, inputs))
            assert remote.stop() == local.stop() == {}
        cached = list(agent.worker._fmu_cache.glob("*.fmu"))
        assert [p.name for p in cached] == [f"{sha256_of(path.read_bytes())}.fmu"]
    finally:
        agent.close()
    assert run_processes(run_id) == []


def test_typed_and_array_fmu_on_worker_matches_local_bit_for_bit(arrays_fmu):
    """tests/fmus/Arrays (Int64 ... Boolean, Enumeration, arrays): the worker's ports carry
    their FMI types, and its outputs are the local typed host's."""
    interface = describe_fmu(arrays_fmu)
    endpoint = free_tcp_endpoint()
    agent = WorkerThread("wa", DeploySettings(listen=[endpoint], auth=shared_auth()), allow=[])
    agent.worker.allow_fmu = True
    run_id = f"t-fmu-arrays-{os.getpid()}"
    local = hosted_fmu("plant", arrays_fmu, interface, {}, 1)
    try:
        launch = fmu_launch("plant", arrays_fmu, {}, {}, 1)
        with DistributedComponents([launch], run_id, 5.0, placement={"plant": "wa"},
                                   settings=settings_for(endpoint)) as hosted:
            remote = hosted.components["plant"]
            assert remote.inputs == local.inputs and remote.outputs == local.outputs
            assert {p.name: p.type for p in remote.outputs}["count"] == "Int64"
            first = {"u": np.array([1.0, 1.0]), "k_in": 0.0}
            assert bits(remote.start(0.0, first)) == bits(local.start(0.0, first))
            for k in range(1, 51):
                inputs = {"u": np.array([np.sin(k * TICK), 2.0]), "k_in": float(k % 7)}
                assert bits(remote.step(k, k * TICK, inputs)) == bits(local.step(k, k * TICK, inputs))
            remote.stop()
            local.stop()
    finally:
        agent.close()
    assert run_processes(run_id) == []


def test_worker_refuses_fmus_unless_allowed_and_checks_the_hash(bicycle, tmp_path):
    path, _ = bicycle
    launch = fmu_launch("vehicle", path, {}, PARAMETERS, 1)
    request = {"op": "start", "run_id": "r1", "component": "vehicle",
               "class_path": launch.class_path, "parameters": dict(launch.parameters),
               "connect": ["tcp/127.0.0.1:1"], "fmu": fmu_payload(launch)}
    closed = Worker("w0", DeploySettings(auth=shared_auth()), ["controllers."])
    reply = closed.handle(encode(request))
    assert reply["ok"] is False
    assert "worker 'w0'" in reply["error"] and "refuses FMU component 'vehicle'" in reply["error"]
    assert "--allow-fmu" in reply["error"]
    data = path.read_bytes()
    tampered = data[:-1] + bytes([data[-1] ^ 1])
    bad = {"sha256": sha256_of(data), "data": base64.b64encode(tampered).decode()}
    with pytest.raises(ValueError, match="do not match their sha256"):
        store_fmu(bad, tmp_path)
    opened = Worker("w1", DeploySettings(auth=shared_auth()), ["controllers."], allow_fmu=True)
    reply = opened.handle(encode({**request, "fmu": bad}))
    assert reply["ok"] is False and "do not match their sha256" in reply["error"]
    assert "worker 'w1'" in reply["error"] and opened.info()["running"] == 0
    stored = store_fmu(fmu_payload(launch), tmp_path)
    assert stored.read_bytes() == data and stored.name == f"{sha256_of(data)}.fmu"


def test_fmu_refusal_reaches_the_master(bicycle):
    path, _ = bicycle
    endpoint = free_tcp_endpoint()
    agent = WorkerThread("wn", DeploySettings(listen=[endpoint], auth=shared_auth()), allow=["controllers."])
    try:
        with pytest.raises(UserError, match=r"worker 'wn' on host .* refuses FMU component "
                                            r"'vehicle'.*--allow-fmu"):
            with DistributedComponents([fmu_launch("vehicle", path, {}, PARAMETERS, 1)],
                                       "t-fmu-refused", 2.0, placement={"vehicle": "wn"},
                                       settings=settings_for(endpoint)):
                pass
    finally:
        agent.close()


def test_fmu_component_can_be_placed(tmp_path):
    from cosim.distributed.placement import resolve_placement
    from cosim.scenario.loader import load_scenario
    path = tmp_path / "s.yaml"
    path.write_text("name: p\nduration: 0.1\ntick: 0.01\ncomponents:\n"
                    "  vehicle: {fmu: Bicycle, host: wf}\n"
                    "  ctl: {python: tests.helpers.components:Echo}\n"
                    "connections:\n  - {from: vehicle.x, to: ctl.u}\n")
    scenario = load_scenario(path)
    assert resolve_placement(scenario) == {"vehicle": "wf"}
    assert resolve_placement(scenario, ["vehicle=local", "ctl=w2"]) == {"ctl": "w2"}
