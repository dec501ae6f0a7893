"""Reading SSP 1.0 and 2.0 packages written in the style of public examples (tests/helpers/ssp.py).

The structure is cross-checked against fmpy's own SSP reader where it can read
the file (SSP 1.0); every problem must name the member, the line and the element.
"""

from __future__ import annotations

import pytest

from cosim.errors import ScenarioError
from cosim.scenario.loader import load_scenario
from cosim.scenario.ssp import read_system
from tests.helpers.ssp import HEADER, lag_pair_resources, lag_pair_ssd, write_ssp

VERSIONS = ("1.0", "2.0")


@pytest.fixture(autouse=True)
def _cache(tmp_path, monkeypatch):
    monkeypatch.setenv("COSIM_CACHE_DIR", str(tmp_path / "cache"))  # FMUs extract here


def pair(tmp_path, lag_fmus, version, ssd=None, files=None, name="pair.ssp"):
    """The two-lag package of tests/helpers/ssp.py (or another SSD around the same files)."""
    resources = lag_pair_resources(version) if files is None else files
    return write_ssp(tmp_path / name, ssd or lag_pair_ssd(version),
                     {"resources/Lag.fmu": lag_fmus[2]}, resources)


def problems_of(path) -> str:
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path)
    return str(caught.value)


def line_of(text: str, needle: str) -> int:
    """1-based line of the first line of `text` containing `needle`."""
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


@pytest.mark.parametrize("version", VERSIONS)
def test_components_parameters_connections_and_timing(tmp_path, lag_fmus, version):
    scenario = load_scenario(pair(tmp_path, lag_fmus, version))
    assert list(scenario.components) == ["lag2", "lag1"]  # the SSD's order
    lag1, lag2 = scenario.components["lag1"], scenario.components["lag2"]
    # .ssv value renamed by the .ssm (time_constant -> tau), inline set, system-level binding
    assert lag1.parameters == {"tau": 0.25, "y_init": 1.0}
    assert lag2.parameters == {"gain": 0.5}
    assert lag1.fmu.endswith("resources/Lag.fmu") and lag1.fmu == lag2.fmu
    (connection,) = scenario.connections
    assert (connection.src, connection.dst) == ("lag1.y_out", "lag2.u_cmd")
    assert (connection.scale, connection.offset) == (1.3, 50.0)
    assert (scenario.tick, scenario.duration, scenario.start_time) == (0.01, 2.0, 0.0)
    assert scenario.name == "lag_pair"


def test_transformation_keeps_only_the_attributes_given(tmp_path, lag_fmus):
    ssd = lag_pair_ssd("2.0", factor='factor="-2"')
    (connection,) = load_scenario(pair(tmp_path, lag_fmus, "2.0", ssd)).connections
    assert (connection.scale, connection.offset) == (-2.0, None)


def test_system_bindings_override_component_bindings(tmp_path, lag_fmus):
    ssd = lag_pair_ssd("1.0").replace('name="lag2.gain"', 'name="lag1.y_init"')
    scenario = load_scenario(pair(tmp_path, lag_fmus, "1.0", ssd))
    assert scenario.components["lag1"].parameters["y_init"] == 0.5  # system level wins
    assert scenario.components["lag2"].parameters == {}


def test_same_structure_as_fmpy_reads(tmp_path, lag_fmus):
    from fmpy.ssp.ssd import find_components, read_ssd

    path = pair(tmp_path, lag_fmus, "1.0")
    theirs = read_ssd(str(path))  # validates against the same SSP 1.0 schema
    ours = read_system(path)
    assert [c.name for c in find_components(theirs.system)] == list(ours.components)
    assert [c.source for c in find_components(theirs.system)] == ["resources/Lag.fmu"] * 2
    assert [(c.startElement, c.startConnector, c.endElement, c.endConnector)
            for c in theirs.system.connections] == [("lag1", "y_out", "lag2", "u_cmd")]


def test_schema_violation_names_member_line_and_message(tmp_path, lag_fmus):
    ssd = lag_pair_ssd("1.0").replace('kind="output"', 'kind="sideways"')
    text = problems_of(pair(tmp_path, lag_fmus, "1.0", ssd))
    assert f"SystemStructure.ssd:{line_of(ssd, 'sideways')}: schema:" in text
    assert "sideways" in text and "Traceback" not in text


