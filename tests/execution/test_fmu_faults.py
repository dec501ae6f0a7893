"""`cosim run` with a plant that segfaults, aborts, exits, hangs, returns Fatal or Error
or asks to stop, in the master's process (the supervisor completes the run) and
isolated (`isolate: true`), over the inproc and zenoh transports: exit code, the
one-line message, one row per completed tick, the manifest's status and cause, no
process left behind.

tests/fmus/Faulty fires its fault in the step that ends at fault_time = 0.2 s,
tick 20: ticks 0..19 are complete, so signals.csv holds 20 rows. FaultyME (Model
Exchange, integrated by the master) fires it at its time event t = 0.2, in the
same tick's step.
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

from cosim.results.recorder import read_signals
from tests.helpers.paths import REPO_ROOT

COSIM = Path(sys.executable).with_name("cosim")
SCENARIO = """\
name: faulty
duration: 0.4
tick: 0.01
components:
  plant:
    fmu: {fmu}
    parameters: {{fault_mode: {mode}, fault_time: 0.2}}
    isolate: {isolate}
    deadline: 1.0
  ctl:
    python: tests.helpers.components:PController
sources:
  ref: {{kind: constant, value: 1.0}}
connections:
  - plant.u_echo -> ctl.y
  - ref.value -> ctl.ref
  - ctl.u -> plant.u
"""
FAULT_TICK, FAULT_T = 20, 0.2
SEGFAULT, ABORT, EXIT, HANG, FATAL, ERROR, TERMINATE = 1, 2, 3, 4, 5, 6, 7


def run_cosim(tmp_path: Path, text: str, *options: str, interrupt_at_row: int | None = None):
    """`cosim run` in its own session, Ctrl-C'd once signals.csv's spool counts
    `interrupt_at_row` rows (and half a second more); (process result, run folder,
    processes left)."""
    scenario, out = tmp_path / "s.yaml", tmp_path / "run"
    scenario.write_text(text)
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT)}
    proc = subprocess.Popen([str(COSIM), "run", str(scenario), "--out", str(out), "--no-figures",
                             *options], cwd=REPO_ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    if interrupt_at_row is not None:
        _wait_for(lambda: _spool_rows(out / "signals.f64") >= interrupt_at_row, 60)
        time.sleep(0.5)
        os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C does
    stdout, stderr = proc.communicate(timeout=120)
    left = _leftovers(proc.pid, out)
    return subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr), out, left


def _spool_rows(spool: Path) -> int:
    """The complete rows a spool counts (its first 8 bytes), 0 before it exists."""
    try:
        with open(spool, "rb") as f:
            return int.from_bytes(f.read(8), sys.byteorder, signed=True)
    except OSError:
        return 0


def _wait_for(condition, timeout_s: float) -> None:
    end = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.02)


def _leftovers(session: int, out: Path) -> list[str]:
    """Processes of the run's session, or listed in its manifest, still alive (after 5 s)."""
    manifest = json.loads((out / "manifest.json").read_text()) if (out / "manifest.json").exists() else {}
    pids = {str(p) for p in manifest.get("pids", {}).values()}
    end = time.monotonic() + 5

    def alive() -> list[str]:
        found = subprocess.run(["pgrep", "-s", str(session)], capture_output=True,
                               text=True).stdout.split()
        return found + [p for p in pids if Path(f"/proc/{p}").exists()
                        and "Z" not in Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[-1][:3]]
    while alive() and time.monotonic() < end:
        time.sleep(0.05)
    return alive()


def _check_failed(done, out: Path, left: list[str], cause: dict, message: str) -> dict:
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith(f"run failed: component 'plant' failed at tick {FAULT_TICK} "
                           f"(t={FAULT_T:g} s): ") and message in last, last
    assert len(read_signals(out / "signals.csv")[1]) == FAULT_TICK  # ticks 0..19
    assert not list(out.glob("*.f64*"))
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "failed" and manifest["ticks"] == FAULT_TICK - 1
    assert last == f"run failed: {manifest['error']}"
    assert {k: manifest["cause"][k] for k in cause} == cause
    assert (manifest["cause"]["component"], manifest["cause"]["tick"],
            manifest["cause"]["time"]) == ("plant", FAULT_TICK, FAULT_T)
    assert left == []
    return manifest


