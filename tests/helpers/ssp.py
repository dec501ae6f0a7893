"""SSP packages written by hand in the tests, in the style of public examples.

The layout follows libcosim's test data (test/data/ssp/linear_transformation,
demo): an ssd:SystemStructureDescription with namespace prefixes ssd/ssc/ssv,
components with a `source` and optional ssd:Connectors, inline
ssv:ParameterSet bindings, ssc:LinearTransformation inside ssd:Connection, and
OSP's FixedStepAlgorithm annotation for the step; plus a referenced .ssv and
.ssm as in the SSP standard's examples. Nothing here comes from the platform's
own writer, so the reader is tested on files it did not write.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

HEADER = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription name="{name}" version="{version}"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping"
    xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations">
"""

SSV = """<?xml version="1.0" encoding="UTF-8"?>
<ssv:ParameterSet version="{version}" name="values"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssv:Parameters>
{parameters}
  </ssv:Parameters>
</ssv:ParameterSet>
"""

SSM = """<?xml version="1.0" encoding="UTF-8"?>
<ssm:ParameterMapping version="{version}"
    xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">
{entries}
</ssm:ParameterMapping>
"""


def real(version: str) -> str:
    """The Real type element's name: ssc:Real in SSP 1.0, ssc:Float64 in 2.0."""
    return "Real" if version == "1.0" else "Float64"


def parameter(name: str, value: float, version: str, prefix: str = "ssv") -> str:
    """One ssv:Parameter with a Real (1.0) / Float64 (2.0) value."""
    return (f'    <{prefix}:Parameter name="{name}"><{prefix}:{real(version)} value="{value!r}"/>'
            f"</{prefix}:Parameter>")


def inline_binding(version: str, name: str, parameters: str) -> str:
    """An ssd:ParameterBinding holding an inline ssv:ParameterSet (as libcosim's demo)."""
    return f"""      <ssd:ParameterBinding><ssd:ParameterValues>
        <ssv:ParameterSet version="{version}" name="{name}"><ssv:Parameters>
{parameters}
        </ssv:Parameters></ssv:ParameterSet>
      </ssd:ParameterValues></ssd:ParameterBinding>"""


def lag_connectors(version: str, input_unit: str = "") -> str:
    """ssd:Connectors of a Lag component: u_cmd (input), y_out (output)."""
    unit = f' unit="{input_unit}"' if input_unit else ""
    return f"""<ssd:Connectors>
          <ssd:Connector name="u_cmd" kind="input"><ssc:{real(version)}{unit}/></ssd:Connector>
          <ssd:Connector name="y_out" kind="output"><ssc:{real(version)}/></ssd:Connector>
        </ssd:Connectors>"""


def lag_pair_ssd(version: str, *, factor: str = 'factor="1.3" offset="50"',
                 extra_connection: str = "", step: float = 0.01, stop: float = 2.0,
                 lag2_source: str = "resources/Lag.fmu") -> str:
    """Two Lag FMUs: lag1.y_out -> lag2.u_cmd through a linear transformation.

    lag1 gets y_init from an inline set and tau from parameters.ssv (renamed by
    mapping.ssm from time_constant); lag2 (declared first, as in libcosim's
    demo) gets gain from a system-level binding with hierarchical names.
    """
    transformation = f"<ssc:LinearTransformation {factor}/>" if factor else ""
    return HEADER.format(name="lag pair", version=version) + f"""
  <ssd:System name="lags">
    <ssd:ParameterBindings>
{inline_binding(version, "system", parameter("lag2.gain", 0.5, version))}
    </ssd:ParameterBindings>
    <ssd:Elements>
      <ssd:Component name="lag2" source="{lag2_source}">
        {lag_connectors(version, "1")}
      </ssd:Component>
      <ssd:Component name="lag1" source="resources/Lag.fmu" implementation="CoSimulation">
        <ssd:ParameterBindings>
          <ssd:ParameterBinding source="resources/parameters.ssv">
            <ssd:ParameterMapping source="resources/mapping.ssm"/>
          </ssd:ParameterBinding>
{inline_binding(version, "initial", parameter("y_init", 1.0, version))}
        </ssd:ParameterBindings>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="lag1" startConnector="y_out" endElement="lag2" endConnector="u_cmd">{transformation}</ssd:Connection>
{extra_connection}
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="{stop!r}">
    <ssd:Annotations>
      <ssc:Annotation type="com.opensimulationplatform">
        <osp:Algorithm><osp:FixedStepAlgorithm baseStepSize="{step!r}"/></osp:Algorithm>
      </ssc:Annotation>
    </ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
"""


def lag_pair_resources(version: str) -> dict[str, str]:
    """parameters.ssv (time_constant = 0.25) and mapping.ssm (time_constant -> tau)."""
    return {
        "resources/parameters.ssv": SSV.format(version=version, parameters=parameter(
            "time_constant", 0.25, version)),
        "resources/mapping.ssm": SSM.format(version=version, entries=(
            '  <ssm:MappingEntry source="time_constant" target="tau"/>')),
    }


def write_ssp(path: Path, ssd: str, fmus: dict[str, Path], files: dict[str, str] | None = None
              ) -> Path:
    """Zip an .ssp: SystemStructure.ssd, FMUs (member -> file) and text files (member -> text)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("SystemStructure.ssd", ssd)
        for member, fmu in fmus.items():
            archive.write(fmu, member)
        for member, text in (files or {}).items():
            archive.writestr(member, text)
    return path
