"""`cosim run` before tick 0: option errors first, a start-up error or a Ctrl-C
leaves a readable failed manifest in an announced run folder, no traceback,
no process left behind."""

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
from tests.helpers.paths import REPO_ROOT

ROOT = REPO_ROOT
COSIM = Path(sys.executable).with_name("cosim")
LANE_CHANGE = ROOT / "scenarios" / "lane_change.yaml"


@pytest.mark.parametrize("option", [["--transport", "foo"], ["--realtime", "-1"]])
def test_option_errors_come_before_the_run_folder(option, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", str(LANE_CHANGE), "--out", str(out), *option]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # not even "run folder:"
    assert captured.err.startswith("error: ") and len(captured.err.splitlines()) == 1
    assert not out.exists()


def test_fmu_parameter_error_at_start_leaves_a_failed_manifest(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", str(LANE_CHANGE), "--out", str(out), "--no-figures",
                 "--set", "components.vehicle.parameters.m=-5"])
    assert code == 2
    captured = capsys.readouterr()
    message = "parameter 'm' = -5 is below its minimum 100"
    assert message in captured.err and "Traceback" not in captured.err
    assert captured.out.startswith(f"run folder: {out}\n")
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "failed" and message in manifest["error"]
    assert manifest["ticks"] == 0 and manifest["name"] == "lane_change"
    assert sorted(p.name for p in out.iterdir()) == ["manifest.json"]


def test_error_before_the_folder_is_made_announces_no_folder(tmp_path, capsys):
    out = tmp_path / "run"  # placing a component needs zenoh: found before the folder
    assert main(["run", str(LANE_CHANGE), "--out", str(out), "--transport", "inproc",
                 "--place", "controller=w1"]) == 2
    captured = capsys.readouterr()
    assert "run folder:" not in captured.out and not out.exists()
    assert captured.err.startswith("error: ")


def _interactive_sigint() -> None:
    """In the child: Ctrl-C as in a terminal, even when the suite itself was started in the
    background (a non-interactive shell starts background jobs with SIGINT ignored)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _interrupt_run(out: Path, delay_s: float) -> tuple[subprocess.CompletedProcess, list[str]]:
    """Start `cosim run` (zenoh, a long duration), SIGINT it after delay_s;
    return its outcome and what is left in its process session."""
    proc = subprocess.Popen(
        [str(COSIM), "run", str(LANE_CHANGE), "--out", str(out), "--no-figures",
         "--set", "duration=600"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, start_new_session=True, preexec_fn=_interactive_sigint)
    time.sleep(delay_s)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    left = subprocess.run(["pgrep", "-s", str(proc.pid)], capture_output=True,
                          text=True).stdout.split()
    return subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr), left


@pytest.mark.timeout(120)
@pytest.mark.parametrize("delay_s", [0.15, 0.5, 0.9, 1.5])
def test_ctrl_c_at_start_exits_1_with_one_line_and_a_failed_manifest(tmp_path, delay_s):
    out = tmp_path / "run"
    done, left = _interrupt_run(out, delay_s)
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("run failed: interrupted"), done.stderr
    assert left == []
    if not out.exists():  # interrupted before the folder was announced
        assert "run folder:" not in done.stdout
        assert last == "run failed: interrupted before tick 0"
        return
    assert f"run folder: {out}" in done.stdout
    assert not (out / "manifest.json.tmp").exists()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "failed" and manifest["error"].startswith("interrupted")
    assert last == f"run failed: {manifest['error']}"


# The command with a Ctrl-C sent at a chosen point of its start (no timing involved):
# "options", while its options are checked (before the supervisor's fork); "fork", in
# the master just after the fork, as the supervisor forwards one there.
INTERRUPT_AT = """\
import os, signal, sys
sys.argv[0] = "cosim"  # the command itself: its early Ctrl-C handler, its supervisor
import cosim.execution.run as execution_run
import cosim.execution.supervisor as supervisor

def interrupt():
    os.kill(os.getpid(), signal.SIGINT)

check, fork = execution_run.check_run_options, supervisor.fork_supervisor

def check_then_interrupt(*args):
    check(*args)
    interrupt()

def fork_then_interrupt():
    status = fork()
    if status is None:  # in the master
        interrupt()
    return status

if os.environ["AT"] == "options":
    execution_run.check_run_options = check_then_interrupt
else:
    supervisor.fork_supervisor = fork_then_interrupt
from cosim.cli.app import main
sys.exit(main())
"""


@pytest.mark.timeout(60)
@pytest.mark.parametrize("at", ["options", "fork"])
def test_ctrl_c_before_the_run_starts_is_one_line_and_exit_1(tmp_path, at):
    out = tmp_path / "run"
    proc = subprocess.run(
        [sys.executable, "-c", INTERRUPT_AT, "run", str(LANE_CHANGE), "--out", str(out),
         "--no-figures"], cwd=ROOT, env={**os.environ, "AT": at, "PYTHONPATH": str(ROOT)},
        capture_output=True, text=True, timeout=50, start_new_session=True,
        preexec_fn=_interactive_sigint)
    assert (proc.returncode, proc.stderr, proc.stdout) == (
        1, "run failed: interrupted before tick 0\n", "")
    assert not out.exists()


def _interrupted_run(*args, **kwargs):
    raise KeyboardInterrupt


def _interrupted_then_cleanup_fails(*args, **kwargs):
    try:
        raise KeyboardInterrupt
    except KeyboardInterrupt:
        raise RuntimeError("cannot stop the writer process") from None


def _interrupt_turned_into_a_library_error(*args, **kwargs):
    from cosim.cli import interrupts

    try:
        interrupts._interrupt(signal.SIGINT, None)  # what the run's Ctrl-C handler does
    except KeyboardInterrupt:
        pass  # caught inside a library (pydantic-core, while it builds a model)...
    raise RuntimeError("SchemaError: Error building `literal` serializer: KeyboardInterrupt")  # ...no context


@pytest.mark.parametrize("load_and_run, note", [
    (_interrupted_run, ""),
    (_interrupt_turned_into_a_library_error, ""),
    (_interrupted_then_cleanup_fails,
     " (then, while stopping: RuntimeError: cannot stop the writer process)")])
def test_interrupt_before_tick0_is_one_line_exit_1(monkeypatch, capsys, load_and_run, note):
    import cosim.cli.interrupts
    import cosim.cli.run

    monkeypatch.setattr(cosim.cli.interrupts, "_seen", False)  # restored after the test
    monkeypatch.setattr(cosim.cli.run, "_load_and_run", load_and_run)
    assert main(["run", str(LANE_CHANGE), "--transport", "inproc"]) == 1
    assert capsys.readouterr().err == f"run failed: interrupted before tick 0{note}\n"


def test_a_bug_outside_an_interrupt_is_not_hidden(monkeypatch):
    import cosim.cli.interrupts
    import cosim.cli.run

    monkeypatch.setattr(cosim.cli.interrupts, "_seen", False)  # no Ctrl-C came

    def buggy(*args, **kwargs):
        raise RuntimeError("a bug")

    monkeypatch.setattr(cosim.cli.run, "_load_and_run", buggy)
    with pytest.raises(RuntimeError, match="a bug"):
        main(["run", str(LANE_CHANGE), "--transport", "inproc"])
