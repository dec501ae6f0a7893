"""A run's figure drawn by the process `cosim run` starts with the run
(`cosim.execution.figure_process`, `cosim.figures.drawing_process`): the same PNG,
byte for byte, as drawn in the run's own process; drawn here when that process cannot
draw; a note, never a hang, a leftover process or a lost run, when it dies."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

import cosim.execution.figure_process as figure_process
from cosim.engine import one_cpu
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


@pytest.fixture
def two_cpus(monkeypatch):
    """A CPU beside the chain's, whatever this machine has, and matplotlib not loaded here
    as far as `start` can tell (the process starts only then)."""
    monkeypatch.setattr(one_cpu, "cpus_beside", lambda: {0})
    monkeypatch.setattr(figure_process, "drawing_loaded_here", lambda: False)


@pytest.fixture
def figure(short_run):
    path = short_run.out_dir / "figure_manoeuvre.png"
    path.unlink(missing_ok=True)
    return path


def _started(**_) -> FigureProcess:
    drawer = FigureProcess()
    drawer.start()
    assert drawer.pid is not None
    return drawer


@pytest.mark.integration
def test_the_process_draws_the_figure_this_process_draws_byte_for_byte(short_run, figure, two_cpus):
    drawer = _started()
    assert analyse_run_folder(short_run, figures=True, drawer=drawer) == [f"figure: {figure}"]
    assert drawer._process.returncode == 0  # it drew, and answered, before it exited
    drawn_there = figure.read_bytes()
    figure.unlink()
    assert analyse_run_folder(short_run, figures=True) == [f"figure: {figure}"]
    assert figure.read_bytes() == drawn_there


@pytest.mark.integration
def test_a_process_gone_before_the_run_ends_leaves_the_figure_to_this_process(short_run, figure, two_cpus):
    drawer = _started()
    drawer._process.kill()
    drawer._process.wait()
    assert analyse_run_folder(short_run, figures=True, drawer=drawer) == [f"figure: {figure}"]
    assert figure.is_file()


@pytest.mark.integration
def test_a_process_that_could_not_run_leaves_the_figure_to_this_process(short_run, figure, two_cpus,
                                                                         monkeypatch):
    # e.g. the package not importable from its interpreter: it reads the request, exits 1
    monkeypatch.setattr(figure_process, "CHILD", [sys.executable, "-c",
                                                  "import sys; sys.stdin.read(); sys.exit(1)"])
    drawer = _started()
    assert analyse_run_folder(short_run, figures=True, drawer=drawer) == [f"figure: {figure}"]


@pytest.mark.integration
def test_a_process_killed_while_drawing_leaves_a_note_and_the_run(short_run, figure, two_cpus,
                                                                  monkeypatch):
    monkeypatch.setattr(figure_process, "CHILD", [sys.executable, "-c", "import os, sys; "
                                                  "sys.stdin.read(); print('dying', file=sys.stderr); "
                                                  "os.kill(os.getpid(), 9)"])
    drawer = _started()
    notes = analyse_run_folder(short_run, figures=True, drawer=drawer)
    assert notes == ["figures not drawn: the drawing process ended with status -9: dying"]
    assert not figure.exists()
    assert json.loads((short_run.out_dir / "metrics.json").read_text())  # the metrics are there


@pytest.mark.integration
def test_rows_above_the_limit_are_drawn_here(short_run, figure, two_cpus, monkeypatch):
    monkeypatch.setattr(figure_process, "ROWS_HANDED_OVER_BYTES", 1000)
    drawer = _started()
    assert not drawer.take(short_run.out_dir, short_run.full_signals)
    assert analyse_run_folder(short_run, figures=True, drawer=drawer) == [f"figure: {figure}"]
    drawer.close()
    assert drawer._process.returncode == -9  # never asked: ended by close


def test_with_one_cpu_there_is_no_drawing_process(short_run, figure, monkeypatch):
    # its import would take the run's own CPU for as long as it saves afterwards
    monkeypatch.setattr(one_cpu, "cpus_beside", lambda: set())
    drawer = FigureProcess()
    drawer.start()
    assert drawer.pid is None
    assert analyse_run_folder(short_run, figures=True, drawer=drawer) == [f"figure: {figure}"]


def test_a_process_that_has_matplotlib_loaded_draws_itself(short_run, figure, monkeypatch):
    import matplotlib  # noqa: F401  (loaded here, as in a Python session)

    monkeypatch.setattr(one_cpu, "cpus_beside", lambda: {0})
    assert figure_process.drawing_loaded_here()
    drawer = FigureProcess()
    drawer.start()
    assert drawer.pid is None
    assert analyse_run_folder(short_run, figures=True, drawer=drawer) == [f"figure: {figure}"]


def test_a_process_never_asked_is_ended_by_close(two_cpus):
    drawer = _started()
    drawer.close()
    assert drawer._process.poll() is not None
    drawer.close()  # twice: nothing more


def _child(request: bytes, rows: bytes = b"") -> subprocess.CompletedProcess:
    read, write = os.pipe()  # any readable descriptor stands for the memory file here
    os.write(write, rows)
    os.close(write)
    try:
        return subprocess.run([*CHILD, "--rows-fd", str(read)], input=request, capture_output=True,
                              cwd=REPO_ROOT, timeout=60, pass_fds=(read,))
    finally:
        os.close(read)


def test_end_of_input_before_a_request_ends_the_child_quietly():
    done = _child(b"")
    assert (done.returncode, done.stdout) == (0, b"")


def test_a_rows_file_shorter_than_announced_is_answered_with_what_is_missing(tmp_path):
    from cosim.figures.drawing_process import read_request

    rows = tmp_path / "rows"
    rows.write_bytes(b'["time", "x"]   ' + bytes(10))
    with open(rows, "rb") as handle:
        with pytest.raises(ValueError, match="the rows file holds 26 bytes, not 1616"):
            read_request(json.dumps({"folder": "/run", "columns_bytes": 16, "rows": 100}).encode(),
                         handle.fileno())


def test_a_malformed_request_is_answered_and_ends_the_child():
    done = _child(b'{"folder": "/run"}\n')
    assert done.returncode == 1
    assert json.loads(done.stdout) == {"error": "bad request from the run: 'columns_bytes'"}


def test_a_figure_that_cannot_be_drawn_is_answered_with_why(tmp_path):
    request = json.dumps({"folder": str(tmp_path / "gone"), "columns_bytes": None, "rows": 0})
    done = _child(request.encode() + b"\n")
    assert done.returncode == 0
    assert json.loads(done.stdout) == {"error": f"{tmp_path / 'gone'}: no such run folder"}


@pytest.mark.integration
@pytest.mark.parametrize("transport", ["inproc", "zenoh"])
def test_cosim_run_hands_its_run_to_the_process_and_leaves_it_ended(tmp_path, transport, two_cpus,
                                                                    monkeypatch, capsys):
    from cosim.cli.app import main

    seen: list[tuple[FigureProcess, bool]] = []
    take = FigureProcess.take

    def spy(self, out_dir, full_signals):
        seen.append((self, handed := take(self, out_dir, full_signals)))
        return handed

    monkeypatch.setattr(FigureProcess, "take", spy)
    out = tmp_path / "run"
    assert main(["run", str(LANE_CHANGE), "--set", "duration=2", "--transport", transport,
                 "--out", str(out)]) == 0
    assert f"figure: {out / 'figure_manoeuvre.png'}\n" in capsys.readouterr().out
    [(drawer, handed)] = seen
    assert handed and drawer._process.returncode == 0  # it drew the figure, then exited
