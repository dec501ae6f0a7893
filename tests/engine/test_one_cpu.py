"""The lockstep chain on one CPU (cosim.engine.one_cpu): which threads and processes it pins,
what it restores, and that a run over Zenoh puts its component processes on the CPU the
manifest names (and leaves them alone with `lockstep_cpu="off"`)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from collections.abc import Mapping

import pytest

import cosim
from cosim.component import Component, Port, Value, may_load_beside, start_beside
from cosim.engine import one_cpu
from cosim.errors import UserError

ALLOWED = set(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else set()
needs_two_cpus = pytest.mark.skipif(len(ALLOWED) < 2 or not one_cpu.supported(),
                                    reason="needs Linux and two CPUs this process may use")


class CpuReporter(Component):
    """Outputs how many CPUs its thread may run on, and the lowest of them."""

    inputs = (Port("x"),)
    outputs = (Port("cpus"), Port("first_cpu"))

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        cpus = os.sched_getaffinity(0)
        return {"cpus": float(len(cpus)), "first_cpu": float(min(cpus))}


SCENARIO = {"name": "cpu_report", "duration": 0.05, "tick": 0.01,
            "components": {"probe": {"python": "tests.engine.test_one_cpu:CpuReporter"}},
            "sources": {"u": {"kind": "constant", "value": 1.0}},
            "connections": [{"from": "u.value", "to": "probe.x"}]}


class BesideReporter(Component):
    """Starts a thread beside the run when its host allows it (-1 outputs when not); outputs the CPUs
    that thread and the stepping one may run on."""

    inputs = (Port("x"),)
    outputs = (Port("beside_cpus"), Port("beside_first_cpu"), Port("cpus"))

    def __init__(self) -> None:
        self.done = threading.Event()
        self.thread = start_beside(lambda: self.done.wait(60), "probe") if may_load_beside() else None

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        beside = os.sched_getaffinity(self.thread.native_id) if self.thread is not None else {-1}
        return {"beside_cpus": float(len(beside)) if self.thread is not None else -1.0,
                "beside_first_cpu": float(min(beside)), "cpus": float(len(os.sched_getaffinity(0)))}

    def finish(self) -> dict[str, float]:
        self.done.set()
        return {}


BESIDE_SCENARIO = {**SCENARIO, "name": "beside_report",
                   "components": {"probe": {"python": "tests.engine.test_one_cpu:BesideReporter"}}}


@pytest.mark.parametrize("value, expected", [("auto", "auto"), ("OFF", "off"), ("1", 1), (0, 0),
                                             (" 3 ", 3)])
def test_settings_are_auto_off_or_a_cpu_number(value, expected):
    assert one_cpu.parse_setting(value) == expected


@pytest.mark.parametrize("value, problem", [("fast", "expected auto, off or a CPU number, got 'fast'"),
                                            ("-1", "a CPU number is 0 or more, got -1"),
                                            (True, "expected auto, off or a CPU number, got True")])
def test_a_bad_setting_names_the_option_and_the_value(value, problem):
    with pytest.raises(UserError) as caught:
        one_cpu.parse_setting(value, "--lockstep-cpu")
    assert str(caught.value) == f"--lockstep-cpu: {problem}"


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="Linux CPU affinity")
def test_off_pins_nothing():
    before = os.sched_getaffinity(0)
    with one_cpu.PinnedChain("off") as chain:
        assert chain.pin() is None and one_cpu.pinned_cpu() is None
        assert os.sched_getaffinity(0) == before


@needs_two_cpus
def test_pin_puts_this_thread_and_what_it_starts_on_one_cpu_and_the_end_restores_both():
    seen: dict[str, set[int]] = {}
    release = threading.Event()

    def born_pinned() -> None:
        seen["inside"] = set(os.sched_getaffinity(0))
        release.wait(10)
        seen["after"] = set(os.sched_getaffinity(0))

    with one_cpu.PinnedChain("auto") as chain:
        assert os.sched_getaffinity(0) == ALLOWED     # nothing before pin (start-up uses every CPU)
        cpu = chain.pin()
        assert cpu in ALLOWED and one_cpu.pinned_cpu() == cpu == chain.pin()
        assert os.sched_getaffinity(0) == {cpu}
        thread = threading.Thread(target=born_pinned)
        thread.start()
        while "inside" not in seen:
            threading.Event().wait(0.001)
    release.set()
    thread.join(10)
    assert seen["inside"] == {cpu}
    assert os.sched_getaffinity(0) == ALLOWED
    assert seen["after"] == ALLOWED           # born pinned, given every CPU back at the end
    assert one_cpu.pinned_cpu() is None


@needs_two_cpus
def test_an_explicit_cpu_is_used_and_one_not_allowed_is_refused():
    cpu = max(ALLOWED)
    with one_cpu.PinnedChain(cpu) as chain:
        assert chain.pin() == cpu and os.sched_getaffinity(0) == {cpu}
    with pytest.raises(UserError, match=r"lockstep CPU 4096: this process may run only on CPU "):
        with one_cpu.PinnedChain(4096) as chain:   # (a run checks it first: check_setting)
            chain.pin()
    assert one_cpu.pinned_cpu() is None and os.sched_getaffinity(0) == ALLOWED


@needs_two_cpus
def test_a_chain_inside_a_pinned_one_reports_its_cpu_and_leaves_the_restore_to_it():
    with one_cpu.PinnedChain("auto") as outer:
        cpu = outer.pin()
        with one_cpu.PinnedChain("auto") as inner:
            assert inner.pin() == cpu and inner.cpu is None
        assert os.sched_getaffinity(0) == {cpu}
    assert os.sched_getaffinity(0) == ALLOWED


@needs_two_cpus
def test_an_interruption_while_pinning_is_undone_at_the_end(monkeypatch):
    def interrupted(pid):
        raise KeyboardInterrupt

    monkeypatch.setattr(one_cpu, "_threads_of", interrupted)
    with pytest.raises(KeyboardInterrupt):
        with one_cpu.PinnedChain("auto") as chain:
            chain.pin([12345])
    assert os.sched_getaffinity(0) == ALLOWED and one_cpu.pinned_cpu() is None


@needs_two_cpus
@pytest.mark.parametrize("own_pin", [False, True], ids=["unpinned", "pinned by its owner to that CPU"])
def test_other_threads_of_the_process_keep_their_cpus(own_pin):
    cpu = max(ALLOWED)
    ready, done = threading.Event(), threading.Event()
    seen: list[set[int]] = []

    def bystander() -> None:
        if own_pin:
            os.sched_setaffinity(0, {cpu})
        ready.set()
        done.wait(10)
        seen.append(set(os.sched_getaffinity(0)))

    thread = threading.Thread(target=bystander)
    thread.start()
    ready.wait(10)
    with one_cpu.PinnedChain(cpu) as chain:
        assert chain.pin() == cpu
    done.set()
    thread.join(10)
    assert seen == [{cpu} if own_pin else ALLOWED]


def test_one_cpu_or_no_affinity_pins_nothing_and_a_cpu_number_is_refused_where_it_cannot_be_had(
        monkeypatch):
    monkeypatch.setattr(one_cpu, "supported", lambda: True)
    monkeypatch.setattr(one_cpu.os, "sched_getaffinity", lambda pid: {0}, raising=False)
    with one_cpu.PinnedChain("auto") as chain:
        assert chain.pin() is None              # one CPU: the chain is on it already
    with pytest.raises(UserError, match=r"^--lockstep-cpu 1: this process may run only on CPU 0$"):
        one_cpu.check_setting(1)
    monkeypatch.setattr(one_cpu, "supported", lambda: False)
    with one_cpu.PinnedChain("auto") as chain:
        assert chain.pin() is None
    assert one_cpu.check_setting("auto") == "auto"
    with pytest.raises(UserError, match=r"^--lockstep-cpu 0: this platform does not let a process"):
        one_cpu.check_setting(0)


def _child_reporting_its_cpus() -> subprocess.Popen:
    script = "import os, sys; sys.stdin.readline(); print(sorted(os.sched_getaffinity(0)))"
    return subprocess.Popen([sys.executable, "-c", script], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)


@needs_two_cpus
def test_pin_takes_the_chains_processes_along_and_release_gives_a_helper_the_others():
    member = _child_reporting_its_cpus()      # started before the pin, as the components are
    with one_cpu.PinnedChain("auto") as chain:
        cpu = chain.pin([member.pid])
        helper = _child_reporting_its_cpus()  # started after it, as the CSV writer is
        one_cpu.release(helper.pid)
        outputs = [child.communicate("go\n", timeout=30)[0] for child in (member, helper)]
    assert [json.loads(out) for out in outputs] == [[cpu], sorted(ALLOWED - {cpu})]


@needs_two_cpus
def test_a_zenoh_run_puts_its_component_processes_on_the_manifests_cpu(tmp_path):
    pinned = cosim.run(SCENARIO, transport="zenoh", out=tmp_path / "auto")
    manifest = json.loads((tmp_path / "auto" / "manifest.json").read_text())
    cpu = manifest["lockstep_cpu"]
    assert pinned.status == "ok" and cpu in ALLOWED
    assert set(pinned.signals["probe.cpus"]) == {1.0}
    assert set(pinned.signals["probe.first_cpu"]) == {float(cpu)}
    assert os.sched_getaffinity(0) == ALLOWED    # this process has its CPUs back

    free = cosim.run(SCENARIO, transport="zenoh", out=tmp_path / "off", lockstep_cpu="off")
    assert json.loads((tmp_path / "off" / "manifest.json").read_text())["lockstep_cpu"] is None
    assert set(free.signals["probe.cpus"]) == {float(len(ALLOWED))}


@needs_two_cpus
def test_a_thread_beside_the_lockstep_gets_the_other_cpus_and_only_component_processes_start_one(tmp_path):
    run = cosim.run(BESIDE_SCENARIO, transport="zenoh", out=tmp_path / "zenoh")
    cpu = json.loads((tmp_path / "zenoh" / "manifest.json").read_text())["lockstep_cpu"]
    others = ALLOWED - {cpu}
    assert run.status == "ok" and set(run.signals["probe.cpus"]) == {1.0}        # the stepping thread: the chain's
    assert set(run.signals["probe.beside_cpus"]) == {float(len(others))}
    assert set(run.signals["probe.beside_first_cpu"]) == {float(min(others))}

    inproc = cosim.run(BESIDE_SCENARIO, transport="inproc", out=tmp_path / "inproc")
    assert inproc.status == "ok" and set(inproc.signals["probe.beside_cpus"]) == {-1.0}  # the master's process: not


@needs_two_cpus
def test_a_component_process_with_one_cpu_is_not_offered_a_thread_beside(tmp_path):
    """As on a sweep worker's CPU: a thread beside the chain would share the chain's one CPU."""
    script = (f"import os, cosim\nos.sched_setaffinity(0, {{{min(ALLOWED)}}})\n"
              f"run = cosim.run({BESIDE_SCENARIO!r}, transport='zenoh', out={str(tmp_path / 'one')!r})\n"
              f"print(run.status, sorted(set(run.signals['probe.beside_cpus'])))")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                          cwd=os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["ok", "[-1.0]"]


def test_an_in_process_run_pins_nothing(tmp_path):
    setting = min(ALLOWED) if ALLOWED and one_cpu.supported() else "auto"
    cosim.run(SCENARIO, transport="inproc", out=tmp_path / "inproc", lockstep_cpu=setting)
    assert json.loads((tmp_path / "inproc" / "manifest.json").read_text())["lockstep_cpu"] is None


def test_the_api_refuses_a_bad_setting_before_running(tmp_path):
    with pytest.raises(UserError, match=r"^lockstep_cpu: expected auto, off or a CPU number, got 'x'$"):
        cosim.run(SCENARIO, transport="zenoh", out=tmp_path / "bad", lockstep_cpu="x")
    with pytest.raises(UserError, match=r"^lockstep_cpu 4096: "):   # whatever the transport
        cosim.run(SCENARIO, transport="inproc", out=tmp_path / "bad", lockstep_cpu=4096)
    assert not (tmp_path / "bad").exists()


@needs_two_cpus
def test_an_in_process_run_with_an_isolated_fmu_pins_its_chain(tmp_path):
    run = cosim.run("lane_change", set={"duration": 0.5, "components.vehicle.isolate": True},
                    transport="inproc", out=tmp_path / "isolated")
    manifest = json.loads((tmp_path / "isolated" / "manifest.json").read_text())
    assert run.status == "ok" and manifest["lockstep_cpu"] in ALLOWED
    assert os.sched_getaffinity(0) == ALLOWED


def test_a_sweep_sample_leaves_the_placement_to_the_os(tmp_path):
    from cosim.execution.sweep import run_scenario_sample
    from tests.helpers.paths import SCENARIOS_DIR

    metrics = run_scenario_sample(SCENARIOS_DIR / "lane_change.yaml", ["duration=0.5"],
                                  tmp_path / "sample", "zenoh")
    assert metrics and json.loads((tmp_path / "sample" / "manifest.json").read_text())["lockstep_cpu"] is None


def test_cpus_beside_the_chain_are_its_others_else_this_threads_several():
    with one_cpu.PinnedChain("auto") as chain:
        before = one_cpu.cpus_beside()
        allowed = set(os.sched_getaffinity(0))
        assert before == (allowed if len(allowed) > 1 else set())
        if chain.pin() is not None:
            assert one_cpu.cpus_beside() == allowed - {chain.cpu}
    assert one_cpu.cpus_beside() == before