SUPERVISED = (SEGFAULT, ABORT, EXIT, HANG)  # in the master's process, the supervisor reports these
CAUSES = {
    SEGFAULT: {"kind": "signal", "signal": "SIGSEGV"},
    ABORT: {"kind": "signal", "signal": "SIGABRT"},
    EXIT: {"kind": "exit", "exit_code": 3},
    HANG: {"kind": "deadline", "deadline_s": 1.0},
    FATAL: {"kind": "fmi_status", "status": "Fatal"},
    ERROR: {"kind": "fmi_status", "status": "Error"},
}


def _message(mode: int, isolate: bool, fatal_call: str) -> str:
    """The one-line message after the component, tick and time; `fatal_call`: the FMI
    function that returns Fatal (e.g. fmi3DoStep)."""
    where = "its isolated process" if isolate else "the master process"
    if mode in (SEGFAULT, ABORT):
        return f"{where} was killed by {CAUSES[mode]['signal']} in its step"
    if mode == EXIT:
        return f"{where} exited with status 3 in its step"
    if mode == HANG:
        return f"no return from its step within the deadline of 1 s ({where} was ended)"
    if mode == FATAL:
        return f"{fatal_call} failed with status 4 (fatal)"
    return "Faulty: injected error in the step from t = 0.19 to 0.2"


def _fatal_call(model: str, version: int) -> str:
    if model == "FaultyME":
        return "fmi2NewDiscreteStates" if version == 2 else "fmi3UpdateDiscreteStates"
    return f"fmi{version}DoStep"


def _matrix(model: str, modes: tuple[int, ...], transports: tuple[str, ...]) -> list:
    """Every mode in-process and isolated over each transport; the FMI version alternates
    over the placements, so that each mode and each placement meets both versions."""
    cases = []
    for mode in modes:
        for isolate in (False, True):
            for n, transport in enumerate(transports):
                version = 2 + (int(isolate) + n) % 2
                cases.append(pytest.param(model, version, mode, isolate, transport, id=(
                    f"{model}-fmi{version}-mode{mode}-"
                    f"{'isolated' if isolate else 'in-process'}-{transport}")))
    return cases


FAILURES = (_matrix("Faulty", (SEGFAULT, ABORT, EXIT, HANG, FATAL, ERROR), ("inproc", "zenoh"))
            + _matrix("FaultyME", (FATAL,), ("inproc", "zenoh"))
            + _matrix("FaultyME", (SEGFAULT, HANG), ("inproc",)))


@pytest.mark.timeout(120)
@pytest.mark.parametrize("model, version, mode, isolate, transport", FAILURES)
def test_a_faulty_plant_fails_the_run_with_every_completed_tick(
        tmp_path, faulty_fmus, model, version, mode, isolate, transport, monkeypatch):
    text = SCENARIO.format(fmu=faulty_fmus[model, version], mode=mode,
                           isolate=str(isolate).lower())
    temp = tmp_path / "temp"
    temp.mkdir()
    monkeypatch.setenv("TMPDIR", str(temp))  # where the FMU is extracted
    done, out, left = run_cosim(tmp_path, text, "--transport", transport)
    manifest = _check_failed(done, out, left, CAUSES[mode],
                             _message(mode, isolate, _fatal_call(model, version)))
    assert manifest.get("completed_by") == ("supervisor" if not isolate and mode in SUPERVISED
                                            else None)
    assert list(temp.iterdir()) == []  # the FMU's files too, even from a master that died


@pytest.mark.timeout(120)
@pytest.mark.parametrize("model, version, mode, isolate, transport",
                         _matrix("Faulty", (TERMINATE,), ("inproc", "zenoh"))
                         + _matrix("FaultyME", (TERMINATE,), ("inproc", "zenoh")))
