"""Tests of cosim.fmu.interface on FMUs made of a hand-written modelDescription.xml.

describe_fmu never loads the binary, so a zip with only the XML is a complete
test object; it lets each bad-FMU class be built on purpose.
"""

from __future__ import annotations

import hashlib
import zipfile
from pathlib import Path

import pytest

from cosim.component import Port
from cosim.errors import FmuInterfaceError
from cosim.fmu.interface import ParameterInfo, check_parameters, describe_fmu
from cosim.scenario.loader import load_scenario
from tests.helpers.fmus import built_fmu

FMI2_VARIABLES = """
    <ScalarVariable name="steer" valueReference="1" causality="input" variability="continuous">
      <Real declaredType="Angle" start="0.1"/></ScalarVariable>
    <ScalarVariable name="pos.x" valueReference="2" causality="output" variability="continuous"
      initial="calculated"><Real unit="m"/></ScalarVariable>
    <ScalarVariable name="mass" valueReference="3" causality="parameter" variability="fixed"
      initial="exact"><Real unit="kg" start="1500" min="100" max="5000"/></ScalarVariable>
    <ScalarVariable name="gear" valueReference="4" causality="input" variability="discrete">
      <Integer start="1"/></ScalarVariable>
    <ScalarVariable name="wheels" valueReference="5" causality="parameter" variability="fixed"
      initial="exact"><Integer start="4"/></ScalarVariable>
    <ScalarVariable name="speed" valueReference="6" causality="local" variability="continuous"
      initial="calculated"><Real unit="m/s"/></ScalarVariable>
    <ScalarVariable name="delta" valueReference="7" causality="input" variability="continuous">
      <Real unit="rad" start="0"/></ScalarVariable>
    <ScalarVariable name="label" valueReference="8" causality="output" variability="discrete"
      initial="exact"><String start="none"/></ScalarVariable>
"""
FMI2_STRUCTURE = """<ModelStructure><Outputs><Unknown index="2"/><Unknown index="8"/></Outputs>
  <InitialUnknowns><Unknown index="2"/></InitialUnknowns></ModelStructure>"""


def fmi2_xml(interface: str = '<CoSimulation modelIdentifier="Plant"/>',
             variables: str = FMI2_VARIABLES, version: str = "2.0") -> str:
    """A schema-valid FMI 2.0 model description with the given interface element."""
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="{version}" modelName="Plant" guid="{{1234-abcd}}">
  {interface}
  <UnitDefinitions><Unit name="rad"/><Unit name="m"/><Unit name="kg"/><Unit name="m/s"/>
  </UnitDefinitions>
  <TypeDefinitions><SimpleType name="Angle"><Real unit="rad"/></SimpleType></TypeDefinitions>
  <ModelVariables>{variables}</ModelVariables>
  {FMI2_STRUCTURE}
</fmiModelDescription>"""


FMI3_XML = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Plant3" instantiationToken="{token-3}">
  <CoSimulation modelIdentifier="Plant3id"/>
  <UnitDefinitions><Unit name="rad"/><Unit name="m"/></UnitDefinitions>
  <TypeDefinitions><Float64Type name="Angle" unit="rad" min="-1" max="1"/></TypeDefinitions>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Float64 name="delta" valueReference="1" causality="input" declaredType="Angle" start="0.25"/>
    <Float64 name="x" valueReference="2" causality="output" unit="m"/>
    <Float64 name="window" valueReference="3" causality="output" unit="m">
      <Dimension start="3"/><Dimension start="2"/></Float64>
    <Float64 name="lim" valueReference="4" causality="parameter" variability="fixed"
      declaredType="Angle" start="0.5"/>
  </ModelVariables>
  <ModelStructure><Output valueReference="2"/><Output valueReference="3"/></ModelStructure>
</fmiModelDescription>"""


def make_fmu(folder: Path, xml: str | None, name: str = "plant.fmu") -> Path:
    """Write a zip holding modelDescription.xml (or an empty zip when xml is None)."""
    path = folder / name
    with zipfile.ZipFile(path, "w") as archive:
        if xml is None:
            archive.writestr("resources/readme.txt", "no description here")
        else:
            archive.writestr("modelDescription.xml", xml)
    return path


