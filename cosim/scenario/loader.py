"""Scenario files: loading, command-line overrides, validation with line numbers.

A scenario YAML names the run (`name`, `duration`, `tick`), its components
(FMUs and Python classes), signal sources, connections and what to record;
the models are in `cosim.scenario.models` and `cosim.scenario.sources` and are
re-exported here. `load_scenario` reports every problem of a file at once, each
as "FILE:LINE: PATH: MESSAGE", in one `ScenarioError`.

The format, by example (every mapping forbids unknown fields):

    name: lane_change                  # required; description: optional
    duration: 20.0                     # s, a whole number of ticks
    tick: 0.01                         # s, the master's base step; start_time: 0.0
    components:                        # names are identifiers
      vehicle:
        fmu: Vehicle8DOF               # built-in name, or a .fmu path relative to this file
        parameters: {vx0: 10.0}
        uncertainty: {m: {scale: 1.3}} # plant only: value * scale + offset
        variables: {delta: steerAngle} # foreign FMU: canonical name -> FMU variable
      controller:
        python: controllers.backstepping:BacksteppingController
        period: 0.01                   # s, a whole multiple of tick (default: every tick)
        parameters: {ls: 5.0}
    sources:                           # each a component with one output `value`
      side_wind: {kind: gust, amplitude: 500, start: 2, duration: 1, unit: N}
      mu_road: {kind: table, over: distance, points: [[0, 1.0], [50, 0.5]]}
    connections:
      - vehicle -> controller          # every output feeding the input of the same name
      - controller.delta -> vehicle.delta
      - {from: side_wind.value, to: vehicle.wind_fy, delay: 1}
    record: {include: ["*"], exclude: []}
    # system: plant.ssp               # an SSP's FMU components and connections, merged in first
    # connection options: {from: a.x, to: b.u, scale: 1.3, offset: 50}  -> b.u = 1.3 * a.x + 50

A path ending in .ssp or .ssd loads as the scenario of that SSP package
(`cosim.scenario.ssp`).

Example:
    scenario = load_scenario("scenarios/lane_change.yaml",
                             ["components.controller.parameters.ke=2.0", "duration=5"])
    scenario.total_ticks, scenario.period_ticks("planner")
"""

from __future__ import annotations

import copy
import functools
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from cosim.errors import Problem, ScenarioError, did_you_mean
from cosim.scenario.checks import BUILTIN_FMUS, IDENTIFIER, semantic_problems, whole_ticks
from cosim.scenario.models import (ComponentSpec, Connection, FmuSpec, PythonSpec,
                                   RecordSpec, Scenario, Uncertainty)
from cosim.scenario.schema import json_schema
from cosim.scenario.systems import is_ssp, merge_system, ssp_scenario
from cosim.scenario.sources import (SOURCE_CLASSES, SOURCE_KIND_ERROR, SOURCE_MODELS,
                                    ConstantSource, GustSource, RampSource, SourceSpec,
                                    StepSource, TableSource)
from cosim.scenario.yaml_lines import (LineMap, YamlLimitError, format_path, load_yaml,
                                       parse_scalar, read_yaml_file)

__all__ = [
    "BUILTIN_FMUS", "IDENTIFIER", "ComponentSpec", "Connection", "ConstantSource", "FmuSpec",
    "GustSource", "PythonSpec", "RampSource", "RecordSpec", "SOURCE_CLASSES", "Scenario",
    "SourceSpec", "StepSource", "TableSource", "Uncertainty", "apply_overrides",
    "json_schema", "load_scenario", "scenario_from_dict", "whole_ticks",
]


def load_scenario(path: str | Path, overrides: Sequence[str] = ()) -> Scenario:
    """Read, override and validate a scenario file.

    Args:
        path: the scenario YAML file.
        overrides: "dotted.path=value" strings (value parsed as YAML) applied to
            the document before validation, e.g. "components.controller.period=0.02".
    Returns:
        the validated Scenario, which remembers its file and line numbers.
    Raises:
        ScenarioError: listing every problem found (file, line, path, message).
    """
    file = Path(path)
    if is_ssp(file):  # an SSP package runs as it stands (cosim.scenario.systems)
        document, ssd_lines = ssp_scenario(file)
        return _validate(document, file, ssd_lines, apply_overrides(document, overrides, ssd_lines))
    try:
        text = read_yaml_file(file)
    except FileNotFoundError:
        raise ScenarioError(file, [Problem("", None, "scenario file not found")]) from None
    except YamlLimitError as exc:
        raise ScenarioError(file, [Problem("", exc.line, exc.problem)]) from None
    data, lines, problems = _loaded_yaml(text)
    if problems and data is None:
        raise ScenarioError(file, problems)
    if data is None:
        data = {}
    if isinstance(data, dict) and data.get("system") is not None:
        problems += merge_system(data, file.parent, lines)
    problems += apply_overrides(data, overrides, lines)
    if not isinstance(data, dict):
        problems.append(Problem("", 1, "a scenario must be a mapping of fields "
                                       "(name, duration, tick, components, ...)"))
        raise ScenarioError(file, problems)
    return _validate(data, file, lines, problems)


