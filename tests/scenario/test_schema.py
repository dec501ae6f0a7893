"""The scenario JSON schema for editors: draft 2020-12 with an id, a description on every
property, the shipped classes' parameters typed, every shipped scenario valid and pointing
at the committed schema file, which is what `cosim schema` generates."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import pytest

from cosim.cli.app import main
from cosim.scenario.known_classes import SHIPPED_CLASSES
from cosim.scenario.schema import DRAFT, SCHEMA_FILE_NAME, SCHEMA_ID, json_schema, schema_text
from cosim.scenario.shipped import shipped_scenarios
from cosim.scenario.yaml_lines import load_yaml

jsonschema = pytest.importorskip("jsonschema")

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
MODELINE = f"# yaml-language-server: $schema={SCHEMA_FILE_NAME}"


@pytest.fixture(scope="module")
def schema() -> dict[str, Any]:
    return json_schema()


@pytest.fixture(scope="module")
def validator(schema):
    return jsonschema.Draft202012Validator(schema)


def _document(name: str) -> dict[str, Any]:
    """A shipped scenario as the loader reads it (cosim's YAML: 1e-3 is a float)."""
    data, _, problems = load_yaml(shipped_scenarios()[name].read_text(encoding="utf-8"))
    assert not problems
    return data


def _errors(validator, document) -> list[tuple[str, str]]:
    """(path, message) of each error, a union's alternatives followed down to their leaves."""
    def leaves(error):
        if not error.context:
            return [error]
        return [leaf for sub in error.context for leaf in leaves(sub)]
    return [("/".join(map(str, leaf.absolute_path)), leaf.message)
            for error in validator.iter_errors(document) for leaf in leaves(error)]


def test_schema_is_draft_2020_12_with_a_fixed_id(schema):
    assert (schema["$schema"], schema["$id"]) == (DRAFT, SCHEMA_ID)
    jsonschema.Draft202012Validator.check_schema(schema)


def test_committed_schema_file_is_what_cosim_schema_generates(tmp_path, capsys):
    committed = (SCENARIOS / SCHEMA_FILE_NAME).read_text(encoding="utf-8")
    assert committed == schema_text(), (
        "scenarios/scenario.schema.json is stale: run `cosim schema --out "
        "scenarios/scenario.schema.json` and commit it")
    out = tmp_path / "s.json"
    assert main(["schema", "--out", str(out)]) == 0
    assert out.read_text(encoding="utf-8") == committed
    capsys.readouterr()
    assert main(["schema"]) == 0
    assert capsys.readouterr().out == committed


@pytest.mark.parametrize("where", ["missing/dir/s.json", "."])
def test_schema_out_to_an_unwritable_path_is_one_line_and_exit_2(tmp_path, capsys, where):
    target = tmp_path / where
    assert main(["schema", "--out", str(target)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {target}: cannot write the schema: ") and err.count("\n") == 1


def test_every_shipped_scenario_points_at_the_schema_and_is_valid(validator):
    assert len(shipped_scenarios()) == 11
    for name, path in shipped_scenarios().items():
        assert path.read_text(encoding="utf-8").splitlines()[0] == MODELINE, name
        assert (path.parent / SCHEMA_FILE_NAME).is_file()  # the modeline's path is relative
        assert _errors(validator, _document(name)) == [], name


def _walk_properties(node: Any, where: str):
    """(path, property schema) of every property anywhere in a schema (not in the
    conditions of if/then, which name a property only to test its value)."""
    if isinstance(node, dict):
        for name, prop in node.get("properties", {}).items():
            yield f"{where}/properties/{name}", prop
        for key, child in node.items():
            if key != "if":
                yield from _walk_properties(child, f"{where}/{key}")
    elif isinstance(node, list):
        for i, child in enumerate(node):
            yield from _walk_properties(child, f"{where}/{i}")


def test_every_property_has_a_description(schema):
    properties = list(_walk_properties(schema, "#"))
    assert len(properties) > 150  # the scenario's ~70 and the parameter models'
    bare = [path for path, prop in properties if not prop.get("description", "").strip()]
    assert bare == []


def test_descriptions_end_with_the_default_and_the_range(schema):
    ke = schema["$defs"]["BacksteppingParameters"]["properties"]["ke"]
    assert ke["description"].endswith("1/s: one number for both or a list of two "
                                      "(default 1.0; > 0)")
    delay = schema["$defs"]["Connection"]["properties"]["delay"]
    assert delay["description"].endswith("(default 0; >= 0, <= 1)")
    assert schema["properties"]["tick"]["description"].endswith(", s (> 0)")  # required


def test_known_class_parameters_are_typed_in_the_schema(validator):
    document = _document("lane_change")
    controller = document["components"]["controller"]
    assert controller["python"] == "controllers.backstepping:BacksteppingController"
    for bad, message in [({"ke": "x"}, "'x' is not of type 'number'"),
                         ({"mu0": 0}, "less than or equal to the minimum of 0"),
                         ({"adaptive": "yes"}, "is not of type 'boolean'"),
                         ({"kee": 1.0}, "Additional properties are not allowed")]:
        wrong = copy.deepcopy(document)
        wrong["components"]["controller"]["parameters"] = bad
        where = "components/controller/parameters" + ("" if "kee" in bad else f"/{next(iter(bad))}")
        assert any(path == where and message in text for path, text in _errors(validator, wrong))
        wrong["components"]["controller"]["python"] = "my_pkg.laws:MyController"
        assert _errors(validator, wrong) == []  # the same parameters, free-form


def test_unknown_class_parameters_stay_free_form(validator):
    document = _document("lane_change")
    document["components"]["controller"] = {"python": "my_pkg.laws:MyController",
                                            "parameters": {"ke": "x", "anything": [1, 2]}}
    assert _errors(validator, document) == []


def test_every_shipped_class_is_described_and_offered_for_completion(schema):
    python = schema["$defs"]["PythonSpec"]
    assert python["properties"]["python"]["examples"] == list(SHIPPED_CLASSES)
    classes = [rule["if"]["properties"]["python"]["const"] for rule in python["allOf"]]
    assert classes == list(SHIPPED_CLASSES)
    for rule in python["allOf"]:
        target = rule["then"]["properties"]["parameters"]["$ref"].removeprefix("#/$defs/")
        assert schema["$defs"][target]["additionalProperties"] is False


def test_a_source_entry_is_typed_by_its_kind(validator):
    document = _document("satory_disturbed")
    name, source = next(iter(document["sources"].items()))
    assert _errors(validator, document) == []
    document["sources"][name] = {**source, "interpolation": "cubic"}
    assert (f"sources/{name}/interpolation", "'cubic' is not one of ['linear', 'previous']"
            ) in _errors(validator, document)


def test_schema_file_is_valid_json_with_the_modeline_name():
    assert json.loads((SCENARIOS / SCHEMA_FILE_NAME).read_text())["$id"] == SCHEMA_ID
