"""A run's figure drawn by the process `cosim run` starts with the run
(`cosim.execution.figure_process`, `cosim.figures.drawing_process`): the same PNG,
byte for byte, as drawn in the run's own process; a note, never a hang or a lost
run, when that process is gone or the request breaks."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from cosim.execution.figure_process import CHILD, FigureProcess
from cosim.execution.finish import analyse_run_folder
from tests.helpers.paths import REPO_ROOT

LANE_CHANGE = REPO_ROOT / "scenarios" / "lane_change.yaml"


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    from cosim.execution.run import run_scenario
    from cosim.scenario.loader import load_scenario

    result = run_scenario(load_scenario(LANE_CHANGE, ["duration=3"]),
                          out_dir=tmp_path_factory.mktemp("run") / "lane_change",
                          transport="inproc", progress=False)
    assert result.status == "ok"
    return result


@pytest.mark.integration
def test_the_process_draws_the_figure_this_process_draws_byte_for_byte(short_run):
    drawer = FigureProcess()
    drawer.start()
    assert drawer.started
    notes = analyse_run_folder(short_run, figures=True, drawer=drawer)
    figure = short_run.out_dir / "figure_manoeuvre.png"
    assert notes == [f"figure: {figure}"]
    drawn_there = figure.read_bytes()
    figure.unlink()
    assert analyse_run_folder(short_run, figures=True) == [f"figure: {figure}"]
    assert figure.read_bytes() == drawn_there
    assert drawer._process.returncode == 0


@pytest.mark.integration
def test_a_drawing_process_that_died_leaves_a_note_and_the_run(short_run):
    drawer = FigureProcess()
    drawer.start()
    drawer._process.kill()
    drawer._process.wait()
    notes = analyse_run_folder(short_run, figures=True, drawer=drawer)
    assert len(notes) == 1
    assert notes[0].startswith("figures not drawn: the drawing process ended with status -9 "
                               "before it had the run ("), notes
    assert json.loads((short_run.out_dir / "metrics.json").read_text())  # the metrics are there


@pytest.mark.integration
def test_a_drawing_process_that_could_not_run_leaves_the_figure_to_this_process(short_run, monkeypatch):
    # e.g. the package not importable from its interpreter: it exits 1 before any answer
    import cosim.execution.figure_process as figure_process

    monkeypatch.setattr(figure_process, "CHILD", [sys.executable, "-c", "raise SystemExit(1)"])
    figure = short_run.out_dir / "figure_manoeuvre.png"
    figure.unlink(missing_ok=True)
    drawer = FigureProcess()
    drawer.start()
    assert analyse_run_folder(short_run, figures=True, drawer=drawer) == [f"figure: {figure}"]
    assert figure.is_file()


def test_without_a_drawing_process_the_figure_is_drawn_here(short_run):
    figure = short_run.out_dir / "figure_manoeuvre.png"
    figure.unlink(missing_ok=True)
    assert analyse_run_folder(short_run, figures=True, drawer=FigureProcess()) == [f"figure: {figure}"]
    assert figure.is_file()


def test_with_one_cpu_there_is_no_drawing_process(monkeypatch):
    # its import would take the run's own CPU for as long as it saves afterwards
    from cosim.engine import one_cpu

    monkeypatch.setattr(one_cpu, "cpus_beside", lambda: set())
    drawer = FigureProcess()
    drawer.start()
    assert not drawer.started
    drawer.close()


def test_a_process_never_asked_ends_quietly_when_closed():
    drawer = FigureProcess()
    drawer.start()
    drawer.close()
    assert drawer._process.returncode == 0
    drawer.close()  # twice: nothing more


def _child(request: bytes) -> subprocess.CompletedProcess:
    return subprocess.run(CHILD, input=request, capture_output=True, cwd=REPO_ROOT, timeout=60)


def test_end_of_input_before_a_request_ends_the_child_at_once():
    done = _child(b"")
    assert (done.returncode, done.stdout) == (0, b"")


def test_a_request_cut_short_is_answered_with_what_is_missing():
    header = {"folder": "/nowhere", "columns": ["time", "x"], "rows": 100}
    done = _child(json.dumps(header).encode() + b"\n" + bytes(10))
    assert done.returncode == 1
    assert json.loads(done.stdout) == {"error": "bad request from the run: the rows ended after "
                                                "10 of 1600 bytes"}


def test_a_figure_that_cannot_be_drawn_is_answered_with_why(tmp_path):
    done = _child(json.dumps({"folder": str(tmp_path / "gone"), "columns": None}).encode() + b"\n")
    assert done.returncode == 0
    assert json.loads(done.stdout) == {"error": f"{tmp_path / 'gone'}: no such run folder"}


def _drawing_processes() -> list[int]:
    """Processes of this machine running the drawing module (this test's children)."""
    found = []
    for entry in os.listdir("/proc"):
        try:
            with open(f"/proc/{entry}/cmdline", "rb") as handle:
                if b"cosim.figures.drawing_process" in handle.read():
                    found.append(int(entry))
        except (OSError, ValueError):
            continue
    return found


@pytest.mark.integration
@pytest.mark.parametrize("transport", ["inproc", "zenoh"])
def test_cosim_run_draws_through_its_process_and_leaves_none(tmp_path, transport):
    out = tmp_path / "run"
    done = subprocess.run([sys.executable, "-m", "cosim.cli.app", "run", str(LANE_CHANGE),
                           "--set", "duration=2", "--transport", transport, "--out", str(out)],
                          cwd=REPO_ROOT, capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stderr
    assert f"figure: {out / 'figure_manoeuvre.png'}\n" in done.stdout
    assert (out / "figure_manoeuvre.png").stat().st_size > 0
    assert _drawing_processes() == []