# the YAML documents loaded in this process, by their text: the samples of a sweep load
# one file again and again (composing it with lines is most of a load, ~2 ms), and each
# load gets its own copy, which its overrides then change
YAML_KEPT = 8
_kept_yaml = functools.lru_cache(maxsize=YAML_KEPT)(load_yaml)


def _loaded_yaml(text: str) -> tuple[Any, LineMap, list[Problem]]:
    """`load_yaml(text)`, as a fresh copy of the document loaded before from the same text."""
    return copy.deepcopy(_kept_yaml(text))


def scenario_from_dict(document: dict, overrides: Sequence[str] = ()) -> Scenario:
    """Validate a scenario given as a mapping (as its YAML would load), overrides applied.

    The checks and messages are those of `load_scenario`, without line numbers;
    relative paths resolve against the working directory. The mapping is not modified.

    Args:
        document: the scenario fields (name, duration, tick, components, ...).
        overrides: "dotted.path=value" strings, as for `load_scenario`.
    Raises:
        ScenarioError: listing every problem found (file shown as "<scenario>").
    """
    data = copy.deepcopy(document)
    lines = LineMap()
    problems = []
    if isinstance(data, dict) and data.get("system") is not None:
        problems += merge_system(data, Path.cwd(), lines)
    problems += apply_overrides(data, overrides, lines)
    if not isinstance(data, dict):
        raise ScenarioError(None, [Problem("", None, "a scenario must be a mapping of fields "
                                                     "(name, duration, tick, components, ...)")])
    return _validate(data, None, lines, problems)


def _validate(data: dict, file: Path | None, lines: LineMap,
              problems: list[Problem]) -> Scenario:
    """Validate a document, gathering schema and cross-field problems in one error."""
    scenario: Scenario | None = None
    try:
        scenario = Scenario.model_validate(data, context={"deferred_checks": True})
    except ValidationError as exc:
        unreadable = {p.path for p in problems}  # a value YAML could not build is None now
        problems += [p for p in (_problem_of(err, lines) for err in exc.errors())
                     if p.path not in unreadable]
    seen = {p.path for p in problems}
    base_dir = file.parent if file is not None else Path.cwd()
    for loc, message in semantic_problems(data, base_dir, lines.also_set):
        problem = _located(loc, message, lines)
        if problem.path not in seen:
            problems.append(problem)
    if problems or scenario is None:
        problems.sort(key=lambda p: (p.line is None, p.line or 0))
        raise ScenarioError(file, problems)
    scenario._file = file
    scenario._lines = lines
    return scenario


def _located(loc: Sequence[str | int], message: str, lines: LineMap) -> Problem:
    """A Problem at a document path, noting a --set override that put the value there."""
    override = lines.override_of(loc)
    if override is not None:
        message += f" (set by --set {override})"
    return Problem(format_path(loc), lines.line_of(loc), message)


#: the discriminator tags pydantic puts in an error's location (not keys of the document)
UNION_TAGS = frozenset({"<fmu>", "<python>", *(f"<{kind}>" for kind in SOURCE_MODELS)})

PATTERN_HINTS = {
    "python": "'package.module:Class'",
    "from": "'component' or 'component.port'",
    "to": "'component' or 'component.port'",
}


def _problem_of(error: Any, lines: LineMap) -> Problem:
    """Turn one pydantic error into a located Problem that shows the offending value."""
    raw_loc = tuple(error["loc"])
    loc = tuple(k for k in raw_loc if k not in UNION_TAGS and k != "[key]")
    value = error.get("input")
    message = error["msg"].removeprefix("Value error, ")
    if error["type"] == "missing":
        message = f"field {loc[-1]!r} is required" if loc else "a field is required"
    elif error["type"] == "extra_forbidden" and loc:
        message = f"unknown field {loc[-1]!r}" + (_other_kind_hint(raw_loc)
                                                  or _suggestion(loc))
    elif error["type"] == SOURCE_KIND_ERROR and isinstance(value, dict):
        message += f" (got {value.get('kind')!r})"
    elif error["type"] == "string_pattern_mismatch" and loc and loc[-1] in PATTERN_HINTS:
        message = f"{loc[-1]} must read {PATTERN_HINTS[loc[-1]]} (got {value!r})"
    elif (value is not None and not isinstance(value, (dict, list, tuple))
          and repr(value) not in message):
        message += f" (got {value!r})"
    return _located(loc, message, lines)


def _field_names() -> set[str]:
    """Every field name of every model of the schema (for spelling suggestions)."""
    models = [Scenario, FmuSpec, PythonSpec, Uncertainty, RecordSpec, Connection,
              ConstantSource, StepSource, RampSource, GustSource, TableSource]
    names = {"from", "to"}
    for model in models:
        names.update(model.model_fields)
    return names


