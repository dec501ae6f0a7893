"""An FMU file that cannot be read (not a zip, a modelDescription.xml that fails the
schema) is named as every FMU check is: on one line, after the scenario file, line
and field that name the FMU."""

from __future__ import annotations

import zipfile

import pytest

from cosim.errors import FmuInterfaceError
from cosim.execution.prepare import plan_fmus
from cosim.scenario.loader import load_scenario

SCENARIO = """\
name: foreign
duration: 1.0
tick: 0.01
components:
  vehicle:
    fmu: {fmu}
sources:
  steer: {{kind: constant, value: 0.01}}
connections:
  - steer.value -> vehicle.delta
"""
# two schema errors: the message lists both, on the same line
BAD_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="P" guid="{g}">
  <CoSimulation modelIdentifier="P"/>
  <ModelVariables>
    <ScalarVariable name="delta" valueReference="1" causality="sideways"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="2" causality="output" variability="wrong"><Real/></ScalarVariable>
  </ModelVariables>
  <ModelStructure/>
</fmiModelDescription>
"""


def _plan(tmp_path, fmu):
    scenario = tmp_path / "foreign.yaml"
    scenario.write_text(SCENARIO.format(fmu=fmu))
    with pytest.raises(FmuInterfaceError) as raised:
        plan_fmus(load_scenario(scenario))
    return str(raised.value), f"{scenario}:6: components.vehicle.fmu: {fmu}: "


def test_a_file_that_is_not_a_zip(tmp_path):
    fmu = tmp_path / "plant.fmu"
    fmu.write_bytes(b"not a zip")
    message, where = _plan(tmp_path, fmu)
    assert message == where + "not an FMU (an FMU is a zip archive; this file is not)"


def test_a_model_description_that_fails_the_schema_is_one_line(tmp_path):
    fmu = tmp_path / "plant.fmu"
    with zipfile.ZipFile(fmu, "w") as archive:
        archive.writestr("modelDescription.xml", BAD_DESCRIPTION)
    message, where = _plan(tmp_path, fmu)
    assert "\n" not in message
    assert message.startswith(where + "cannot read modelDescription.xml: Failed to validate "
                                      "modelDescription.xml: ERROR (line 5")
    assert "'sideways'" in message and "; ERROR (line 6" in message and "'wrong'" in message
