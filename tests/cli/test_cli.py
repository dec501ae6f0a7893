"""The `cosim` command line: exit codes, messages, overrides, run folders."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cosim.cli.app import main, normalize_realtime
from cosim.results.recorder import read_signals
from tests.helpers.components import GOOD, Gain  # noqa: F401  (Gain: by class path)


@pytest.fixture
def good(tmp_path) -> Path:
    path = tmp_path / "good.yaml"
    path.write_text(GOOD)
    return path


def test_validate_good_file(good, capsys):
    assert main(["validate", str(good)]) == 0
    out = capsys.readouterr().out
    assert "ok (2 components, 1 connections; step order: ramp, gain)" in out


def test_validate_bad_file_exit_2_with_located_message(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(GOOD.replace("tick: 0.01", "tick: 0.01\ncolour: red")
                   .replace("{k: 3.0}", "{k: 3.0}\n    period: 0.015"))
    assert main(["validate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert f"{bad}:4: colour" in err
    assert "period" in err


def test_validate_wiring_error(tmp_path, capsys):
    bad = tmp_path / "wiring.yaml"
    bad.write_text(GOOD.replace("to: gain.x", "to: gain.nope"))
    assert main(["validate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:" in err and "nope" in err and "Traceback" not in err


def test_validate_algebraic_loop(tmp_path, capsys):
    loop = tmp_path / "loop.yaml"
    loop.write_text(GOOD.replace("connections:\n", "connections:\n  - {from: gain.y, to: gain.x}\n")
                    .replace("  - {from: ramp.value, to: gain.x}\n", ""))
    assert main(["validate", str(loop)]) == 2
    assert "algebraic loop: gain -> gain" in capsys.readouterr().err


def test_run_with_set_override_writes_the_run_folder(good, tmp_path, capsys):
    out = tmp_path / "run1"
    code = main(["run", str(good), "--out", str(out), "--transport", "inproc",
                 "--set", "duration=0.1", "--set", "components.gain.parameters.k=-1.5"])
    assert code == 0
    names, data = read_signals(out / "signals.csv")
    assert names == ["time", "gain.y", "ramp.value"]
    assert data.shape == (11, 3)
    # ramp value at t is t (0..1 over 1 s); gain reads it in the same tick
    assert data[:, 1].tolist() == [-1.5 * v for v in data[:, 2].tolist()]
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["scenario"]["duration"] == 0.1
    assert manifest["scenario"]["components"]["gain"]["parameters"] == {"k": -1.5}
    assert manifest["status"] == "ok" and manifest["ticks"] == 10
    assert manifest["sim_time_s"] == 0.1 and manifest["transport"] == "inproc"
    assert manifest["wall_time_s"] > 0 and manifest["real_time_factor"] > 0
    assert 0 < manifest["loop_time_s"] <= manifest["wall_time_s"]     # ticks 1..N, without tick 0
    printed = capsys.readouterr().out
    assert "real-time factor" in printed
    # the run is analysed afterwards: a figure, or a note saying why not
    assert "figure: " in printed or "figures not drawn: " in printed


def test_failed_run_exits_1_and_keeps_what_it_has(good, tmp_path, capsys):
    out = tmp_path / "run2"
    code = main(["run", str(good), "--out", str(out), "--transport", "inproc", "--no-figures",
                 "--set", "components.gain.parameters.fail_at=0.3"])
    assert code == 1
    err = capsys.readouterr().err
    assert "component 'gain' failed at tick 30 (t=0.3 s): output 'y' is non-finite: nan" in err
    _, data = read_signals(out / "signals.csv")
    assert data.shape == (30, 3) and data[-1, 0] == 0.29
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "failed" and "tick 30" in manifest["error"]
    assert manifest["ticks"] == 29


def test_run_failure_message_keeps_its_square_brackets(good, tmp_path, capsys):
    # brackets in a failure message look like rich markup; they must print as they are
    code = main(["run", str(good), "--out", str(tmp_path / "run3"), "--transport", "inproc",
                 "--no-figures", "--set", "components.gain.parameters.raise_at=0.2"])
    assert code == 1
    failed = [line for line in capsys.readouterr().err.splitlines()
              if line.startswith("run failed: ")]
    assert len(failed) == 1
    assert "component 'gain' failed at tick 20" in failed[0]
    assert failed[0].endswith("omega[fl] left its range: [nan 1.0] [red]x[/red]")


def test_bad_set_override_exit_2(good, capsys):
    assert main(["run", str(good), "--set", "duration=-1"]) == 2
    err = capsys.readouterr().err
    assert "duration" in err and "Traceback" not in err


def test_default_run_folder_under_runs(good, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(good), "--transport", "inproc", "--no-figures",
                 "--set", "duration=0.02"]) == 0
    folders = list((tmp_path / "runs").iterdir())
    assert len(folders) == 1 and folders[0].name.startswith("gain_demo-")
    assert f"run folder: runs/{folders[0].name}" in capsys.readouterr().out


def test_realtime_pacing_reports_stats(good, tmp_path):
    out = tmp_path / "rt"
    assert main(["run", str(good), "--out", str(out), "--transport", "inproc", "--no-figures",
                 "--set", "duration=0.05", "--realtime", "10"]) == 0
    realtime = json.loads((out / "manifest.json").read_text())["realtime"]
    assert realtime["factor"] == 10.0 and realtime["ticks"] == 5
    assert isinstance(realtime["deadline_misses"], int)


def test_bare_realtime_means_factor_one():
    assert normalize_realtime(["run", "x.yaml", "--realtime"]) == ["run", "x.yaml", "--realtime", "1.0"]
    assert normalize_realtime(["run", "--realtime", "--out", "d", "x.yaml"]) == [
        "run", "--realtime", "1.0", "--out", "d", "x.yaml"]
    assert normalize_realtime(["run", "--realtime", "4", "x.yaml"]) == ["run", "--realtime", "4", "x.yaml"]


def test_a_negative_foxglove_port_is_its_value_not_an_option(capsys):
    assert normalize_realtime(["run", "x.yaml", "--foxglove", "-1"]) == ["run", "x.yaml", "--foxglove", "-1"]
    assert normalize_realtime(["run", "--foxglove", "--out", "d"]) == [
        "run", "--foxglove", "8765", "--out", "d"]
    assert main(["run", "open_loop", "--foxglove", "-1"]) == 2
    assert capsys.readouterr().err.strip() == "error: --foxglove: expected a TCP port 0..65535, got -1"


def test_unknown_transport_exit_2(good, capsys):
    assert main(["run", str(good), "--transport", "carrier-pigeon"]) == 2
    assert "unknown transport 'carrier-pigeon' (--transport: choose" in capsys.readouterr().err


def test_schema_is_json(capsys):
    assert main(["schema"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert "components" in schema["properties"] and "duration" in schema["properties"]


def test_validate_foreign_fmu_name_map_and_parameter_range(tmp_path, lag_fmus, capsys):
    from tests.helpers.fmus import LAG_SCENARIO as SCENARIO

    path = tmp_path / "lag.yaml"
    path.write_text(SCENARIO.format(fmu=lag_fmus[3]))
    assert main(["validate", str(path)]) == 0
    assert "step order: plant, ref, controller" in capsys.readouterr().out
    assert main(["validate", str(path), "--set", "components.plant.parameters.gain=500"]) == 2
    err = capsys.readouterr().err
    assert "components.plant.parameters.gain" in err and "above its maximum 100" in err
    path.write_text(SCENARIO.format(fmu=lag_fmus[3]).replace("y: y_out", "y: y_output"))
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "y_output" in err and "Traceback" not in err


@pytest.mark.parametrize("factor", ["0", "1e-9", "inf", "nan"])
def test_realtime_factor_out_of_range_exit_2(good, capsys, factor):
    assert main(["run", str(good), "--transport", "inproc", "--realtime", factor]) == 2
    assert (f"--realtime factor must be a number from 0.001 (1000 times slower than real "
            f"time) up, got {float(factor)!r}") in capsys.readouterr().err
