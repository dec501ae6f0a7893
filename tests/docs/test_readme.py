"""The README's scenario example is a real, valid scenario (docs must not rot)."""

import re

from cosim.scenario.loader import load_scenario
from tests.helpers.paths import REPO_ROOT

ROOT = REPO_ROOT


def test_readme_scenario_example_loads(tmp_path):
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    example = re.search(r"```yaml\n(name: .*?)```", text, re.S)
    assert example, "README has no scenario example"
    path = tmp_path / "example.yaml"
    path.write_text(example.group(1), encoding="utf-8")
    scenario = load_scenario(path)
    assert set(scenario.components) == {"vehicle", "controller", "planner"}
    assert scenario.components["vehicle"].uncertainty["m"].scale == 1.3
    assert "side_wind" in scenario.python_components()


def test_readme_opens_with_the_two_commands():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    block = lines[lines.index("```sh") + 1:lines.index("```sh") + 3]
    assert "cosim run scenarios/" in block[0] and "pytest" in block[1]
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert "-m pytest -q" in ci


def test_readme_signal_types_table_is_the_generated_one():
    from cosim.signal_types import types_table

    text = (ROOT / "README.md").read_text()
    start = "<!-- generated: signal types (cosim.signal_types.types_table) -->\n"
    block = text[text.index(start) + len(start):text.index("<!-- end generated: signal types -->")]
    assert block == types_table()