def test_a_termination_request_ends_the_run_ok_with_the_step_that_asked(
        tmp_path, faulty_fmus, model, version, mode, isolate, transport):
    text = SCENARIO.format(fmu=faulty_fmus[model, version], mode=mode,
                           isolate=str(isolate).lower())
    done, out, left = run_cosim(tmp_path, text, "--transport", transport)
    assert done.returncode == 0, done.stderr
    assert (f"stopped by component 'plant' at tick {FAULT_TICK} (t={FAULT_T:g} s): the FMU "
            f"asked to terminate the simulation") in done.stdout
    names, data = read_signals(out / "signals.csv")
    assert len(data) == FAULT_TICK + 1 and data[-1, names.index("plant.y")] == FAULT_T
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "ok" and manifest["ticks"] == FAULT_TICK
    assert {k: manifest["stopped_by"][k] for k in ("component", "tick", "time")} == {
        "component": "plant", "tick": FAULT_TICK, "time": FAULT_T}
    assert left == []


@pytest.mark.timeout(120)
def test_a_segfault_in_the_master_is_reported_by_the_supervisor(tmp_path):
    text = ("name: crash\nduration: 0.4\ntick: 0.01\ncomponents:\n"
            "  plant:\n    python: tests.helpers.components:Segfault\n"
            "    parameters: {at: 0.2}\n"
            "sources:\n  ref: {kind: constant, value: 1.0}\n"
            "connections:\n  - ref.value -> plant.u\n")
    done, out, left = run_cosim(tmp_path, text, "--transport", "inproc")
    _check_failed(done, out, left, {"kind": "signal", "signal": "SIGSEGV", "call": "step"},
                  "the master process was killed by SIGSEGV in its step")


@pytest.mark.timeout(120)
@pytest.mark.parametrize("isolate", [False, True], ids=["in-process", "isolated"])
def test_ctrl_c_ends_a_run_hung_in_an_fmu_call(tmp_path, faulty_fmus, isolate):
    text = SCENARIO.format(fmu=faulty_fmus["Faulty", 2], mode=HANG, isolate=str(isolate).lower())
    text = text.replace("deadline: 1.0", "deadline: 600")
    done, out, left = run_cosim(tmp_path, text, "--transport", "inproc",
                                interrupt_at_row=FAULT_TICK)  # hung in tick 20's step
    assert done.returncode == 1, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("run failed: interrupted by the user (Ctrl-C)"), last
    assert len(read_signals(out / "signals.csv")[1]) == FAULT_TICK
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "failed" and last == f"run failed: {manifest['error']}"
    if not isolate:  # the supervisor had to end the master
        assert "component 'plant' did not return from its step at tick 20" in last
        assert manifest["cause"]["kind"] == "interrupted"
    assert left == []


def test_the_readme_quotes_these_messages():
    """README "Plants: built-in FMUs and your own" quotes the messages asserted above
    (with the default deadline of 10 s)."""
    readme = (REPO_ROOT / "README.md").read_text(encoding="utf-8")
    quoted = [_message(mode, isolate, "").replace("deadline of 1 s", "deadline of 10 s")
              for mode in (SEGFAULT, EXIT, HANG) for isolate in (False, True)]
    quoted += [_message(FATAL, False, _fatal_call("FaultyME", 2)),
               "failed at tick 2001 (t=20.01 s): " + _message(SEGFAULT, False, ""),
               "stopped by component 'vehicle' at tick 900 (t=9 s): the FMU asked to "
               "terminate the simulation"]
    assert [q for q in quoted if q not in readme] == []


# ---- faults outside doStep: tests/fmus/Wayward (hand-written FMI 2.0, `fault` parameter) ----

WAYWARD = """\
name: wayward
duration: 0.4
tick: 0.01
components:
  {name}:
    fmu: {fmu}
    parameters: {{fault: {fault}}}
    isolate: {isolate}
    deadline: 1.0
sources:
  ref: {{kind: constant, value: 1.0}}
connections:
  - ref.value -> {name}.u
"""
TERM_SEGV, TERM_HANG, TERM_ERROR, FREE_SEGV, SETUP_HANG, STEP_PENDING = 1, 2, 3, 4, 5, 6
LAST_TICK, LAST_T = 40, 0.4  # duration 0.4 s in ticks of 0.01 s