def test_a_description_is_read_once_per_content_not_per_path(tmp_path: Path) -> None:
    fmu = make_fmu(tmp_path, fmi2_xml())
    first = describe_fmu(fmu)
    (tmp_path / "copy.fmu").write_bytes(fmu.read_bytes())
    copy = describe_fmu(tmp_path / "copy.fmu")
    assert copy.model_description is first.model_description  # same bytes: parsed once
    assert copy.path == tmp_path / "copy.fmu" and copy.sha256 == first.sha256
    changed = make_fmu(tmp_path, fmi2_xml().replace('guid="{1234-abcd}"', 'guid="{5678-ef01}"'))
    again = describe_fmu(changed)  # the first file's path, other bytes: read afresh
    assert again.guid == "{5678-ef01}" and again.model_description is not first.model_description


def test_fmi2_interface_is_read_under_canonical_names(tmp_path: Path) -> None:
    fmu = make_fmu(tmp_path, fmi2_xml())
    iface = describe_fmu(fmu, {"delta_cmd": "steer", "x": "pos.x", "m": "mass"})
    assert iface.fmi_version == "2.0"
    assert (iface.model_name, iface.model_identifier, iface.guid) == ("Plant", "Plant", "{1234-abcd}")
    assert iface.sha256 == hashlib.sha256(fmu.read_bytes()).hexdigest()
    # the unit of steer comes from its declaredType; its start value is the input's default
    assert iface.inputs == (Port("delta_cmd", 1, "rad", "", 0.1),
                            Port("gear", 1, "", "", 1.0, "Integer"), Port("delta", 1, "rad", "", 0.0))
    assert iface.outputs == (Port("x", 1, "m", "", 0.0),)  # a String is not a signal
    assert iface.not_recorded == {"label": "String"}
    assert iface.parameters == {"m": ParameterInfo(3, 1500.0, "kg", 100.0, 5000.0)}
    assert iface.value_references == {"delta_cmd": 1, "x": 2, "m": 3, "gear": 4, "wheels": 5,
                                      "delta": 7, "label": 8}
    assert iface.fmu_names["delta_cmd"] == "steer" and iface.fmu_names["gear"] == "gear"
    assert set(iface.unsupported) == {"wheels", "label"}
    assert iface.unsupported["wheels"] == ("a parameter of type Integer (only Float64/Real "
                                           "parameters can be set)")
    assert iface.model_description.coSimulation.modelIdentifier == "Plant"
    assert iface.ports == (iface.inputs, iface.outputs)


def test_fmi3_arrays_declared_types_and_token(tmp_path: Path) -> None:
    iface = describe_fmu(make_fmu(tmp_path, FMI3_XML))
    assert iface.fmi_version == "3.0"
    assert (iface.model_identifier, iface.guid) == ("Plant3id", "{token-3}")
    assert iface.inputs == (Port("delta", 1, "rad", "", 0.25),)
    assert iface.outputs == (Port("x", 1, "m", "", 0.0), Port("window", 6, "m", "", 0.0))
    # min/max and unit fall back on the declared type
    assert iface.parameters == {"lim": ParameterInfo(4, 0.5, "rad", -1.0, 1.0)}
    assert "time" not in iface.value_references


def test_not_a_zip(tmp_path: Path) -> None:
    bogus = tmp_path / "bogus.fmu"
    bogus.write_text("hello")
    with pytest.raises(FmuInterfaceError, match=r"bogus\.fmu: not an FMU \(an FMU is a zip"):
        describe_fmu(bogus)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(FmuInterfaceError, match=r"nothere\.fmu: FMU file not found"):
        describe_fmu(tmp_path / "nothere.fmu")


def test_zip_without_model_description(tmp_path: Path) -> None:
    with pytest.raises(FmuInterfaceError, match="no modelDescription.xml in the archive"):
        describe_fmu(make_fmu(tmp_path, None))


def test_model_exchange_only_fmu_is_described_for_model_exchange(tmp_path: Path) -> None:
    fmu = make_fmu(tmp_path, fmi2_xml('<ModelExchange modelIdentifier="PlantME"/>'), "me.fmu")
    iface = describe_fmu(fmu)
    assert (iface.fmi_type, iface.model_identifier) == ("ModelExchange", "PlantME")
    with pytest.raises(FmuInterfaceError,
                       match=r"me\.fmu: the FMU does not offer co simulation \(it offers: model_exchange\)"):
        describe_fmu(fmu, kind="co_simulation")