def test_ssp2_structural_check_without_schema(tmp_path, lag_fmus):
    ssd = lag_pair_ssd("2.0").replace('kind="output"', 'kind="sideways"')
    text = problems_of(pair(tmp_path, lag_fmus, "2.0", ssd))
    assert (f"SystemStructure.ssd:{line_of(ssd, 'sideways')}: ssd:Connector lag2.y_out: a "
            "connector needs a name and a kind") in text


@pytest.mark.parametrize("version", VERSIONS)
def test_unknown_connector_in_a_connection(tmp_path, lag_fmus, version):
    ssd = lag_pair_ssd(version).replace('startConnector="y_out"', 'startConnector="y_outt"')
    text = problems_of(pair(tmp_path, lag_fmus, version, ssd))
    line = line_of(ssd, 'startConnector="y_outt"')
    assert (f"SystemStructure.ssd:{line}: ssd:Connection lag1.y_outt -> lag2.u_cmd: unknown "
            "connector lag1.y_outt: the FMU has no such variable (did you mean 'y_out'?)") in text


def test_declared_connector_the_fmu_lacks_and_wrong_kind_and_unit(tmp_path, lag_fmus):
    ssd = (lag_pair_ssd("1.0")
           .replace('name="u_cmd" kind="input"><ssc:Real unit="1"/>',
                    'name="u_cmd" kind="output"><ssc:Real unit="m"/>')
           .replace('<ssd:Connector name="y_out"', '<ssd:Connector name="y_gone"'))
    text = problems_of(pair(tmp_path, lag_fmus, "1.0", ssd))
    assert "ssd:Connector lag2.u_cmd: kind 'output', but the FMU variable is causality 'input'" in text
    assert "ssd:Connector lag2.u_cmd: unit 'm', but the FMU variable is in '1'" in text
    assert "ssd:Connector lag2.y_gone: unknown connector: the FMU has no variable 'y_gone'" in text


def test_unresolved_resources(tmp_path, lag_fmus):
    ssd = lag_pair_ssd("1.0", lag2_source="resources/Missing.fmu")
    files = dict(lag_pair_resources("1.0"))
    del files["resources/mapping.ssm"]
    text = problems_of(pair(tmp_path, lag_fmus, "1.0", ssd, files))
    assert (f"SystemStructure.ssd:{line_of(ssd, 'Missing.fmu')}: ssd:Component 'lag2': source "
            "'resources/Missing.fmu' does not resolve to a file in pair.ssp") in text
    assert ("ssd:ParameterMapping source='resources/mapping.ssm': unresolved resource: "
            "'resources/mapping.ssm' is not a file in pair.ssp") in text


def test_unknown_parameter_and_non_float_value_in_an_ssv(tmp_path, lag_fmus):
    files = lag_pair_resources("2.0")
    files["resources/parameters.ssv"] = files["resources/parameters.ssv"].replace(
        "time_constant", "time_constnt")
    ssd = lag_pair_ssd("2.0").replace('<ssv:Float64 value="1.0"/>', '<ssv:Int32 value="1"/>')
    text = problems_of(pair(tmp_path, lag_fmus, "2.0", ssd, files))
    assert "resources/parameters.ssv:5: ssv:Parameter 'time_constnt': FMU of 'lag1' has no " \
           "parameter 'time_constnt'; its parameters: tau, gain, y_init" in text
    assert "lag1.y_init is of type Real (value given as Int32); only Real/Float64" in text


