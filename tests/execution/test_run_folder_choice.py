"""Where a run writes: `--out` / `cosim.run(out=)`, `--force`, and a folder that stays
put when a component changes the working directory.

`--force` replaces an earlier run's folder whole (no file of the old run is left to
be read as this one's) and nothing else: a non-empty folder without a manifest.json
is refused, so `--out / --force` cannot empty a system folder. The Python API refuses
what the command refuses.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

import cosim
from cosim.errors import UserError
from tests.execution.test_fmu_faults import COSIM
from tests.helpers.paths import REPO_ROOT

CHDIR_SCENARIO = """\
name: chdir
duration: 0.3
tick: 0.01
components:
  g:
    python: tests.helpers.components:ChangesDirectory
sources:
  ref: {kind: constant, value: 1.0}
connections:
  - ref.value -> g.u
"""


def _cosim(*args: str, cwd: Path = REPO_ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([str(COSIM), *args], cwd=cwd, capture_output=True, text=True,
                          timeout=120, env={**os.environ, "PYTHONPATH": str(REPO_ROOT)})


def test_force_replaces_an_earlier_run_whole(tmp_path):
    out = tmp_path / "run"
    first = _cosim("run", "lane_change", "--transport", "inproc", "--set", "duration=1",
                   "--no-figures", "--out", str(out))
    assert first.returncode == 0, first.stderr
    assert list((out / "arrays").glob("planner.*.csv"))  # the lane change's planner arrays
    again = _cosim("run", "open_loop", "--transport", "inproc", "--set", "duration=1",
                   "--no-figures", "--out", str(out), "--force")
    assert again.returncode == 0, again.stderr
    assert not (out / "arrays").exists()  # open_loop has no planner: nothing of the old run
    assert json.loads((out / "manifest.json").read_text())["name"] == "open_loop"
    assert cosim.load_run(out).arrays == {}


def test_force_refuses_a_folder_that_is_not_a_run_folder(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    done = _cosim("run", "open_loop", "--transport", "inproc", "--out", str(tmp_path), "--force")
    assert done.returncode == 2
    assert done.stderr.strip() == (
        f"error: --out {tmp_path}: the folder is not empty and is not a run folder (no "
        f"manifest.json); --force replaces only an earlier run's folder")
    assert [p.name for p in tmp_path.iterdir()] == ["notes.txt"]


def test_the_python_api_refuses_what_the_command_refuses(tmp_path):
    out = tmp_path / "run"
    cosim.run("open_loop", set=["duration=0.5"], out=out)
    with pytest.raises(UserError, match=r"^out .*: the folder exists and is not empty .*"
                                        r"replace that run with force=True$"):
        cosim.run("open_loop", set=["duration=0.5"], out=out)
    with pytest.raises(UserError, match="^out needs a folder name, got an empty one$"):
        cosim.run("open_loop", set=["duration=0.5"], out="")
    assert cosim.run("open_loop", set=["duration=0.5"], out=out, force=True).status == "ok"


def test_a_component_that_changes_directory_does_not_move_the_run_folder(tmp_path):
    scenario = tmp_path / "chdir.yaml"
    scenario.write_text(CHDIR_SCENARIO)
    done = _cosim("run", str(scenario), "--transport", "inproc", "--no-figures",
                  "--out", "relative_run", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "run folder: relative_run\n" in done.stdout
    manifest = json.loads((tmp_path / "relative_run" / "manifest.json").read_text())
    assert manifest["status"] == "ok" and manifest["ticks"] == 30
    assert len(cosim.load_run(tmp_path / "relative_run").signals) == 31


def test_a_run_folder_is_private_to_its_owner(tmp_path):
    (tmp_path / "given").mkdir(mode=0o755)  # a folder the user made: the run makes it private too
    for out in (tmp_path / "new" / "run", tmp_path / "given"):
        cosim.run("open_loop", set=["duration=0.2"], out=out)
        assert out.stat().st_mode & 0o777 == 0o700
    if os.geteuid() == 0 and shutil.which("runuser"):  # another user cannot read its signals
        tmp_path.chmod(0o755)
        (tmp_path / "new").chmod(0o755)
        other = subprocess.run(["runuser", "-u", "nobody", "--", "cat",
                                str(tmp_path / "new" / "run" / "signals.csv")],
                               capture_output=True, text=True)
        assert other.returncode != 0 and "Permission denied" in other.stderr


def test_the_folder_of_a_run_that_never_started_is_reused_without_force(tmp_path):
    """Run again after fixing a mistake found at start-up: the same --out just works."""
    out = tmp_path / "run"
    typo = _cosim("run", "lane_change", "--no-figures", "--out", str(out),  # Zenoh: after the folder
                  "--set", "components.controller.python=controllers.backstepping:Backsteping")
    assert typo.returncode == 2 and "has no class 'Backsteping'" in typo.stderr
    assert json.loads((out / "manifest.json").read_text())["status"] == "failed"
    fixed = _cosim("run", "lane_change", "--transport", "inproc", "--no-figures", "--out", str(out),
                   "--set", "duration=1")
    assert fixed.returncode == 0, fixed.stderr
    assert json.loads((out / "manifest.json").read_text())["status"] == "ok"
    again = _cosim("run", "lane_change", "--transport", "inproc", "--no-figures", "--out", str(out),
                   "--set", "duration=1")  # a run that did start is kept unless --force
    assert again.returncode == 2 and "the folder exists and is not empty" in again.stderr