@pytest.mark.parametrize("version", ["1.0", "4.0"])
def test_unsupported_fmi_version(tmp_path: Path, version: str) -> None:
    fmu = make_fmu(tmp_path, fmi2_xml(version=version))
    with pytest.raises(FmuInterfaceError, match=rf"FMI version {version} is not supported"):
        describe_fmu(fmu)


def test_schema_invalid_description(tmp_path: Path) -> None:
    broken = fmi2_xml(variables='<ScalarVariable name="a" causality="input"><Real/></ScalarVariable>')
    with pytest.raises(FmuInterfaceError, match=r"(?s)cannot read modelDescription.xml.*'valueReference' is required"):
        describe_fmu(make_fmu(tmp_path, broken))


def test_malformed_xml(tmp_path: Path) -> None:
    with pytest.raises(FmuInterfaceError, match="modelDescription.xml is not valid XML"):
        describe_fmu(make_fmu(tmp_path, "<fmiModelDescription"))


def test_mapping_to_missing_variable_names_it_and_suggests(tmp_path: Path) -> None:
    fmu = make_fmu(tmp_path, fmi2_xml())
    with pytest.raises(FmuInterfaceError) as info:
        describe_fmu(fmu, {"delta_cmd": "steerr", "m": "mass"}, origin="s.yaml:9: components.v.variables")
    assert str(info.value) == ("s.yaml:9: components.v.variables: 'delta_cmd' maps to 'steerr', "
                               "which the FMU does not have (did you mean 'steer'?)")


@pytest.mark.parametrize("mapping, expected", [
    ({"v": "label"}, "'v' maps to 'label' of type String; only numeric signals can be used"),
    ({"v": "speed"}, "'v' maps to 'speed', a local variable; only inputs, outputs and parameters "
                     "can be mapped"),
    ({"a": "steer", "b": "steer"}, "'b' and 'a' both map to 'steer'"),
    ({"delta": "steer"}, "'delta' is mapped to another variable, but the FMU also has its own "
                         "variable 'delta'"),
])
def test_bad_mappings(tmp_path: Path, mapping: dict[str, str], expected: str) -> None:
    fmu = make_fmu(tmp_path, fmi2_xml())
    with pytest.raises(FmuInterfaceError) as info:
        describe_fmu(fmu, mapping)
    assert str(info.value) == f"{fmu}: {expected}"


def test_check_parameters_accepts_valid_values(tmp_path: Path) -> None:
    iface = describe_fmu(make_fmu(tmp_path, fmi2_xml()), {"m": "mass"})
    check_parameters(iface, {"m": 100.0}, "vehicle")  # the bounds themselves are allowed
    check_parameters(iface, {"m": 5000.0}, "vehicle")


def test_check_parameters_lists_every_problem(tmp_path: Path) -> None:
    iface = describe_fmu(make_fmu(tmp_path, fmi2_xml()), {"m": "mass"})
    with pytest.raises(FmuInterfaceError) as info:
        check_parameters(iface, {"mm": 1.0, "wheels": 3.0, "m": 99.5}, "vehicle")
    assert str(info.value).splitlines() == [
        "component 'vehicle': FMU 'Plant' has no parameter 'mm' (did you mean 'm'?)",
        "component 'vehicle': parameter 'wheels' of FMU 'Plant' cannot be set: it is a "
        "parameter of type Integer (only Float64/Real parameters can be set)",
        "component 'vehicle': parameter 'm' = 99.5 is below its minimum 100",
    ]
    with pytest.raises(FmuInterfaceError, match="parameter 'm' = 6000 is above its maximum 5000"):
        check_parameters(iface, {"m": 6000.0}, "vehicle")
    with pytest.raises(FmuInterfaceError, match="parameter 'm' = nan is not finite"):
        check_parameters(iface, {"m": float("nan")}, "vehicle")


