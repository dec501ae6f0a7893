"""Where plot, compare, export-ssp and sweep write: a missing folder is created (as
`cosim run --out` creates its folder), a path under a regular file, a folder given for a
file, or a place that cannot be written is one line "error: ..." and exit 2; and sweep's
options (--seed, --scheduler, --out, --transport) are refused before anything starts."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.cli.app import main
from tests.helpers.synthetic_runs import lane_change_run

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
VARY = ["--vary", "components.vehicle.parameters.vx0=5:10", "--samples", "2"]


def _err(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err.strip()


@pytest.fixture
def a_file(tmp_path) -> Path:
    path = tmp_path / "afile"
    path.write_text("not a folder\n")
    return path


@pytest.fixture
def run_dir(tmp_path) -> Path:
    return lane_change_run(tmp_path / "run")


def test_plot_creates_the_missing_folder_of_its_out_file(tmp_path, run_dir, capsys):
    out = tmp_path / "new" / "deeper" / "x.png"
    assert main(["plot", str(run_dir), "--out", str(out)]) == 0
    assert capsys.readouterr().out == f"figure: {out}\n"
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("under", ["", "sub/"])
def test_plot_out_under_a_regular_file_is_one_line(tmp_path, run_dir, a_file, capsys, under):
    out = f"{a_file}/{under}x.png"
    assert main(["plot", str(run_dir), "--out", out]) == 2
    assert _err(capsys) == f"error: --out {out}: {a_file} is a file, not a folder"
    assert a_file.read_text() == "not a folder\n"


def test_plot_out_that_is_a_folder_is_one_line(tmp_path, run_dir, capsys):
    assert main(["plot", str(run_dir), "--out", str(tmp_path)]) == 2
    assert _err(capsys) == f"error: --out {tmp_path}: is a folder; give the name of the file to write"


@pytest.mark.skipif(not Path("/sys/kernel").is_dir(), reason="needs sysfs (no new file can be made there)")
def test_plot_into_a_place_that_cannot_be_written_is_one_line(run_dir, capsys):
    assert main(["plot", str(run_dir), "--out", "/sys/x.png"]) == 2
    assert _err(capsys) in ("error: /sys/x.png: cannot write: Permission denied",
                            "error: /sys/x.png: cannot write: Read-only file system")


def test_compare_out_under_a_regular_file_is_one_line_and_a_new_folder_is_made(
        tmp_path, run_dir, a_file, capsys):
    out = f"{a_file}/x.png"
    assert main(["compare", str(run_dir), str(run_dir), "--out", out]) == 2
    assert _err(capsys) == f"error: --out {out}: {a_file} is a file, not a folder"
    assert main(["compare", str(run_dir), "--out", str(a_file)]) == 2
    assert _err(capsys) == f"error: --out {a_file}: is a file, not a folder"
    fresh = tmp_path / "new" / "cmp"
    assert main(["compare", str(run_dir), "--out", str(fresh)]) == 0
    assert (fresh / "compare_metrics.csv").read_text().splitlines()[0] == "metric,run"


def test_export_ssp_paths(tmp_path, a_file, capsys):
    out = f"{a_file}/x.ssp"
    assert main(["export-ssp", "lane_change", out]) == 2
    assert _err(capsys) == f"error: {out}: {a_file} is a file, not a folder"
    folder = tmp_path / "d.ssp"
    folder.mkdir()
    assert main(["export-ssp", "lane_change", str(folder)]) == 2
    assert _err(capsys) == f"error: {folder}: is a folder; give the name of the file to write"
    fresh = tmp_path / "nodir" / "x.ssp"
    assert main(["export-ssp", "lane_change", str(fresh)]) == 0
    assert capsys.readouterr().out.startswith(f"wrote {fresh}: 1 FMU components")
    assert fresh.read_bytes()[:2] == b"PK"


@pytest.mark.parametrize("options, message", [
    (["--seed", "-1"], "--seed -1: must be a whole number from 0 up"),
    (["--scheduler", "garbage"], "--scheduler 'garbage': expected a Dask scheduler address "
                                 "PROTOCOL://HOST:PORT (port 1..65535), e.g. tcp://127.0.0.1:8786"),
    (["--scheduler", "tcp://127.0.0.1:99999"], "--scheduler 'tcp://127.0.0.1:99999': expected a "
                                               "Dask scheduler address PROTOCOL://HOST:PORT "
                                               "(port 1..65535), e.g. tcp://127.0.0.1:8786"),
    (["--transport", "bogus"], "unknown transport 'bogus' (--transport: choose from inproc, zenoh)"),
])
def test_sweep_options_are_refused_before_anything_starts(tmp_path, capsys, monkeypatch,
                                                         options, message):
    import cosim.execution.sweep as sweep

    def no_cluster(*args, **kwargs):
        raise AssertionError("a cluster was started")

    monkeypatch.setattr(sweep, "execute_samples", no_cluster)
    out = tmp_path / "sw"
    assert main(["sweep", str(SCENARIOS / "open_loop.yaml"), *VARY, "--out", str(out), *options]) == 2
    assert _err(capsys) == f"error: {message}"
    assert not out.exists()


@pytest.mark.parametrize("under", ["", "/x"])
def test_sweep_out_under_a_regular_file_is_refused(a_file, capsys, under):
    out = f"{a_file}{under}"
    assert main(["sweep", str(SCENARIOS / "open_loop.yaml"), *VARY, "--out", out]) == 2
    which = "" if not under else f"{a_file} "
    assert _err(capsys) == f"error: --out {out}: {which}is a file, not a folder"
