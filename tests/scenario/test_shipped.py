"""Shipped scenarios by name from any folder: resolution, listing, `cosim scenarios`, bare `cosim run`."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.cli.app import main
from cosim.errors import ScenarioError
from cosim.resources import scenarios_dir
from cosim.scenario.shipped import find_scenario, listing, resolve_scenario, shipped_scenarios

YAML_FILES = sorted(p.stem for p in scenarios_dir().glob("*.yaml"))


def test_every_yaml_of_the_scenarios_folder_is_shipped():
    assert list(shipped_scenarios()) == YAML_FILES
    assert "lane_change" in YAML_FILES


def test_names_resolve_from_any_folder_and_files_win(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    shipped = scenarios_dir() / "lane_change.yaml"
    assert resolve_scenario("lane_change") == shipped
    assert resolve_scenario("lane_change.yaml") == shipped
    (tmp_path / "lane_change.yaml").write_text("name: mine\n")
    assert resolve_scenario("lane_change.yaml") == Path("lane_change.yaml")  # the user's file
    assert find_scenario("sub/lane_change") == Path("sub/lane_change")  # a path is never a name


def test_unknown_name_lists_the_shipped_ones_with_a_hint(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ScenarioError) as caught:
        resolve_scenario("lane_chnage")
    text = str(caught.value)
    assert text.startswith("lane_chnage: scenario file not found, nor a shipped scenario")
    assert "did you mean 'lane_change'" in text and "satory_nominal" in text


def test_cosim_scenarios_lists_one_line_each(capsys):
    assert main(["scenarios"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == YAML_FILES
    lane = next(line for line in lines if line.startswith("lane_change "))
    assert "45 s" in lane and "two-lane road" in lane
    assert listing().splitlines() == lines


def test_bare_cosim_run_lists_the_shipped_scenarios(capsys):
    assert main(["run"]) == 0
    out = capsys.readouterr().out
    assert "usage: cosim run SCENARIO" in out
    assert all(name in out for name in YAML_FILES)


def test_run_and_validate_a_shipped_scenario_by_name(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["validate", "open_loop"]) == 0
    assert main(["run", "open_loop", "--transport", "inproc", "--set", "duration=0.5",
                 "--out", "r", "--no-figures"]) == 0
    assert (tmp_path / "r" / "signals.csv").is_file()
    assert main(["run", "nope", "--transport", "inproc"]) == 2
    assert "nope: scenario file not found, nor a shipped scenario" in capsys.readouterr().err
