"""The shipped component classes: their typed `parameters:`, checked at load time.

A Python component of a scenario names its class (`python: module:Class`) and
gives its keyword arguments as `parameters:`. For the classes shipped with
the platform (`SHIPPED_CLASSES`) those parameters have a pydantic model with
every name, type, unit, default and range: the class's `parameters_model`
(cosim.component.Component), or, for the signal sources of cosim.sources,
the fields of their `sources:` entry (cosim.scenario.sources) without
`kind`, `period` and `host`. The loader validates a known class's
parameters with its model, so a wrong one is a located problem
("FILE:LINE: components.controller.parameters.ke: ...") before anything
runs, and `cosim schema` describes them, so an editor completes them. Any
other class stays free-form here: its constructor's annotations check it
when it is constructed (cosim.transport.parameters).

The models are looked up by importing the shipped module (only for a class
named in `SHIPPED_CLASSES`, never a user's module).
"""

from __future__ import annotations

import functools
import importlib
import re
from typing import Any

from pydantic import BaseModel, ValidationError, create_model

from cosim.errors import did_you_mean
from cosim.scenario.sources import SOURCE_CLASSES, SOURCE_MODELS, STRICT

#: "module:Class" of every shipped component class with a parameter model
SHIPPED_CLASSES: tuple[str, ...] = (
    "controllers.backstepping:BacksteppingController",
    "controllers.planning:Planner",
    "controllers.baselines:PurePursuitController",
    "controllers.baselines:StanleyController",
    "controllers.baselines:SpeedLoop",
    *SOURCE_CLASSES.values(),
)
#: the fields of a source entry that are not its class's keyword arguments
SOURCE_PLACEMENT = ("kind", "period", "host")

Loc = tuple[str | int, ...]
_PYDANTIC_TAG = re.compile(r"[^A-Za-z0-9_]|^(float|int|bool|str|list|dict|none)$")


@functools.cache
def parameters_model(class_path: str) -> type[BaseModel] | None:
    """The parameter model of a shipped class ("module:Class"); None for any other class."""
    if class_path not in SHIPPED_CLASSES:
        return None
    for kind, source_class in SOURCE_CLASSES.items():
        if source_class == class_path:
            return _source_parameters(kind)
    module, _, name = class_path.partition(":")
    return getattr(importlib.import_module(module), name).parameters_model


def _source_parameters(kind: str) -> type[BaseModel]:
    """The keyword arguments of a source class, from the fields of its `sources:` entry."""
    spec = SOURCE_MODELS[kind]
    fields: Any = {name: (field.annotation, field) for name, field in spec.model_fields.items()
                   if name not in SOURCE_PLACEMENT}
    name = spec.__name__.removesuffix("Source") + "SourceParameters"
    return create_model(name, __config__=STRICT, __doc__=f"Parameters of {SOURCE_CLASSES[kind]}"
                        f" (the fields of a `{kind}` source).", **fields)


def parameter_problems(loc: Loc, spec: dict) -> list[tuple[Loc, str]]:
    """The problems of a raw component entry's `parameters:` when its class is a shipped one.

    Args:
        loc: the component's document path, ("components", name).
        spec: the component's raw mapping (python, parameters, ...).
    Returns:
        (document path, message) pairs, one per wrong parameter; [] for an
        unknown class or parameters that are not a mapping (the schema says so).
    """
    class_path, parameters = spec.get("python"), spec.get("parameters", {})
    model = parameters_model(class_path) if isinstance(class_path, str) else None
    if model is None or not isinstance(parameters, dict):
        return []
    try:
        model.model_validate(parameters)
    except ValidationError as exc:
        return _problems(loc + ("parameters",), class_path, model, exc.errors())
    return []