def _suggestion(loc: tuple[str | int, ...]) -> str:
    """' (did you mean ...?)' for a misspelt field name (never the name itself)."""
    if not loc or not isinstance(loc[-1], str):
        return ""
    if loc[0] == "connections":  # a connection's fields are few: suggest only those
        return did_you_mean(loc[-1], ["from", "to", *Connection.model_fields])
    return did_you_mean(loc[-1], sorted(_field_names() - {loc[-1]}))


def _other_kind_hint(raw_loc: tuple[Any, ...]) -> str:
    """For a source field that belongs to another kind: which kinds take it, and this kind's fields.

    A gust's `amplitude` written under `kind: step` is not a spelling mistake, so a
    "did you mean" would mislead; "" when `raw_loc` is not inside a source of a known kind.
    """
    tags = [k for k in raw_loc[:-1] if k in UNION_TAGS]
    kind = tags[-1][1:-1] if tags else None
    name = raw_loc[-1] if raw_loc else None
    if kind not in SOURCE_MODELS or not isinstance(name, str):
        return ""
    owners = [k for k, model in SOURCE_MODELS.items() if name in model.model_fields]
    if not owners:
        return ""
    own = ", ".join(f for f in SOURCE_MODELS[kind].model_fields if f != "kind")
    return (f" for kind {kind!r}, whose fields are: {own}"
            f" ({name!r} belongs to kind {', '.join(owners)})")


def apply_overrides(data: Any, overrides: Sequence[str], lines: LineMap) -> list[Problem]:
    """Apply "a.b.c=value" overrides to a loaded document, in order.

    Intermediate mappings are created when missing; list items are addressed
    by their index, "connections.0.delay=1" or, as error messages print the path,
    "connections[0].delay=1". Values are parsed as YAML.

    Args:
        data: the document (modified in place).
        overrides: the override strings.
        lines: the document's line map; overridden paths are marked in it.
    Returns:
        problems with overrides that cannot be applied (path "--set").
    """
    problems: list[Problem] = []
    for text in overrides:
        error = _apply_one(data, text, lines)
        if error:
            problems.append(Problem("--set", None, f"{text!r}: {error}"))
    return problems


#: one dotted part of an override's path: a key, then list indices ("connections[1]")
_KEY_PART = re.compile(r"^([^\[\]]*)((?:\[\s*\d+\s*\])*)$")


def _path_keys(dotted: str) -> list[tuple[str, bool]] | None:
    """The keys of an override's path, each with whether it was written as an index in
    brackets: "connections[1].delay" and "connections.1.delay" are both connections, 1,
    delay (the first as an error message prints it). None when a part is empty.
    """
    keys: list[tuple[str, bool]] = []
    for part in dotted.split("."):
        match = _KEY_PART.match(part.strip())
        if match is None:  # brackets that are no index ("a[b]"): a key as written
            keys.append((part.strip(), False))
            continue
        name, indices = match.group(1).strip(), re.findall(r"\d+", match.group(2))
        if not name and not (indices and keys):
            return None
        keys += [(name, False)] if name else []
        keys += [(index, True) for index in indices]
    return keys


def _apply_one(data: Any, text: str, lines: LineMap) -> str | None:
    """Apply one override; return what is wrong with it, or None."""
    dotted, sep, raw = text.partition("=")
    keys = _path_keys(dotted)
    if not sep or not keys:
        return "an override reads PATH=VALUE, e.g. components.controller.parameters.ke=2.0"
    try:
        value = parse_scalar(raw)
    except YamlLimitError as exc:  # valid YAML that cannot become a value (a tag, a date)
        return f"value {raw!r} cannot be read: {exc.problem}"
    except yaml.YAMLError as exc:
        reason = getattr(exc, "problem", None) or type(exc).__name__
        mark = getattr(exc, "problem_mark", None)
        where = f" at column {mark.column + 1}" if mark is not None else ""
        return f"value {raw!r} is not valid YAML: {reason}{where}"
    node, loc = data, []
    created: tuple[str | int, ...] | None = None
    note = ""  # a misspelt key that the override created, with the close existing one
    for depth, (key, bracketed) in enumerate(keys):
        last = depth == len(keys) - 1
        if isinstance(node, list):
            if not key.isdigit() or int(key) >= len(node):
                return f"{format_path(loc)} is a list of {len(node)} items; {key!r} is no index"
            index: str | int = int(key)
        elif isinstance(node, dict) and bracketed:
            return (f"{format_path(loc) or 'the document'} is a mapping, not a list, "
                    f"so [{key}] is no index")
        elif isinstance(node, dict):
            index = key
            if not last and key not in node:
                hint = did_you_mean(key, [k for k in node if isinstance(k, str)])
                note = note or (f"; it made a new {key!r}{hint}" if hint else "")
                node[key] = {}
                created = created or tuple(loc) + (key,)
        else:
            return f"{format_path(loc) or 'the document'} is a value, not a mapping or list"
        loc.append(index)
        if last:
            node[index] = value
        else:
            node = node[index]
    lines.detached[created or tuple(loc)] = text + note
    return None