@pytest.fixture(scope="module")
def wayward(tmp_path_factory) -> dict[str, Path]:
    """tests/fmus/Wayward built for FMI 2.0 ("ok"), and two broken copies: "garbage" (its
    library is not an ELF file) and "nosym" (a library without the FMI functions)."""
    import zipfile

    import fmpy

    model, out = REPO_ROOT / "tests" / "fmus" / "Wayward", tmp_path_factory.mktemp("wayward")
    headers = Path(fmpy.__file__).parent / "c-code"
    libraries = {"ok": out / "ok.so", "nosym": out / "nosym.so"}
    subprocess.run(["gcc", "-std=c99", "-O2", "-fPIC", "-shared", "-Wall", "-Werror",
                    f"-I{headers}", str(model / "model.c"), "-o", str(libraries["ok"])],
                   check=True, capture_output=True)
    (out / "empty.c").write_text("int wayward_nothing(void) { return 0; }\n")
    subprocess.run(["gcc", "-fPIC", "-shared", str(out / "empty.c"), "-o",
                    str(libraries["nosym"])], check=True, capture_output=True)
    fmus = {}
    for name in ("ok", "nosym", "garbage"):
        fmus[name] = out / f"{name}" / "Wayward.fmu"
        fmus[name].parent.mkdir()
        with zipfile.ZipFile(fmus[name], "w") as archive:
            archive.write(model / "modelDescription.xml", "modelDescription.xml")
            so = "binaries/linux64/Wayward.so"
            if name == "garbage":
                archive.writestr(so, "not a shared library\n")
            else:
                archive.write(libraries[name], so)
    return fmus


def _run_wayward(tmp_path: Path, fmu: Path, fault: int, isolate: bool, name: str = "plant"):
    """`cosim run` of a Wayward scenario with its own TMPDIR; (result, run folder, processes
    left, FMU folders left in that TMPDIR)."""
    temp = tmp_path / "temp"
    temp.mkdir()
    text = WAYWARD.format(name=name, fmu=fmu, fault=fault, isolate=str(isolate).lower())
    previous = os.environ.get("TMPDIR")
    os.environ["TMPDIR"] = str(temp)  # run_cosim passes os.environ on
    try:
        done, out, left = run_cosim(tmp_path, text, "--transport", "inproc")
    finally:
        if previous is None:
            del os.environ["TMPDIR"]
        else:
            os.environ["TMPDIR"] = previous
    extracted = [str(p.parent) for p in temp.rglob("modelDescription.xml")]
    return done, out, left, extracted


def _check_stop_failed(done, out: Path, left: list[str], message: str) -> dict:
    """A failure in the stop after the last tick: named at that tick, every row kept."""
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith(f"run failed: component 'plant' failed at tick {LAST_TICK} "
                           f"(t={LAST_T:g} s): ") and message in last, last
    assert last.endswith(f"after tick {LAST_TICK}") or f"after tick {LAST_TICK}." in last, last
    assert len(read_signals(out / "signals.csv")[1]) == LAST_TICK + 1
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "failed" and last == f"run failed: {manifest['error']}"
    assert (manifest["cause"]["component"], manifest["cause"]["tick"],
            manifest["cause"]["time"]) == ("plant", LAST_TICK, LAST_T)
    assert left == []
    return manifest


STOP_FAULTS = [
    pytest.param(TERM_SEGV, True, "its isolated process was killed by SIGSEGV in its stop",
                 id="terminate-segfault-isolated"),
    pytest.param(FREE_SEGV, True, "its isolated process was killed by SIGSEGV in its stop",
                 id="freeInstance-segfault-isolated"),
    pytest.param(TERM_HANG, True, "no return from its stop within the deadline of 1 s (its "
                 "isolated process was ended)", id="terminate-hang-isolated"),
    pytest.param(TERM_ERROR, True, "fmi2Terminate failed with status 3 (error) in its stop "
                 "after tick 40. (FMU Wayward.fmu: [Error/logStatusError] Wayward: injected "
                 "error in fmi2Terminate at t = 0.4)", id="terminate-error-isolated"),
    pytest.param(TERM_ERROR, False, "fmi2Terminate failed with status 3 (error) in its stop "
                 "after tick 40. (FMU Wayward.fmu: [Error/logStatusError] Wayward: injected "
                 "error in fmi2Terminate at t = 0.4)", id="terminate-error-in-process"),
]


@pytest.mark.timeout(120)
@pytest.mark.parametrize("fault, isolate, message", STOP_FAULTS)
def test_a_failing_stop_is_named_after_the_last_tick(tmp_path, wayward, fault, isolate, message):
    done, out, left, extracted = _run_wayward(tmp_path, wayward["ok"], fault, isolate)
    _check_stop_failed(done, out, left, message)  # a hang: the component's deadline of 1 s
    assert extracted == []  # also the folder of an isolated process that died