def _problems(loc: Loc, class_path: str, model: type[BaseModel],
              errors: list[Any]) -> list[tuple[Loc, str]]:
    """One problem per value: of a union's alternatives, the deepest error, else all of them."""
    by_value: dict[Loc, list[Any]] = {}
    for error in errors:
        tags = [i for i, key in enumerate(error["loc"]) if _is_tag(key)]
        by_value.setdefault(error["loc"][:tags[0]] if tags else error["loc"], []).append(error)
    problems = []
    for group in by_value.values():
        deepest = max(len(error["loc"]) for error in group)
        chosen = [error for error in group if len(error["loc"]) == deepest]
        path = tuple(key for key in chosen[0]["loc"] if not _is_tag(key))
        problems.append((loc + path, _message(chosen, class_path, model)))
    return problems


def _is_tag(key: str | int) -> bool:
    """True for the union alternative pydantic puts in an error's location ("list[int]")."""
    return isinstance(key, str) and _PYDANTIC_TAG.search(key) is not None


def _message(errors: list[Any], class_path: str, model: type[BaseModel]) -> str:
    """The text of a value's problem, in the words of the constructor-time check
    (cosim.transport.parameters): "expected a number > 0, got -1"."""
    first = errors[0]
    key = first["loc"][-1] if first["loc"] else ""
    if first["type"] == "extra_forbidden":
        if len(first["loc"]) > 1:
            return f"unknown field {key!r}"
        known = list(model.model_fields)
        if not known:
            return f"unknown parameter {key!r}: {class_path} takes no parameters"
        return (f"unknown parameter {key!r}{did_you_mean(str(key), known)}; "
                f"known: {', '.join(known)}")
    if first["type"] == "missing":
        return f"parameter {key!r} of {class_path} is required"
    wanted = " or ".join(dict.fromkeys(_wanted(error) for error in errors))
    return f"expected {wanted}, got {_shown(first['input'])}"


_WORDS = {"float_type": "a number", "finite_number": "a finite number", "int_type": "an integer",
          "int_from_float": "an integer", "bool_type": "true or false", "string_type": "a string",
          "list_type": "a list", "dict_type": "a mapping", "model_type": "a mapping"}
_BOUNDS = {"greater_than": ("gt", ">"), "greater_than_equal": ("ge", ">="),
           "less_than": ("lt", "<"), "less_than_equal": ("le", "<=")}


def _wanted(error: Any) -> str:
    """What a pydantic error says the value should be, in words."""
    kind, ctx = error["type"], error.get("ctx", {})
    if kind in _BOUNDS:
        name, sign = _BOUNDS[kind]
        return f"a number {sign} {ctx[name]:g}"
    if kind == "literal_error":
        return f"one of {ctx['expected']}"
    return _WORDS.get(kind, error["msg"][:1].lower() + error["msg"][1:])


def _shown(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def describe_parameters(schema: dict[str, Any]) -> None:
    """Add each shipped class's parameter model to a scenario JSON schema (in place).

    The model goes into `$defs`; the Python component's definition gets one
    if/then per class (`python` equal to the class: `parameters` follows its
    model) and the class names as `examples` of `python`, for completion.
    """
    defs = schema.setdefault("$defs", {})
    rules = []
    for class_path in SHIPPED_CLASSES:
        model = parameters_model(class_path)
        assert model is not None, class_path
        model_schema = model.model_json_schema(ref_template="#/$defs/{model}")
        for name, definition in {**model_schema.pop("$defs", {}),
                                 model.__name__: model_schema}.items():
            if defs.get(name, definition) != definition:
                raise ValueError(f"schema definition {name!r} defined twice, differently")
            defs[name] = definition
        rules.append({"if": {"properties": {"python": {"const": class_path}},
                             "required": ["python"]},
                      "then": {"properties": {"parameters": {
                          "$ref": f"#/$defs/{model.__name__}",
                          "description": f"keyword arguments of {class_path}"}}}})
    python_spec = defs["PythonSpec"]
    python_spec["allOf"] = rules
    python_spec["properties"]["python"]["examples"] = list(SHIPPED_CLASSES)
