"""One import path for every way of running: the scenario file's folder, then the working directory.

A controller in the user's own module (not installed, not on PYTHONPATH) imports the
same way in `cosim validate`, `--transport inproc`, `--transport zenoh` and `cosim sweep`,
whether it sits beside the scenario file or in the working directory.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from cosim.cli.app import main
from cosim.scenario.imports import add_import_roots, import_roots, pythonpath

MODULE = '''\
from cosim.component import Component, Port


class Doubler(Component):
    inputs = (Port("x"),)
    outputs = (Port("y", unit="m", description="twice x"),)

    def __init__(self, offset: float = 0.0):
        self.offset = float(offset)

    def step(self, t, inputs):
        return {{"y": 2.0 * inputs["x"] + self.offset + {tag}}}
'''

SCENARIO = """\
name: user_module
duration: 0.2
tick: 0.01
components:
  doubler: {{python: {module}:Doubler, parameters: {{offset: 0.5}}}}
sources:
  ramp: {{kind: ramp, start: 0.0, end: 1.0, t_start: 0.0, t_end: 0.2}}
connections:
  - {{from: ramp.value, to: doubler.x}}
"""


def _layout(tmp_path: Path, where: str, module: str) -> tuple[Path, Path]:
    """A scenario in tmp/scenarios/ whose module is beside it or in tmp/work/ (the cwd)."""
    scenario_dir, work = tmp_path / "scenarios", tmp_path / "work"
    scenario_dir.mkdir()
    work.mkdir()
    home = scenario_dir if where == "scenario" else work
    (home / f"{module}.py").write_text(MODULE.format(tag=1.0 if where == "scenario" else 2.0))
    scenario = scenario_dir / "s.yaml"
    scenario.write_text(SCENARIO.format(module=module))
    return scenario, work


@pytest.fixture
def clean_path(monkeypatch):
    """Restore sys.path and sys.modules (the user modules) after the test."""
    monkeypatch.setattr(sys, "path", list(sys.path))
    before = set(sys.modules)
    yield
    for name in set(sys.modules) - before:
        if name.startswith("usermod_"):
            del sys.modules[name]


def test_import_roots_are_the_scenario_folder_then_the_cwd(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    scenario = tmp_path / "sub" / "s.yaml"
    assert import_roots(scenario) == (str(tmp_path / "sub"), str(tmp_path))
    assert import_roots(tmp_path / "s.yaml") == (str(tmp_path),)  # the same folder once
    assert import_roots(None) == (str(tmp_path),)
    assert pythonpath(["a", "b"], "c") == os.pathsep.join(["a", "b", "c"])
    assert pythonpath(["a"], None) == "a"


def test_add_import_roots_puts_them_first_once(monkeypatch):
    monkeypatch.setattr(sys, "path", ["/x", "/site"])
    add_import_roots(["/a", "/x", "/b"])
    assert sys.path == ["/a", "/b", "/x", "/site"]


@pytest.mark.parametrize("where", ["scenario", "cwd"])
def test_validate_and_inproc_import_a_user_module(tmp_path, monkeypatch, capsys, clean_path, where):
    module = f"usermod_{where}_inproc"
    scenario, work = _layout(tmp_path, where, module)
    monkeypatch.chdir(work)
    assert main(["validate", str(scenario)]) == 0, capsys.readouterr().err
    out = tmp_path / "run"
    assert main(["run", str(scenario), "--transport", "inproc", "--out", str(out),
                 "--no-figures"]) == 0, capsys.readouterr().err
    last = (out / "signals.csv").read_text().splitlines()[-1].split(",")
    header = (out / "signals.csv").read_text().splitlines()[0].split(",")
    y = float(last[header.index("doubler.y")])
    x = float(last[header.index("ramp.value")])
    assert y == 2.0 * x + 0.5 + (1.0 if where == "scenario" else 2.0)  # that module, not another


@pytest.mark.integration
@pytest.mark.parametrize("where", ["scenario", "cwd"])
def test_zenoh_processes_import_a_user_module_bit_identical_to_inproc(tmp_path, monkeypatch,
                                                                      capsys, clean_path, where):
    module = f"usermod_{where}_zenoh"
    scenario, work = _layout(tmp_path, where, module)
    monkeypatch.chdir(work)
    monkeypatch.delenv("PYTHONPATH", raising=False)
    for transport in ("inproc", "zenoh"):
        code = main(["run", str(scenario), "--transport", transport,
                     "--out", str(tmp_path / transport), "--no-figures"])
        assert code == 0, capsys.readouterr().err
    assert ((tmp_path / "zenoh" / "signals.csv").read_bytes()
            == (tmp_path / "inproc" / "signals.csv").read_bytes())


@pytest.mark.integration
def test_sweep_imports_a_user_module_beside_the_scenario(tmp_path, monkeypatch, clean_path):
    from cosim.execution.sweep import run_sweep

    scenario, work = _layout(tmp_path, "scenario", "usermod_sweep")
    monkeypatch.chdir(work)
    monkeypatch.delenv("PYTHONPATH", raising=False)
    result = run_sweep(scenario, ["components.doubler.parameters.offset=0:1"], 2,
                       out_dir=tmp_path / "sweep")
    assert [s.status for s in result.samples] == ["ok", "ok"], [s.error for s in result.samples]
