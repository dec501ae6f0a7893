"""Faults of the run folder: a full disk (a small tmpfs mounted here, or the
spool's next window failing to allocate with ENOSPC), a read-only folder, the folder removed mid-run. Each gives
one line "cannot write the run folder X: <reason> at tick k", a failed run
(status 1), a manifest that says failed where it can be written, no .tmp file,
and spools that `cosim recover` turns into the CSV and a "recovered" manifest."""

from __future__ import annotations

import contextlib
import errno
import json
import math
import mmap
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from cosim.cli.app import main
from cosim.results import recorder as recorder_module
from tests.helpers.components import GOOD

LONG = GOOD.replace("duration: 0.5", "duration: 20.0")  # 2001 rows: spools of about 48 kB


def _scenario(tmp_path: Path, text: str = LONG) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(text)
    return path


def _run(scenario: Path, out: Path, *extra: str) -> int:
    return main(["run", str(scenario), "--transport", "inproc", "--out", str(out),
                 "--no-figures", *extra])


def _error_line(capsys) -> str:
    lines = [l for l in capsys.readouterr().err.splitlines() if l.strip()]
    assert not any("Traceback" in l for l in lines)
    return lines[-1]


def _no_tmp(folder: Path) -> None:
    assert not list(folder.rglob("*.tmp"))


@pytest.fixture
def small_disk(tmp_path):
    """A 40 kB tmpfs (needs root); skipped when it cannot be mounted."""
    mount = tmp_path / "disk"
    mount.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None or subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=40k", "tmpfs", str(mount)],
            capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    yield mount
    subprocess.run(["umount", "-l", str(mount)], check=False)


def test_full_disk_fails_the_run_in_one_line_and_recover_completes_it(tmp_path, small_disk,
                                                                     capsys, monkeypatch):
    monkeypatch.setattr(recorder_module, "WINDOW_BYTES", 1)  # 12 kB windows: some fit in 40 kB
    out = small_disk / "run"
    assert _run(_scenario(tmp_path), out) == 1
    line = _error_line(capsys)
    assert line.startswith(f"run failed: cannot write the run folder {out}: "
                           "No space left on device at tick ")
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "failed" and "No space left on device" in manifest["error"]
    assert (out / "signals.f64").exists()  # kept for recover
    _no_tmp(out)
    _fill(small_disk)  # the spool gave back its unused window: take that space too
    assert main(["recover", str(out)]) == 2  # still full: one line, no traceback
    assert "cannot write the run folder" in _error_line(capsys)
    _no_tmp(out)
    subprocess.run(["mount", "-o", "remount,size=8m", str(small_disk)], check=True)
    assert main(["recover", str(out)]) == 0
    rows = (out / "signals.csv").read_text().splitlines()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "recovered" and manifest["recovered_from_status"] == "failed"
    assert manifest["ticks"] == len(rows) - 2  # header and tick 0
    assert manifest["last_time_s"] == float(rows[-1].split(",")[0])
    assert not (out / "signals.f64").exists()


def test_enospc_mid_run_stops_it_at_that_tick(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(recorder_module, "WINDOW_BYTES", 1)  # windows of one page: many allocations
    calls = {"n": 0}
    real_allocate = os.posix_fallocate

    def allocate(fd, offset, length):
        calls["n"] += 1
        if calls["n"] > 3:  # the row count's page, then two windows of rows
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real_allocate(fd, offset, length)

    monkeypatch.setattr(recorder_module.os, "posix_fallocate", allocate)
    out = tmp_path / "run"
    assert _run(_scenario(tmp_path), out) == 1
    row_bytes = 8 * 3  # time, ramp.value, gain.y
    rows_per_window = math.lcm(row_bytes, mmap.ALLOCATIONGRANULARITY) // row_bytes
    tick = 2 * rows_per_window  # the first row that needed a third window
    line = _error_line(capsys)
    assert line == (f"run failed: cannot write the run folder {out}: No space left on device "
                    f"at tick {tick}")
    manifest = json.loads((out / "manifest.json").read_text())
    assert (manifest["status"], manifest["ticks"]) == ("failed", tick)
    _no_tmp(out)
    assert main(["recover", str(out)]) == 0  # every row before that tick is in the spool
    assert len((out / "signals.csv").read_text().splitlines()) == 1 + tick


def _fill(disk: Path) -> None:
    """Write a file on `disk` until it is full."""
    with open(disk / "filler", "wb", buffering=0) as filler:
        with contextlib.suppress(OSError):
            while True:
                filler.write(b"\0" * 4096)


def test_folder_removed_mid_run(tmp_path, capsys, monkeypatch):
    out = tmp_path / "run"
    original = recorder_module.Recorder.after_tick

    def after_tick(self, tick, t, values, arrays):
        if tick == 50:
            shutil.rmtree(out)
        original(self, tick, t, values, arrays)

    monkeypatch.setattr(recorder_module.Recorder, "after_tick", after_tick)
    assert _run(_scenario(tmp_path), out) == 1
    line = _error_line(capsys)
    assert line.startswith(f"run failed: cannot write the run folder {out}: the folder was "
                           "removed at tick ")
    assert not out.exists()


def test_read_only_folder_is_one_line(tmp_path, capsys):
    out = tmp_path / "ro"
    out.mkdir()
    if os.geteuid() == 0:  # root ignores permissions: a read-only mount instead
        if subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(out)],
                          capture_output=True).returncode != 0:
            pytest.skip("cannot mount a read-only tmpfs")
    else:
        out.chmod(0o555)
    try:
        assert _run(_scenario(tmp_path), out) == 2
        assert _error_line(capsys) == (f"error: cannot write the run folder {out}: "
                                       "Read-only file system" if os.geteuid() == 0 else
                                       f"error: cannot write the run folder {out}: "
                                       "Permission denied")
    finally:
        if os.geteuid() == 0:
            subprocess.run(["umount", "-l", str(out)], check=False)


def test_out_refuses_an_occupied_folder_and_the_empty_name(tmp_path, capsys):
    scenario = _scenario(tmp_path, GOOD)
    out = tmp_path / "run"
    assert _run(scenario, out) == 0
    before = (out / "signals.csv").read_bytes()
    capsys.readouterr()
    assert _run(scenario, out) == 2
    assert _error_line(capsys) == (f"error: --out {out}: the folder exists and is not empty "
                                   "(another run?); choose another folder, or replace that "
                                   "run with --force")
    assert (out / "signals.csv").read_bytes() == before
    assert _run(scenario, out, "--force") == 0
    assert main(["run", str(scenario), "--transport", "inproc", "--out", ""]) == 2
    assert _error_line(capsys) == "error: --out needs a folder name, got an empty one"
