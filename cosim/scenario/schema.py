"""The JSON schema of scenario files, for editors (`cosim schema`).

It is generated from the pydantic models (cosim.scenario.models and
.sources) and the parameter models of the shipped component classes
(cosim.scenario.known_classes): JSON Schema draft 2020-12, every property
described. Each description ends with what the schema keywords say of the
value, written from them: its default and its range ("(default 5.0; > 0)"),
so an editor's hover shows them. The `$id` is fixed (`SCHEMA_ID`), not tied
to the package version: a scenario's `# yaml-language-server: $schema=...`
line points at a file, and the id only names the document.

The shipped scenarios point at `scenarios/scenario.schema.json`, a
committed copy that a test holds equal to what this module generates.
"""

from __future__ import annotations

import json
from typing import Any

from cosim.scenario.known_classes import describe_parameters
from cosim.scenario.models import Scenario

DRAFT = "https://json-schema.org/draft/2020-12/schema"
SCHEMA_ID = "urn:cosim-vehicle:scenario-schema:1"
#: the schema file beside the shipped scenarios (the name their first line gives)
SCHEMA_FILE_NAME = "scenario.schema.json"
_RANGE = (("exclusiveMinimum", ">"), ("minimum", ">="), ("exclusiveMaximum", "<"),
          ("maximum", "<="))


def json_schema() -> dict[str, Any]:
    """The JSON schema of scenario files (for editors), as a dict."""
    body = Scenario.model_json_schema(mode="validation")
    describe_parameters(body)
    for definition in [body, *body.get("$defs", {}).values()]:
        for prop in definition.get("properties", {}).values():
            _add_default_and_range(prop)
    return {"$schema": DRAFT, "$id": SCHEMA_ID, **body, "title": "cosim scenario"}


def schema_text() -> str:
    """The schema as the text of the schema file (sorted neither: pydantic's order kept)."""
    return json.dumps(json_schema(), indent=2) + "\n"


def _add_default_and_range(prop: dict[str, Any]) -> None:
    """Append "(default X; > a, <= b)" to a property's description, from its keywords
    (not the default of a whole section, whose own fields give theirs)."""
    notes = []
    if "default" in prop and not (isinstance(prop["default"], dict) and prop["default"]):
        notes.append(f"default {json.dumps(prop['default'])}")
    bounds = [f"{sign} {_number(alternative[key])}"
              for alternative in [prop, *prop.get("anyOf", [])]
              for key, sign in _RANGE if key in alternative]
    if bounds:
        notes.append(", ".join(bounds))
    if notes:
        prop["description"] = f"{prop.get('description', '').rstrip('.')} ({'; '.join(notes)})"


def _number(value: float) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)
