"""Writing an SSP package (`cosim export-ssp`): SystemStructure.ssd, the FMUs, one .ssv.

The package holds each FMU once under `resources/`, a component per FMU
component with its input, output and parameter connectors (ssc:Real in SSP
1.0, ssc:Float64 in 2.0, with units), a connection per FMU-to-FMU edge (an
ssc:LinearTransformation where the edge has scale/offset), the parameter
values in `resources/parameters.ssv` bound at system level with hierarchical
names, and ssd:DefaultExperiment. Our own annotation (`org.cosim.scenario`)
keeps what SSP has no element for: the tick, the exact duration, and each
component's period; `cosim.scenario.ssp` reads it back.
"""

from __future__ import annotations

import hashlib
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from cosim.scenario.ssp import COSIM_ANNOTATION
from cosim.scenario.ssp_xml import NS, SSD_MEMBER, q

COSIM_NS = "urn:cosim:ssp"
PARAMETERS_MEMBER = "resources/parameters.ssv"


@dataclass
class ExportComponent:
    """One FMU component to write, under the FMU's own variable names.

    Attributes:
        inputs, outputs: (variable, unit) pairs.
        parameters: variable -> (value, unit).
    """

    name: str
    fmu: Path
    inputs: list[tuple[str, str]] = field(default_factory=list)
    outputs: list[tuple[str, str]] = field(default_factory=list)
    parameters: dict[str, tuple[float, str]] = field(default_factory=dict)
    period: float | None = None


@dataclass
class ExportSystem:
    """What goes into the package: timing, components, edges (src, port, dst, port, scale, offset)."""

    name: str
    version: str
    start_time: float
    duration: float
    tick: float
    components: list[ExportComponent]
    edges: list[tuple[str, str, str, str, float | None, float | None]]


def write_ssp(system: ExportSystem, out: Path) -> None:
    """Write the package to `out` (replaced if it exists)."""
    members = _fmu_members(system.components)
    ssd = _ssd(system, members)
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(SSD_MEMBER, _bytes(ssd))
        for path, member in members.items():
            archive.write(path, member)
        if any(c.parameters for c in system.components):
            archive.writestr(PARAMETERS_MEMBER, _bytes(_ssv(system)))


def _fmu_members(components: list[ExportComponent]) -> dict[Path, str]:
    """Each distinct FMU file -> its member name (resources/<file name>, made unique)."""
    members: dict[Path, str] = {}
    by_digest: dict[str, str] = {}
    for component in components:
        digest = hashlib.sha256(component.fmu.read_bytes()).hexdigest()
        if digest in by_digest:
            members[component.fmu] = by_digest[digest]
            continue
        member = f"resources/{component.fmu.name}"
        if member in by_digest.values():
            member = f"resources/{component.name}-{component.fmu.name}"
        members[component.fmu] = by_digest[digest] = member
    return members


def _ssd(system: ExportSystem, members: dict[Path, str]) -> etree._Element:
    root = etree.Element(q("ssd:SystemStructureDescription"), nsmap=_nsmap(),
                         name=system.name, version=system.version)
    top = etree.SubElement(root, q("ssd:System"), name=system.name)
    if any(c.parameters for c in system.components):
        binding = etree.SubElement(etree.SubElement(top, q("ssd:ParameterBindings")),
                                   q("ssd:ParameterBinding"))
        binding.set("source", PARAMETERS_MEMBER)
    elements = etree.SubElement(top, q("ssd:Elements"))
    for component in system.components:
        _component(elements, component, members[component.fmu], system.version)
    if system.edges:
        connections = etree.SubElement(top, q("ssd:Connections"))
        for edge in system.edges:
            _connection(connections, edge)
    experiment = etree.SubElement(root, q("ssd:DefaultExperiment"))
    experiment.set("startTime", repr(system.start_time))
    experiment.set("stopTime", repr(system.start_time + system.duration))
    _annotate(root, "Scenario", tick=system.tick, duration=system.duration)
    return root


def _component(parent: etree._Element, component: ExportComponent, member: str,
               version: str) -> None:
    element = etree.SubElement(parent, q("ssd:Component"), name=component.name,
                               type="application/x-fmu-sharedlibrary", source=member,
                               implementation="CoSimulation")
    connectors = etree.SubElement(element, q("ssd:Connectors"))
    kinds = [("input", component.inputs), ("output", component.outputs),
             ("parameter", [(n, u) for n, (_, u) in component.parameters.items()])]
    for kind, ports in kinds:
        for name, unit in ports:
            connector = etree.SubElement(connectors, q("ssd:Connector"), name=name, kind=kind)
            typed = etree.SubElement(connector, q("ssc:Real" if version == "1.0" else "ssc:Float64"))
            if unit:
                typed.set("unit", unit)
    if component.period is not None:
        _annotate(element, "Component", period=component.period)


def _connection(parent: etree._Element, edge: tuple) -> None:
    src, src_port, dst, dst_port, scale, offset = edge
    element = etree.SubElement(parent, q("ssd:Connection"), startElement=src,
                               startConnector=src_port, endElement=dst, endConnector=dst_port)
    if scale is None and offset is None:
        return
    element.set("suppressUnitConversion", "true")  # the transformation is the whole conversion
    linear = etree.SubElement(element, q("ssc:LinearTransformation"))
    if scale is not None:
        linear.set("factor", repr(scale))
    if offset is not None:
        linear.set("offset", repr(offset))


def _annotate(element: etree._Element, tag: str, **values: float) -> None:
    annotations = etree.SubElement(element, q("ssd:Annotations"))
    annotation = etree.SubElement(annotations, q("ssc:Annotation"), type=COSIM_ANNOTATION)
    etree.SubElement(annotation, f"{{{COSIM_NS}}}{tag}",
                     {k: repr(float(v)) for k, v in values.items()})


def _ssv(system: ExportSystem) -> etree._Element:
    root = etree.Element(q("ssv:ParameterSet"), nsmap={"ssv": NS["ssv"]},
                         version=system.version, name="parameters")
    parameters = etree.SubElement(root, q("ssv:Parameters"))
    kind = "ssv:Real" if system.version == "1.0" else "ssv:Float64"
    for component in system.components:
        for name, (value, unit) in component.parameters.items():
            parameter = etree.SubElement(parameters, q("ssv:Parameter"),
                                         name=f"{component.name}.{name}")
            typed = etree.SubElement(parameter, q(kind), value=repr(float(value)))
            if unit:
                typed.set("unit", unit)
    return root


def _nsmap() -> dict[str, str]:
    return {"ssd": NS["ssd"], "ssc": NS["ssc"], "ssv": NS["ssv"], "cosim": COSIM_NS}


def _bytes(root: etree._Element) -> bytes:
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)
