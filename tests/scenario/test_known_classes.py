"""The parameter models of the shipped component classes: one source with the constructors
(same names, same defaults, ranges the constructors enforce too), and the load-time check
of a scenario's `parameters:` with file:line, component, parameter and value."""

from __future__ import annotations

import importlib
import inspect
from pathlib import Path
from typing import Any

import annotated_types
import pytest
from pydantic_core import PydanticUndefined

from cosim.component import ComponentError
from cosim.errors import ScenarioError
from cosim.scenario.known_classes import SHIPPED_CLASSES, parameters_model
from cosim.scenario.loader import load_scenario, scenario_from_dict

REQUIRED = "<required>"
#: the least a source class needs to be constructed (its required arguments)
MINIMAL = {"cosim.sources:Constant": {"value": 1.0},
           "cosim.sources:Step": {"initial": 0.0, "final": 1.0, "at": 1.0},
           "cosim.sources:Ramp": {"start": 0.0, "end": 1.0, "t_start": 0.0, "t_end": 1.0},
           "cosim.sources:Gust": {"amplitude": 1.0, "start": 0.0, "duration": 1.0},
           "cosim.sources:Table": {"points": [[0.0, 1.0]]}}


def _class(class_path: str) -> type:
    module, _, name = class_path.partition(":")
    return getattr(importlib.import_module(module), name)


def _constructor_defaults(cls: type) -> dict[str, Any]:
    keywords = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    return {p.name: REQUIRED if p.default is inspect.Parameter.empty else p.default
            for p in inspect.signature(cls).parameters.values() if p.kind in keywords}


@pytest.mark.parametrize("class_path", SHIPPED_CLASSES)
def test_model_has_the_constructors_names_and_defaults(class_path):
    model = parameters_model(class_path)
    fields = {name: REQUIRED if field.default is PydanticUndefined else field.default
              for name, field in model.model_fields.items()}
    assert fields == _constructor_defaults(_class(class_path))
    assert model.model_config["extra"] == "forbid"
    assert all(field.description for field in model.model_fields.values())


def _outside(bound: Any) -> float | None:
    """A value just outside a field's bound (the bound itself when exclusive)."""
    if isinstance(bound, annotated_types.Gt):
        return bound.gt
    if isinstance(bound, annotated_types.Ge):
        return bound.ge - 1.0
    if isinstance(bound, annotated_types.Lt):
        return bound.lt
    if isinstance(bound, annotated_types.Le):
        return bound.le + 1.0
    return None


def _bounded_values(class_path: str) -> list[tuple[str, float]]:
    model = parameters_model(class_path)
    return [(name, _outside(bound)) for name, field in model.model_fields.items()
            for bound in field.metadata if _outside(bound) is not None]


@pytest.mark.parametrize("class_path", SHIPPED_CLASSES)
def test_constructor_refuses_what_the_model_refuses(class_path):
    """The model's ranges are the constructor's own checks: no range only one of them has."""
    cls, base = _class(class_path), MINIMAL.get(class_path, {})
    cls(**base)  # the defaults construct
    bounded = _bounded_values(class_path)
    assert bounded or class_path in MINIMAL  # every controller has ranges
    for name, value in bounded:
        with pytest.raises(ComponentError):
            cls(**{**base, name: value})
        with pytest.raises(ValueError):
            parameters_model(class_path).model_validate({**base, name: value})


def test_unknown_classes_have_no_model():
    assert parameters_model("my_pkg.laws:MyController") is None
    assert parameters_model("tests.helpers.components:Gain") is None  # not imported either


SCENARIO = """\
name: params
duration: 1.0
tick: 0.01
components:
  controller:
    python: controllers.backstepping:BacksteppingController
    parameters:
      ke: [1.0, -2.0]
      adaptation: fast
  planner:
    python: controllers.planning:Planner
    parameters: {speed: {v_max: 5, a_max: true}, lane: 1}
  user:
    python: my_pkg.laws:MyController
    parameters: {anything: [1, "x"]}
"""


def test_every_wrong_parameter_is_one_located_line(tmp_path: Path):
    path = tmp_path / "s.yaml"
    path.write_text(SCENARIO + "  extra_field: 1\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert str(info.value).splitlines() == [
        f"{path}:8: components.controller.parameters.ke[1]: expected a number > 0, got -2.0",
        f"{path}:9: components.controller.parameters.adaptation: expected one of 'paper' or "
        "'robust', got 'fast'",
        f"{path}:12: components.planner.parameters.speed.a_max: expected a number, got True",
        f"{path}:16: components.extra_field: a component needs exactly one of 'fmu:' (built-in "
        "name or path to a .fmu) or 'python:' (module:Class) (got 1)",
    ]


def test_an_override_of_a_parameter_is_named(tmp_path: Path):
    path = tmp_path / "s.yaml"
    path.write_text(SCENARIO)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, ["components.controller.parameters.ke=1", "components.controller."
                             "parameters.adaptation=robust", "components.planner.parameters."
                             "speed.a_max=1", "components.planner.parameters.laps=0"])
    assert str(info.value) == (
        f"{path}: components.planner.parameters.laps: expected a number >= 1, got 0 "
        "(set by --set components.planner.parameters.laps=0)")


def test_a_scenario_built_in_memory_is_checked_too():
    document = {"name": "m", "duration": 1.0, "tick": 0.1, "components": {
        "c": {"python": "controllers.baselines:StanleyController",
              "parameters": {"k_stanly": 1.0}}}}
    with pytest.raises(ScenarioError, match=r"components.c.parameters.k_stanly: unknown "
                                            r"parameter 'k_stanly' \(did you mean 'k_stanley'\?\)"):
        scenario_from_dict(document)
    document["components"]["c"]["parameters"] = {"k_stanley": 2}  # an integer is a number
    assert scenario_from_dict(document).components["c"].parameters == {"k_stanley": 2}
