"""`cosim sweep` when a sample's worker process dies, on Ctrl-C, and its --out and --samples
checks: a segfaulting sample fails alone and once (its run folder completed, the others
keep their results), Ctrl-C indexes the finished samples and leaves no process behind, a
non-empty --out is refused unless --force replaces an earlier sweep there, --samples is
bounded; every message one line, without a traceback."""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cosim.cli.app import main
from cosim.execution.sweep import parse_vary, sample_points
from cosim.execution.sweep_samples import MAX_SAMPLES, OUTCOME_SUFFIX, died_error, fault_report, marks
from tests.helpers.components import GOOD
from tests.helpers.paths import REPO_ROOT

COSIM = Path(sys.executable).with_name("cosim")
CRASHY = """\
name: crashy
duration: 0.3
tick: 0.01
components:
  seg:
    python: tests.helpers.components:Segfault
    parameters: {at: 1.0}
sources:
  ramp: {kind: ramp, start: 0.0, end: 1.0, t_start: 0.0, t_end: 1.0}
connections:
  - {from: ramp.value, to: seg.u}
"""
SLOW = CRASHY.replace("tests.helpers.components:Segfault", "tests.helpers.components:Sleeper") \
             .replace("{at: 1.0}", "{seconds: 0.0}").replace("duration: 0.3", "duration: 2.0")


def _sweep(tmp_path: Path, text: str, *options: str, interrupt_when=None):
    """`cosim sweep` in its own session (Ctrl-C'd, as a terminal does, once `interrupt_when()`);
    (process result, --out folder, processes of the session still alive after 5 s)."""
    scenario, out = tmp_path / "s.yaml", tmp_path / "sw"
    scenario.write_text(text)
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT)}
    proc = subprocess.Popen([str(COSIM), "sweep", str(scenario), "--out", str(out), *options],
                            cwd=REPO_ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    if interrupt_when is not None:
        end = time.monotonic() + 60
        while not interrupt_when(out):
            assert time.monotonic() < end and proc.poll() is None, "timed out"
            time.sleep(0.02)
        os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=180)
    return subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr), out, _alive(proc.pid)


def _alive(session: int) -> list[str]:
    """The live processes (not zombies) of the session, after up to 5 s."""
    def alive() -> list[str]:
        found = []
        for pid in subprocess.run(["pgrep", "-s", str(session)], capture_output=True,
                                  text=True).stdout.split():
            try:
                stat = Path(f"/proc/{pid}/stat").read_text()
                cmdline = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
            except OSError:
                continue
            if stat.rsplit(")", 1)[-1].split()[0] != "Z":
                found.append(f"{pid} {cmdline}")
        return found

    end = time.monotonic() + 5
    while alive() and time.monotonic() < end:
        time.sleep(0.05)
    return alive()


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / "samples.csv") as f:
        return list(csv.DictReader(f))


def _manifest(out: Path, index: int) -> dict:
    return json.loads((out / "samples" / f"sample_{index:04d}" / "manifest.json").read_text())


@pytest.mark.integration
def test_a_sample_that_segfaults_fails_alone_once_and_its_run_folder_is_completed(tmp_path):
    vary = "components.seg.parameters.at=0.05:0.6"
    points = sample_points([parse_vary(vary)], 6, seed=3)[:, 0]
    crash = [i for i, at in enumerate(points) if at < 0.3 - 1e-9]
    assert 0 < len(crash) < 6
    done, out, left = _sweep(tmp_path, CRASHY, "--vary", vary, "--samples", "6", "--seed", "3")
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr + done.stdout and "KilledWorker" not in done.stdout
    assert done.stderr.strip().splitlines() == [
        f"sweep failed: {len(crash)} of 6 samples failed (samples {', '.join(map(str, crash))}; "
        f"see samples.csv)"]
    rows = _rows(out)
    assert [r["status"] for r in rows] == ["failed" if i in crash else "ok" for i in range(6)]
    for i, row in enumerate(rows):
        manifest = _manifest(out, i)
        if i not in crash:
            assert manifest["status"] == "ok" and row["error"] == ""
            continue
        tick = math.ceil((points[i] - 1e-9) / 0.01)  # its step at t >= at: ticks 0..tick-1 done
        message = (f"sample {i}: the worker process died while running it (killed by SIGSEGV at "
                   f"components.py:218 in step) after tick {tick - 1} (t={(tick - 1) * 0.01:.10g} s)")
        assert row["error"] == message
        assert f"failed: {message}" in done.stdout
        assert manifest["status"] == "failed" and manifest["error"] == message
        folder = out / "samples" / f"sample_{i:04d}"
        assert not list(folder.glob("*.f64*"))  # the CSV files rebuilt from the spools
        with open(folder / "signals.csv") as f:
            assert len(f.read().splitlines()) == 1 + tick
    assert not list((out / "samples").glob(".*"))  # no mark left
    assert json.loads((out / "sweep.json").read_text())["status"] == "finished"
    assert left == []


