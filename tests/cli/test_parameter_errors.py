"""A component's constructor that rejects a scenario parameter: the message
starts with the parameter's YAML file and line, the same in-process, over
Zenoh and in `cosim validate`; an FMU's unknown parameter lists the valid ones.
A shipped class's parameters are refused earlier, at load time, by its
parameter model (cosim.scenario.known_classes), with the same file:line start."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cosim.cli.app import main

# a user's class (not shipped): its parameters are checked when it is constructed
USER_CLASS = """\
name: params
duration: 0.1
tick: 0.01
components:
  controller:
    python: tests.helpers.components:{cls}
    parameters:
      {good}
      {bad}
"""
CONTROLLER = """\
name: params
duration: 0.1
tick: 0.01
components:
  controller:
    python: controllers.backstepping:BacksteppingController
    parameters:
      kx: 1.0
      {bad}
"""


def _scenario(tmp_path: Path, bad: str, cls: str = "Gain", good: str = "k: 1.0") -> Path:
    path = tmp_path / "params.yaml"
    path.write_text(USER_CLASS.format(cls=cls, good=good, bad=bad))
    return path


def _known_parameters() -> str:
    import inspect

    from tests.helpers.components import Gain

    return ", ".join(inspect.signature(Gain).parameters)


@pytest.mark.parametrize("command", [["run", "--transport", "inproc"],
                                     ["run", "--transport", "zenoh"], ["validate"]])
def test_unknown_parameter_names_its_line_and_the_known_ones(tmp_path, capsys, command):
    path = _scenario(tmp_path, "kk: 2.0")
    out = tmp_path / "run"
    extra = ["--out", str(out), "--no-figures"] if command[0] == "run" else []
    assert main([command[0], str(path), *command[1:], *extra]) == 2
    err = capsys.readouterr().err
    expected = (f"{path}:9: components.controller.parameters.kk: unknown parameter 'kk' "
                f"(did you mean 'k'?); known: {_known_parameters()}")
    assert err == f"error: {expected}\n"
    if command[0] == "run":  # the announced folder records the same error
        manifest = json.loads((out / "manifest.json").read_text())
        assert (manifest["status"], manifest["error"]) == ("failed", expected)


@pytest.mark.parametrize("transport", ["inproc", "zenoh"])
def test_constructor_error_on_a_parameter_names_its_line(tmp_path, capsys, transport):
    path = _scenario(tmp_path, "", cls="BadParameter", good="mass: -2.0")
    assert main(["run", str(path), "--transport", transport, "--out", str(tmp_path / "r"),
                 "--no-figures"]) == 2
    assert capsys.readouterr().err == (
        f"error: {path}:8: components.controller.parameters.mass: mass must be positive, "
        "got -2.0\n")


@pytest.mark.parametrize("command", [["run", "--transport", "inproc"], ["validate"]])
def test_shipped_class_parameter_is_refused_at_load_with_its_line(tmp_path, capsys, command):
    path = tmp_path / "params.yaml"
    path.write_text(CONTROLLER.format(bad="ke: .nan"))
    extra = ["--out", str(tmp_path / "r"), "--no-figures"] if command[0] == "run" else []
    assert main([command[0], str(path), *command[1:], *extra]) == 2
    assert capsys.readouterr().err == (
        f"error: {path}:9: components.controller.parameters.ke: expected a finite number "
        "or a list, got nan\n")


def test_constructor_error_not_about_a_parameter_keeps_the_component(tmp_path, capsys):
    path = tmp_path / "params.yaml"  # the model checks each field, the constructor their order
    path.write_text(CONTROLLER.format(bad="mu_min: 5.0"))  # message starts with "need"
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: component 'controller': need 0 < mu_min <= mu0 <= mu_max")