@pytest.mark.timeout(120)
def test_an_isolated_start_that_hangs_is_ended_after_the_components_deadline(tmp_path, wayward):
    """Killed after the component's deadline by IsolatedFmu itself, before the supervisor's
    backstop (deadline + 2 s) would end the master."""
    done, out, left, extracted = _run_wayward(tmp_path, wayward["ok"], 0, True, name="inst_hang")
    assert done.returncode == 1, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last == ("run failed: component 'inst_hang' failed during initialization (t=0 s): "
                    "no return from its start within the deadline of 1 s (its isolated "
                    "process was ended)"), last
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "failed" and manifest.get("completed_by") is None
    assert {k: manifest["cause"][k] for k in ("kind", "deadline_s", "component", "tick")} == {
        "kind": "deadline", "deadline_s": 1.0, "component": "inst_hang", "tick": None}
    assert left == [] and extracted == []


@pytest.mark.timeout(120)
@pytest.mark.parametrize("isolate", [False, True], ids=["in-process", "isolated"])
def test_an_fmu_that_cannot_be_instantiated_leaves_no_extracted_folder(tmp_path, wayward, isolate):
    done, out, left, extracted = _run_wayward(tmp_path, wayward["ok"], 0, isolate, name="inst_null")
    assert done.returncode == 1, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("run failed: component 'inst_null' failed during initialization "
                           "(t=0 s): ") and "Failed to instantiate model" in last, last
    cause = json.loads((out / "manifest.json").read_text())["cause"]
    assert (cause["kind"], cause["component"], cause["tick"]) == ("fmu_error", "inst_null", None)
    assert left == [] and extracted == []


@pytest.mark.timeout(120)
@pytest.mark.parametrize("case, message", [
    ("garbage", "binaries/linux64/Wayward.so: not a shared library (not an ELF file)"),
    ("nosym", "binaries/linux64/Wayward.so does not export fmi2CancelStep, fmi2DeSerializeFMUstate, "
              "fmi2DoStep, fmi2EnterInitializationMode, fmi2ExitInitializationMode, "
              "fmi2FreeFMUstate and 28 more, which every FMI 2.0 CoSimulation FMU must"),
])
def test_a_library_that_cannot_be_loaded_is_refused_before_the_run(tmp_path, wayward, case, message):
    done, out, left, extracted = _run_wayward(tmp_path, wayward[case], 0, False)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines()[-1] == (
        f"error: {tmp_path / 's.yaml'}:6: components.plant.fmu: {wayward[case]}: {message}")
    assert left == [] and extracted == []


@pytest.mark.parametrize("case, message", [("garbage", "Failed to load shared library"),
                                           ("nosym", "undefined symbol: fmi2")])
def test_a_library_that_fails_to_load_leaves_no_extracted_folder(tmp_path, wayward, case, message,
                                                                  monkeypatch):
    """What the archive check spares a run, had it been skipped: instantiate cleans up."""
    from cosim.fmu.instance import FmuLog, instantiate
    from cosim.fmu.interface import describe_fmu

    temp = tmp_path / "temp"
    temp.mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(temp))
    working_dir = os.getcwd()
    with pytest.raises(Exception, match=message):
        instantiate(wayward[case], describe_fmu(wayward[case], {}), "plant", FmuLog("plant"),
                    model_exchange=False, logging_on=False)
    assert list(temp.iterdir()) == []
    assert os.getcwd() == working_dir  # fmpy's loader left it in the removed library folder


@pytest.mark.timeout(120)
@pytest.mark.parametrize("isolate", [False, True], ids=["in-process", "isolated"])
def test_a_pending_step_is_named_pending(tmp_path, wayward, isolate):
    done, out, left, extracted = _run_wayward(tmp_path, wayward["ok"], STEP_PENDING, isolate)
    _check_failed(done, out, left, {"kind": "fmi_status", "status": "Pending"},
                  "fmi2DoStep failed with status 5 (pending: this host does not run "
                  "asynchronous steps)")
    assert extracted == []
