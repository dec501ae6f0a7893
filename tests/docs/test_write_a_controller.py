"""docs/write-a-controller.md works as written: its module, its commands, its comparison figure.

The page's Python block is saved under the file name of its first line, and its shell
commands are run in that folder (only the duration is shortened, so the test stays quick).
"""

from __future__ import annotations

import json
import re
import shlex

import pytest

from cosim.cli.app import main
from tests.helpers.paths import REPO_ROOT

PAGE = REPO_ROOT / "docs" / "write-a-controller.md"
SHORT = ["--set", "duration=18"]  # through the start of the lane change (~13 s)


def _blocks(kind: str) -> list[str]:
    return re.findall(rf"```{kind}\n(.*?)```", PAGE.read_text(encoding="utf-8"), re.S)


@pytest.mark.integration
def test_the_walk_through_runs_as_written(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("PYTHONPATH", raising=False)
    (module,) = _blocks("python")
    name = module.splitlines()[0].removeprefix("# ").strip()
    (tmp_path / name).write_text(module)
    commands = [shlex.split(line) for block in _blocks("sh") for line in block.splitlines()
                if line.startswith("cosim ")]
    assert [c[:2] for c in commands] == [["cosim", "run"], ["cosim", "run"], ["cosim", "compare"]]
    for argv in commands:
        extra = SHORT if argv[1] == "run" else []
        assert main(argv[1:] + extra) == 0, capsys.readouterr().err
    manifest = json.loads((tmp_path / "runs" / "p_steering" / "manifest.json").read_text())
    assert manifest["status"] == "ok"
    assert manifest["scenario"]["components"]["controller"]["python"] == \
        "p_steering:ProportionalSteering"
    assert (tmp_path / "runs" / "p_steering" / "figure_manoeuvre.png").is_file()
    assert (tmp_path / "runs" / "compare" / "compare_manoeuvre.png").is_file()
    table = (tmp_path / "runs" / "compare" / "compare_metrics.csv").read_text().splitlines()
    assert table[0] == "metric,backstepping,p_steering"
    yc = next(row.split(",") for row in table if row.startswith("max_abs_yc_cg,"))
    assert float(yc[2]) > float(yc[1]) > 0  # no curvature feed-forward: the CG farther off


def test_the_yaml_line_of_the_page_loads():
    from cosim.api import load_scenario

    (line,) = _blocks("yaml")
    parameters = re.search(r"parameters: (\{.*?\})", line).group(1)
    scenario = load_scenario("lane_change", set=[
        "components.controller.python=p_steering:ProportionalSteering",
        f"components.controller.parameters={parameters}"])
    assert scenario.components["controller"].parameters == {"k_y": 0.1, "k_psi": 1.0}