@pytest.mark.parametrize("change, message", [
    ('implementation="CoSimulation"', "implementation='ModelExchange' is not supported: an "
                                      "SSP's components run as co-simulation FMUs (a Model "
                                      "Exchange FMU runs from a scenario YAML with interface: "
                                      "model_exchange)"),
    ('<ssc:LinearTransformation factor="1.3" offset="50"/>',
     "ssc:BooleanMappingTransformation is not supported (only ssc:LinearTransformation"),
    ('<ssd:Component name="lag2"', "nested systems are not supported"),
    ('<ssd:Connection startElement="lag1"', "unit 'm' -> '1': the platform converts no units"),
])
def test_what_the_platform_cannot_honour_is_one_clear_line(tmp_path, lag_fmus, change, message):
    replacement = {
        'implementation="CoSimulation"': 'implementation="ModelExchange"',
        '<ssc:LinearTransformation factor="1.3" offset="50"/>':
            '<ssc:BooleanMappingTransformation><ssc:MapEntry source="true" target="false"/>'
            '</ssc:BooleanMappingTransformation>',
        '<ssd:Component name="lag2"': '<ssd:System name="inner"/><ssd:Component name="lag2"',
        '<ssd:Connection startElement="lag1"':
            '<ssd:Connection startElement="lag2" startConnector="y_out" endElement="lag1" '
            'endConnector="u_cmd"/><ssd:Connection startElement="lag1"',
    }[change]
    ssd = lag_pair_ssd("2.0").replace(change, replacement)
    if "startElement=\"lag2\"" in replacement:  # lag2.y_out declared in m: a unit mismatch
        ssd = ssd.replace('name="y_out" kind="output"><ssc:Float64/>',
                          'name="y_out" kind="output"><ssc:Float64 unit="m"/>')
        ssd = ssd.replace('name="u_cmd" kind="input"><ssc:Float64 unit="1"/>',
                          'name="u_cmd" kind="input"><ssc:Float64/>')
    text = problems_of(pair(tmp_path, lag_fmus, "2.0", ssd))
    assert message in text
    assert len([line for line in text.splitlines() if message in line]) == 1


def test_model_exchange_only_fmu_is_refused(tmp_path, fmu_dir):
    from cosim.fmu.build import build_fmu_from
    from tests.helpers.paths import TEST_FMUS_DIR

    me = build_fmu_from(TEST_FMUS_DIR / "BouncingBallME", 2, fmu_dir)
    ssd = HEADER.format(name="ball", version="1.0") + """
  <ssd:System name="s"><ssd:Elements>
    <ssd:Component name="ball" source="resources/ball.fmu"/>
  </ssd:Elements></ssd:System>
</ssd:SystemStructureDescription>"""
    text = problems_of(write_ssp(tmp_path / "ball.ssp", ssd, {"resources/ball.fmu": me}))
    assert "ssd:Component 'ball': resources/ball.fmu is a Model Exchange-only FMU" in text


def test_not_a_package_and_not_xml(tmp_path, lag_fmus):
    bad = tmp_path / "bad.ssp"
    bad.write_text("hello")
    assert "not an SSP package (an .ssp is a zip archive" in problems_of(bad)
    text = problems_of(pair(tmp_path, lag_fmus, "1.0", ssd="<ssd:Sys"))
    assert "SystemStructure.ssd:1: not well-formed XML" in text


def test_yaml_brings_in_a_system_and_adds_around_it(tmp_path, lag_fmus):
    pair(tmp_path, lag_fmus, "1.0")
    (tmp_path / "s.yaml").write_text(
        "name: around\nduration: 1.0\nsystem: pair.ssp\n"
        "sources:\n  u: {kind: constant, value: 2.0}\n"
        "connections:\n  - u.value -> lag1.u_cmd\n  - {from: u.value, to: lag1.u_cmd, delay: -1}\n")
    with pytest.raises(ScenarioError) as caught:
        load_scenario(tmp_path / "s.yaml")
    assert "s.yaml:8: connections[2].delay" in str(caught.value)  # the YAML's own line, after the SSP's one
    (tmp_path / "s.yaml").write_text(
        "name: around\nduration: 1.0\nsystem: pair.ssp\n"
        "sources:\n  u: {kind: constant, value: 2.0}\n"
        "connections:\n  - {from: u.value, to: lag1.u_cmd}\n")
    scenario = load_scenario(tmp_path / "s.yaml", ["components.lag1.parameters.tau=0.4"])
    assert (scenario.name, scenario.duration, scenario.tick) == ("around", 1.0, 0.01)
    assert list(scenario.components) == ["lag2", "lag1"] and list(scenario.sources) == ["u"]
    assert [c.src for c in scenario.connections] == ["lag1.y_out", "u.value"]
    assert scenario.components["lag1"].parameters["tau"] == 0.4 and scenario.system is None


def test_yaml_component_clashing_with_the_system(tmp_path, lag_fmus):
    pair(tmp_path, lag_fmus, "1.0")
    (tmp_path / "s.yaml").write_text(
        "name: x\nsystem: pair.ssp\ncomponents:\n  lag1: {fmu: Bicycle}\n")
    with pytest.raises(ScenarioError, match=r"s.yaml:4: components.lag1: name 'lag1' is "
                                            r"already a component of pair.ssp"):
        load_scenario(tmp_path / "s.yaml")
