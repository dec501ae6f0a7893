"""The Python API (cosim.run, Run, load_run, load_scenario, validate): the CLI's results, as DataFrames."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import cosim
from cosim.cli.app import main
from tests.helpers.components import GOOD, Gain  # noqa: F401  (Gain: by class path)

SHORT = {"duration": 3.0}


def test_import_cosim_loads_neither_the_api_nor_pandas():
    code = ("import sys, cosim; print(sorted(m for m in ('cosim.api', 'pandas', 'numpy', "
            "'cosim.execution') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    assert callable(cosim.run) and cosim.Run.__name__ == "Run"  # loaded on first access
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        cosim.nope  # noqa: B018


def test_run_gives_the_cli_run_folder_and_metrics_exactly(tmp_path):
    api_run = cosim.run("lane_change", set=SHORT, out=tmp_path / "api")
    assert main(["run", "lane_change", "--transport", "inproc", "--set", "duration=3.0",
                 "--out", str(tmp_path / "cli"), "--no-figures"]) == 0
    assert api_run.status == "ok" and api_run.error is None
    assert ((tmp_path / "api" / "signals.csv").read_bytes()
            == (tmp_path / "cli" / "signals.csv").read_bytes())
    cli_metrics = json.loads((tmp_path / "cli" / "metrics.json").read_text())
    assert api_run.metrics == cli_metrics
    assert {"max_abs_yc", "mu_hat_final"} <= set(api_run.metrics)


def test_signals_frame_is_the_csv_indexed_by_time_with_units(tmp_path):
    run = cosim.run("lane_change", set=SHORT, out=tmp_path / "r")
    frame = run.signals
    data = np.loadtxt(tmp_path / "r" / "signals.csv", delimiter=",", skiprows=1)
    header = (tmp_path / "r" / "signals.csv").read_text().splitlines()[0].split(",")
    assert frame.index.name == "time" and list(frame.columns) == header[1:]
    assert np.array_equal(frame.index.to_numpy(), data[:, 0])
    assert np.array_equal(frame.to_numpy(), data[:, 1:])
    units = frame.attrs["units"]
    assert set(units) == set(frame.columns)
    assert units["vehicle.vx"] == "m/s" and units["controller.delta"] == "rad"
    assert frame.attrs["descriptions"]["controller.torque"] == "total wheel torque command"
    manifest_units = {k: v["unit"] for k, v in run.manifest["signals"].items()}
    assert all(units[c] == manifest_units[c] for c in frame.columns)
    arrays = run.arrays
    assert "planner.ref_x" in arrays
    window = arrays["planner.ref_x"]
    assert window.shape[1] == 64 and window.attrs["units"]["planner.ref_x[0]"] == "m"


def test_a_dict_scenario_and_set_as_a_mapping_or_strings(tmp_path):
    import yaml

    document = yaml.safe_load(GOOD)
    run = cosim.run(document, set={"components.gain.parameters.k": 2.5}, out=tmp_path / "d")
    same = cosim.run(document, set=["components.gain.parameters.k=2.5"], out=tmp_path / "s")
    assert run.status == same.status == "ok"
    assert np.array_equal(run.signals["gain.y"], 2.5 * run.signals["ramp.value"])
    assert run.signals.equals(same.signals)
    assert document["components"]["gain"]["parameters"] == {"k": 3.0}  # not modified


def test_errors_are_the_cli_errors(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(GOOD.replace("tick: 0.01", "tick: 0.01\ncolour: red"))
    with pytest.raises(cosim.ScenarioError) as caught:
        cosim.run(bad, out=tmp_path / "x")
    assert main(["run", str(bad), "--transport", "inproc"]) == 2
    assert str(caught.value) in capsys.readouterr().err
    with pytest.raises(cosim.ScenarioError, match="shipped: .*lane_change"):
        cosim.load_scenario("no_such_scenario")
    with pytest.raises(cosim.UserError, match="unknown transport 'tcp'"):
        cosim.run("lane_change", transport="tcp")
    with pytest.raises(cosim.ScenarioError, match="<scenario>: duration: field 'duration' is required"):
        cosim.validate({"name": "x", "tick": 0.01, "components": {"a": {"fmu": "Bicycle"}}})


def test_validate_load_scenario_load_run_and_scenarios(tmp_path):
    checked = cosim.validate("lane_change")
    assert checked["order"] == ["vehicle", "planner", "controller"]
    scenario = cosim.load_scenario("lane_change", set={"duration": 5})
    assert scenario.duration == 5.0 and scenario.name == "lane_change"
    assert "lane_change" in cosim.scenarios() and "satory_nominal" in cosim.scenarios()
    run = cosim.run("open_loop", set={"duration": 1.0}, out=tmp_path / "ol")
    again = cosim.load_run(tmp_path / "ol")
    assert again.status == "ok" and again.metrics == run.metrics
    assert again.signals.equals(run.signals)
    with pytest.raises(cosim.UserError, match="not a run folder"):
        cosim.load_run(tmp_path)


def test_plot_returns_the_figure_and_can_save_it(tmp_path):
    run = cosim.run("lane_change", set=SHORT, out=tmp_path / "p")
    fig = run.plot()
    assert len(fig.axes) >= 7  # the manoeuvre layout's seven panels
    assert not (tmp_path / "p" / "figure_manoeuvre.png").exists()
    run.plot(save=True)
    assert (tmp_path / "p" / "figure_manoeuvre.png").is_file()


def test_a_failing_component_gives_a_failed_run_not_an_exception(tmp_path):
    document = {"name": "fails", "duration": 0.5, "tick": 0.01,
                "components": {"mix": {"python": "tests.helpers.components:Mixer",
                                       "parameters": {"fail_at": 0.2}}},
                "sources": {"u": {"kind": "constant", "value": 1.0}},
                "connections": [{"from": "u.value", "to": "mix.u"}]}
    run = cosim.run(document, out=tmp_path / "f")
    assert run.status == "failed"
    assert "mixer cannot divide" in run.error and "'mix'" in run.error
    assert len(run.signals) > 0 and run.signals.index[-1] < 0.2


def test_run_places_components_as_the_cli_does(tmp_path):
    placed = cosim.run("lane_change", set=SHORT, transport="zenoh", out=tmp_path / "placed",
                       place=["planner=inproc"])
    assert placed.status == "ok"
    pids = json.loads((tmp_path / "placed" / "manifest.json").read_text())["pids"]
    assert pids["planner"] == os.getpid() != pids["controller"]       # the planner ran in this process
    assert cosim.run("lane_change", set=SHORT, transport="inproc", out=tmp_path / "plain").status == "ok"
    assert (tmp_path / "placed" / "signals.csv").read_bytes() == (tmp_path / "plain" / "signals.csv").read_bytes()
    with pytest.raises(cosim.UserError, match=r"need --transport zenoh"):
        cosim.run("lane_change", set=SHORT, out=tmp_path / "refused", place=["controller=w1"])