def test_unknown_parameter_without_close_match_lists_the_valid_names(tmp_path: Path) -> None:
    iface = describe_fmu(make_fmu(tmp_path, fmi2_xml()), {"m": "mass"})
    with pytest.raises(FmuInterfaceError) as info:
        check_parameters(iface, {"cx_drag": 1.0}, "vehicle")
    assert str(info.value) == ("component 'vehicle': FMU 'Plant' has no parameter 'cx_drag'; "
                               "its parameters: m")


def test_check_parameters_names_yaml_line_of_value_and_of_uncertainty(tmp_path: Path) -> None:
    fmu = make_fmu(tmp_path, fmi2_xml())
    (tmp_path / "s.yaml").write_text(
        "name: s\nduration: 1\ntick: 0.1\ncomponents:\n  vehicle:\n    fmu: plant.fmu\n"
        "    variables: {m: mass}\n    parameters:\n      m: 4000\n      Iz: 2000\n"
        "    uncertainty:\n      m: {scale: 1.3}\n")
    scenario = load_scenario(tmp_path / "s.yaml")
    iface = describe_fmu(scenario.resolve_fmu_path(scenario.components["vehicle"]), {"m": "mass"})
    with pytest.raises(FmuInterfaceError) as info:
        check_parameters(iface, scenario.plant_parameters("vehicle"), "vehicle", scenario)
    file = tmp_path / "s.yaml"
    assert str(info.value).splitlines() == [
        f"{file}:12: components.vehicle.uncertainty.m: parameter 'm' = 5200 is above its "
        "maximum 5000",
        f"{file}:10: components.vehicle.parameters.Iz: FMU 'Plant' has no parameter 'Iz'; "
        "its parameters: m",
    ]
    assert fmu == scenario.resolve_fmu_path(scenario.components["vehicle"])


# ---- the built-in plant, built from the repository's C sources ---------------------------

CONTRACT_INPUTS = [("delta", "rad"), ("torque", "N.m"), ("wind_fx", "N"), ("wind_fy", "N"),
                   ("mu", "1")]
CONTRACT_OUTPUTS = [("x", "m"), ("y", "m"), ("psi", "rad"), ("vx", "m/s"), ("vy", "m/s"),
                    ("r", "rad/s"), ("ax", "m/s2"), ("ay", "m/s2"), ("phi", "rad"),
                    ("omega_fl", "rad/s"), ("omega_fr", "rad/s"), ("omega_rl", "rad/s"),
                    ("omega_rr", "rad/s")]
PAPER_TABLE_1 = {"m": 1500.0, "Iz": 2454.0, "Cf": 57500.0, "Cr": 57500.0, "lf": 1.006,
                 "lr": 1.462, "iy": 1.2, "Rw": 0.3}


@pytest.fixture(scope="module")
def bicycle_fmus(tmp_path_factory) -> dict[int, Path]:
    """Both Bicycle FMUs, from the session's build cache (built once per test session)."""
    out = tmp_path_factory.mktemp("bicycle")
    return {version: built_fmu(out, "Bicycle", version)[0] for version in (2, 3)}


def test_built_bicycle_holds_the_plant_contract_in_both_fmi_versions(bicycle_fmus) -> None:
    two, three = (describe_fmu(bicycle_fmus[v]) for v in (2, 3))
    assert (two.fmi_version, three.fmi_version) == ("2.0", "3.0")
    for iface in (two, three):
        assert [(p.name, p.unit) for p in iface.inputs] == CONTRACT_INPUTS
        assert [(p.name, p.unit) for p in iface.outputs] == CONTRACT_OUTPUTS
        assert {k: iface.parameters[k].start for k in PAPER_TABLE_1} == PAPER_TABLE_1
        assert {"cx", "lw", "x0", "y0", "psi0", "vx0"} <= set(iface.parameters)
        assert iface.unsupported == {}
    assert two.inputs == three.inputs and two.outputs == three.outputs
    assert two.parameters == three.parameters


def test_built_bicycle_parameter_checks(bicycle_fmus) -> None:
    iface = describe_fmu(bicycle_fmus[2])
    check_parameters(iface, {"m": 1500.0 * 1.3, "Cf": 57500.0 * 0.7, "vx0": 10.0}, "vehicle")
    low = iface.parameters["m"].min
    with pytest.raises(FmuInterfaceError, match=rf"parameter 'm' = -1 is below its minimum {low:g}"):
        check_parameters(iface, {"m": -1.0}, "vehicle")