def test_the_error_of_a_dead_worker_names_what_its_fault_report_says(tmp_path):
    run_dir = tmp_path / "samples" / "sample_0003"
    run_dir.parent.mkdir()
    running, _ = marks(run_dir)
    running.write_text("pid 12\n")
    assert fault_report(run_dir) == (None, None)
    assert died_error(3, run_dir) == ("sample 3: the worker process died while running it (no "
                                      "fault report: killed, e.g. SIGKILL out of memory, or it "
                                      "exited?)")
    import ctypes  # a library frame (the stdlib's) is passed over for the user's code

    running.write_text(f'pid 12\nFatal Python error: Aborted\n\nCurrent thread 0x1 (most recent '
                       f'call first):\n  File "{ctypes.__file__}", line 519 in string_at\n'
                       f'  File "/home/u/plant.py", line 7 in step\n')
    assert died_error(3, run_dir) == ("sample 3: the worker process died while running it "
                                      "(killed by SIGABRT at plant.py:7 in step)")


@pytest.mark.integration
def test_ctrl_c_indexes_the_finished_samples_and_leaves_no_process(tmp_path):
    vary = "components.seg.parameters.seconds=0.0:0.05"  # per step: 0.2 to 10 s a sample

    def one_finished(out: Path) -> bool:  # its task's outcome is on disk: it counts as done
        return any((out / "samples").glob(f".sample_*{OUTCOME_SUFFIX}"))

    done, out, left = _sweep(tmp_path, SLOW, "--vary", vary, "--samples", "4", "--seed", "1",
                             interrupt_when=one_finished)
    rows = _rows(out)
    finished = [i for i, r in enumerate(rows) if r["status"] == "ok"]
    assert done.returncode == 1, done.stderr
    assert done.stderr.splitlines() == [
        f"sweep interrupted after {len(finished)} of 4 samples; finished ones indexed in {out}"]
    assert "Traceback" not in done.stdout
    assert len(finished) >= 1 and {r["status"] for r in rows} == {"ok", "interrupted"}
    for i, row in enumerate(rows):
        if i in finished:
            assert _manifest(out, i)["status"] == "ok" and row["error"] == ""
        elif (out / "samples" / f"sample_{i:04d}" / "manifest.json").exists():  # it was running
            assert row["error"].startswith(f"sample {i}: interrupted (Ctrl-C) while running")
            manifest = _manifest(out, i)
            assert manifest["status"] == "interrupted" and manifest["error"] == row["error"]
            assert not list((out / "samples" / f"sample_{i:04d}").glob("*.f64*"))
        else:
            assert row["error"] == f"sample {i}: not run (the sweep was interrupted)"
    settings = json.loads((out / "sweep.json").read_text())
    assert settings["status"] == "interrupted" and settings["interrupted"] == 4 - len(finished)
    assert (out / "summary.csv").is_file()
    assert not list((out / "samples").glob(".*"))
    assert left == []


VARY = ["--vary", "components.gain.parameters.k=1:2"]


def _err(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err.strip()


@pytest.fixture
def no_cluster(monkeypatch):
    import cosim.execution.sweep as sweep

    def refuse(*args, **kwargs):
        raise AssertionError("a cluster was started")

    monkeypatch.setattr(sweep, "execute_samples", refuse)


@pytest.mark.parametrize("samples", ["0", str(MAX_SAMPLES + 1), "100000000000"])
def test_samples_out_of_bounds_are_refused_in_one_line(tmp_path, capsys, no_cluster, samples):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(GOOD)
    out = tmp_path / "sw"
    assert main(["sweep", str(scenario), *VARY, "--samples", samples, "--out", str(out)]) == 2
    message = ("need at least 1" if samples == "0" else
               f"at most {MAX_SAMPLES} (a run folder each); split a larger study into sweeps "
               f"with different --seed or --out")
    assert _err(capsys) == f"error: --samples {samples}: {message}"
    assert not out.exists()


def test_a_non_empty_out_is_refused_without_force_and_unless_a_sweeps_with_it(tmp_path, capsys,
                                                                              no_cluster):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(GOOD)
    out = tmp_path / "other"
    (out / "keep").mkdir(parents=True)
    (out / "notes.txt").write_text("mine\n")
    command = ["sweep", str(scenario), *VARY, "--samples", "2", "--out", str(out)]
    assert main(command) == 2
    assert _err(capsys) == (f"error: --out {out}: the folder exists and is not empty (another "
                            f"sweep?); choose another folder, or replace that sweep with --force")
    assert main([*command, "--force"]) == 2
    assert _err(capsys) == (f"error: --out {out}: the folder is not empty and is not a sweep's "
                            f"folder (no sweep.json or samples.csv); --force replaces only an "
                            f"earlier sweep's folder")
    assert sorted(p.name for p in out.iterdir()) == ["keep", "notes.txt"]


@pytest.mark.integration
def test_force_replaces_an_earlier_sweeps_folder(tmp_path, capsys):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(GOOD)
    out = tmp_path / "sw"
    command = ["sweep", str(scenario), *VARY, "--out", str(out)]
    assert main([*command, "--samples", "3"]) == 0, capsys.readouterr().err
    assert main([*command, "--samples", "2"]) == 2  # an earlier sweep there: not without --force
    assert "the folder exists and is not empty" in _err(capsys)
    assert (out / "samples" / "sample_0002").is_dir()
    assert main([*command, "--samples", "2", "--force"]) == 0, capsys.readouterr().err
    assert sorted(p.name for p in (out / "samples").iterdir()) == ["sample_0000", "sample_0001"]
    assert [r["sample"] for r in _rows(out)] == ["0", "1"]
    assert json.loads((out / "sweep.json").read_text())["samples"] == 2
