"""SSP systems as scenarios: `cosim run system.ssp` and `system: file.ssp` in a YAML.

`read_system` reads an SSP 1.0 or 2.0 package (`cosim.scenario.ssp_xml`) and
checks it against the FMUs it holds: every FMU component resolves to an FMU in
the package that offers co-simulation, every connector and connection names a
variable of its FMU with the right causality and unit, parameter bindings
(`cosim.scenario.ssp_params`) name parameters. Each problem names the file in
the package, the line and the XML element. What the platform cannot honour
(nested systems and SSP components, signal dictionaries, Model Exchange or
scheduled-execution components, non-linear mappings, unit conversions, array
slices) is refused with a one-line reason. Connections to the system's own
connectors are its boundary and are not imported: a YAML drives those inputs.

`system_document` maps the result onto the scenario model: each ssd:Component
becomes `components.<name>: {fmu: <extracted file>, parameters: ...}`, each
ssd:Connection `{from: a.x, to: b.u}` with `scale`/`offset` from its
ssc:LinearTransformation, ssd:DefaultExperiment gives `start_time` and
`duration`; the step comes from the package's cosim annotation (written by
`cosim export-ssp`), else OSP's FixedStepAlgorithm, else the smallest
DefaultExperiment stepSize of its FMUs.

The reader is our own (lxml): fmpy's `fmpy.ssp.ssd` knows only SSP 1.0 (its
schema rejects version="2.0"), looks for the linear transformation under the
wrong namespace (so drops it), keeps neither connector types and units, the
component's `implementation` nor the DefaultExperiment, and gives no lines.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim.scenario.checks import exact
from cosim.scenario.ssp_params import bind_parameters
from cosim.scenario.ssp_xml import NS, VERSIONS, SspPackage, q, short

FMU_TYPE = "application/x-fmu-sharedlibrary"
COSIM_ANNOTATION = "org.cosim.scenario"  # our own annotation (tick, duration, periods)
OSP_ANNOTATION = "com.opensimulationplatform"
FLOAT_TYPES = ("Real", "Float64", "Float32")
CONNECTOR_TYPES = ("Real", "Float64", "Float32", "Integer", "Int8", "UInt8", "Int16", "UInt16",
                   "Int32", "UInt32", "Int64", "UInt64", "Boolean", "String", "Enumeration",
                   "Binary", "Clock")
KINDS = ("input", "output", "parameter", "calculatedParameter", "structuralParameter",
         "constant", "local", "inout", "unspecified")
# what an SSP's component must be: its import has no setting for the interface
SSP_RUNS = ("an SSP's components run as co-simulation FMUs (a Model Exchange FMU runs from a "
            "scenario YAML with interface: model_exchange)")


@dataclass
class FmuVariables:
    """What an FMU in the package declares: variables (name -> (causality, type, unit))."""

    variables: dict[str, tuple[str, str, str]]
    cosimulation: bool
    step: float | None


@dataclass
class SspComponent:
    """One FMU component of the system, its file on disk and its FMU's variables."""

    name: str
    element: Any
    fmu: Path
    md: FmuVariables
    connectors: dict[str, tuple[str, str | None]] = field(default_factory=dict)  # kind, unit
    parameters: dict[str, float] = field(default_factory=dict)
    period: float | None = None


@dataclass
class SspSystem:
    """A checked SSP system: name, FMU components, connections and the experiment."""

    name: str
    version: str
    components: dict[str, SspComponent]
    connections: list[dict[str, Any]]
    lines: dict[tuple, int]
    start_time: float | None = None
    duration: float | None = None
    tick: float | None = None


def read_system(path: str | Path) -> SspSystem:
    """Read and check an .ssp package (or a bare .ssd file).

    Raises:
        ScenarioError: every problem found, each naming the member, line and element.
    """
    package = SspPackage(Path(path))
    member = package.ssd_member
    if not package.exists(member):
        package.error(member, None, "", f"the package has no {member}")
        package.raise_problems()
    root = package.xml(member, "ssd")
    package.raise_problems()
    version = root.get("version", "")
    if version not in VERSIONS:
        package.error(member, root, short(root), f"version {version!r} is not an SSP version "
                      f"this reader knows ({', '.join(VERSIONS)})")
    system = root.find(q("ssd:System"))
    if system is None:
        package.error(member, root, short(root), "no ssd:System element")
        package.raise_problems()
    _refuse_unsupported(package, member, system)
    components = _components(package, member, system)
    connections = _connections(package, member, system, components)
    bind_parameters(package, member, system, components)
    package.raise_problems()
    result = SspSystem(_safe_name(root.get("name") or system.get("name") or package.path.stem),
                       version, components, [c for c, _ in connections], {})
    result.lines = {("components", n): c.element.sourceline for n, c in components.items()}
    result.lines.update({("connections", i): line for i, (_, line) in enumerate(connections)})
    _experiment(root, result)
    return result


def _safe_name(name: str) -> str:
    """A scenario name from the SSD's: anything but letters, digits, '.', '-' becomes '_'."""
    return re.sub(r"[^\w.-]+", "_", name).strip("_") or "ssp"


def _refuse_unsupported(package: SspPackage, member: str, system: Any) -> None:
    """Record the SSP features the platform cannot run, one line each."""
    for element in system.iterfind("ssd:Elements/ssd:System", namespaces=NS):
        package.error(member, element, f"ssd:System {element.get('name')!r}",
                      "nested systems are not supported: flatten the system into one level")
    for element in system.iterfind("ssd:Elements/ssd:SignalDictionaryReference", namespaces=NS):
        package.error(member, element, f"{short(element)} {element.get('name')!r}",
                      "signal dictionaries are not supported: connect the connectors directly")
    for element in system.iterfind("ssd:SignalDictionaries", namespaces=NS):
        package.error(member, element, short(element), "signal dictionaries are not supported")


def _components(package: SspPackage, member: str, system: Any) -> dict[str, SspComponent]:
    """The FMU components of the system, each resolved to an FMU with co-simulation."""
    found: dict[str, SspComponent] = {}
    for element in system.iterfind("ssd:Elements/ssd:Component", namespaces=NS):
        name = element.get("name")
        what = f"ssd:Component {name!r}"
        if not name:
            package.error(member, element, "ssd:Component", "the attribute 'name' is required")
            continue
        if name in found:
            package.error(member, element, what, f"a second component named {name!r}")
            continue
        component = _component(package, member, element, what)
        if component is not None:
            found[name] = component
    return found


def _component(package: SspPackage, member: str, element: Any, what: str) -> SspComponent | None:
    """One ssd:Component, or None after recording why it cannot run."""
    kind = element.get("type", FMU_TYPE)
    if kind != FMU_TYPE:
        package.error(member, element, what, f"component type {kind!r} is not supported "
                      f"(only FMUs, {FMU_TYPE}; nested SSPs/SSDs are not)")
        return None
    implementation = element.get("implementation", "any")
    if implementation in ("ModelExchange", "ScheduledExecution"):
        package.error(member, element, what, f"implementation={implementation!r} is not "
                      f"supported: {SSP_RUNS}")
        return None
    source = element.get("source")
    resolved = package.resolve(source, member) if source else None
    if resolved is None or not package.exists(resolved):
        package.error(member, element, what, f"source {source!r} does not resolve to a file in "
                      f"{package.path.name}" if source else "the attribute 'source' is required")
        return None
    fmu = package.fmu_file(resolved)
    md = _describe(package, resolved, fmu, element, what)
    if md is None:
        return None
    component = SspComponent(element.get("name"), element, fmu, md)
    component.connectors = _connectors(package, member, element, component)
    component.period = _annotation_float(element, "Component", "period")
    return component


def _describe(package: SspPackage, member: str, fmu: Path, element: Any,
              what: str) -> FmuVariables | None:
    """The variables of an FMU in the package (fmpy's reader), or None after recording why not."""
    from fmpy import read_model_description

    try:
        md = read_model_description(str(fmu), validate=False)
    except Exception as exc:  # fmpy and lxml raise many kinds; all mean "not a usable FMU"
        package.error(package.ssd_member, element, what, f"{member} is not a readable FMU: {exc}")
        return None
    if md.coSimulation is None:
        package.error(package.ssd_member, element, what, f"{member} is a Model Exchange-only "
                      f"FMU; {SSP_RUNS}")
        return None
    variables = {}
    for var in md.modelVariables:
        unit = var.unit or (var.declaredType.unit if var.declaredType is not None else None)
        variables[var.name] = (var.causality, var.type, unit or "")
    step = md.defaultExperiment.stepSize if md.defaultExperiment is not None else None
    return FmuVariables(variables, True, float(step) if step else None)


def _connectors(package: SspPackage, member: str, element: Any,
                component: SspComponent) -> dict[str, tuple[str, str | None]]:
    """The declared connectors of a component, each checked against its FMU."""
    result = {}
    for conn in element.iterfind("ssd:Connectors/ssd:Connector", namespaces=NS):
        name, kind = conn.get("name"), conn.get("kind")
        what = f"ssd:Connector {component.name}.{name}"
        if not name or kind not in KINDS:
            package.error(member, conn, what, f"a connector needs a name and a kind "
                          f"({', '.join(KINDS)}); got kind={kind!r}")
            continue
        typed = next((c for c in conn if c.tag in {q("ssc:" + t) for t in CONNECTOR_TYPES}), None)
        unit = typed.get("unit") if typed is not None else None
        var = component.md.variables.get(name)
        if var is None:
            package.error(member, conn, what, f"unknown connector: the FMU has no variable "
                          f"{name!r}{_close(name, component.md.variables)}")
            continue
        if kind in ("input", "output", "parameter") and var[0] != kind:
            package.error(member, conn, what, f"kind {kind!r}, but the FMU variable is "
                          f"causality {var[0]!r}")
        if unit and var[2] and unit != var[2]:
            package.error(member, conn, what, f"unit {unit!r}, but the FMU variable is in "
                          f"{var[2]!r} (the platform converts no units)")
        result[name] = (kind, unit or var[2] or None)
    return result


def _close(name: str, names: Any) -> str:
    from cosim.errors import did_you_mean

    return did_you_mean(name, list(names))


def _connections(package: SspPackage, member: str, system: Any,
                 components: dict[str, SspComponent]) -> list[tuple[dict[str, Any], int]]:
    """The connections between FMU components as scenario entries, with their lines."""
    result = []
    for element in system.iterfind("ssd:Connections/ssd:Connection", namespaces=NS):
        entry = _connection(package, member, element, components)
        if entry is not None:
            result.append((entry, element.sourceline))
    return result


def _connection(package: SspPackage, member: str, element: Any,
                components: dict[str, SspComponent]) -> dict[str, Any] | None:
    """One ssd:Connection as {from, to, scale?, offset?}, or None (system boundary, problem)."""
    ends = [(element.get(f"{side}Element"), element.get(f"{side}Connector"))
            for side in ("start", "end")]
    what = "ssd:Connection " + " -> ".join(f"{e}.{c}" if e else str(c) for e, c in ends)
    if any(element.get(a) for a in ("startIndices", "endIndices")):
        package.error(member, element, what, "startIndices/endIndices (array slices) are not "
                      "supported")
        return None
    if any(e is None for e, _ in ends):
        # the system's own connectors are its boundary: nothing outside drives them in a
        # run, so the component end holds its start value unless a scenario YAML drives it
        for (name, connector), role in zip(ends, ("output", "input")):
            if name is not None:
                _end_unit(package, member, element, what, components, name, connector, role)
        return None
    units = [_end_unit(package, member, element, what, components, e, c, role)
             for (e, c), role in zip(ends, ("output", "input"))]
    if any(u is False for u in units):
        return None
    entry: dict[str, Any] = {"from": f"{ends[0][0]}.{ends[0][1]}",
                             "to": f"{ends[1][0]}.{ends[1][1]}"}
    transform = _transformation(package, member, element, what)
    if transform is False:
        return None
    entry.update(transform)
    suppress = element.get("suppressUnitConversion", "false") in ("true", "1")
    if units[0] and units[1] and units[0] != units[1] and not (suppress and transform):
        package.error(member, element, what, f"unit {units[0]!r} -> {units[1]!r}: the platform "
                      "converts no units; give an ssc:LinearTransformation and "
                      "suppressUnitConversion=\"true\"")
        return None
    return entry


def _end_unit(package: SspPackage, member: str, element: Any, what: str,
              components: dict[str, SspComponent], name: str, connector: str,
              role: str) -> str | None | bool:
    """The unit of one end of a connection ('' / None if none), or False after a problem."""
    component = components.get(name)
    if component is None:
        package.error(member, element, what, f"no FMU component named {name!r}"
                      f"{_close(name, components)}")
        return False
    var = component.md.variables.get(connector)
    if var is None:
        package.error(member, element, what, f"unknown connector {name}.{connector}: the FMU "
                      f"has no such variable{_close(connector, component.md.variables)}")
        return False
    if var[0] != role:
        package.error(member, element, what, f"{name}.{connector} has causality {var[0]!r}; "
                      f"a connection's {'start' if role == 'output' else 'end'} must be an {role}")
        return False
    if var[1] not in FLOAT_TYPES[:2]:
        package.error(member, element, what, f"{name}.{connector} is of type {var[1]}; only "
                      "Real/Float64 signals can be connected")
        return False
    declared = component.connectors.get(connector)
    return (declared[1] if declared else None) or var[2] or None


def _transformation(package: SspPackage, member: str, element: Any,
                    what: str) -> dict[str, float] | bool:
    """{scale?, offset?} of a connection's ssc:LinearTransformation; False if unsupported."""
    for other in ("Boolean", "Integer", "Enumeration"):
        if element.find(q(f"ssc:{other}MappingTransformation")) is not None:
            package.error(member, element, what, f"ssc:{other}MappingTransformation is not "
                          "supported (only ssc:LinearTransformation on Real signals)")
            return False
    linear = element.find(q("ssc:LinearTransformation"))
    if linear is None:
        return {}
    values = {}
    for attribute, key in (("factor", "scale"), ("offset", "offset")):
        text = linear.get(attribute)
        if text is None:
            continue
        try:
            values[key] = float(text)
        except ValueError:
            package.error(member, linear, what, f"{attribute}={text!r} is not a number")
            return False
    return values


def _annotation_float(element: Any, tag: str, attribute: str) -> float | None:
    """A number from our cosim annotation on an element (None when absent)."""
    for annotation in element.iterfind("ssd:Annotations/ssc:Annotation", namespaces=NS):
        if annotation.get("type") == COSIM_ANNOTATION:
            for child in annotation:
                if child.tag.endswith("}" + tag) and child.get(attribute) is not None:
                    return float(child.get(attribute))
    return None


def _experiment(root: Any, system: SspSystem) -> None:
    """Start time, duration and tick from the DefaultExperiment and the annotations."""
    experiment = root.find(q("ssd:DefaultExperiment"))
    start = stop = None
    if experiment is not None:
        start = _float(experiment.get("startTime"))
        stop = _float(experiment.get("stopTime"))
    system.start_time = start
    if stop is not None:
        system.duration = float(exact(stop) - exact(start or 0.0))
    system.duration = _annotation_float(root, "Scenario", "duration") or system.duration
    system.tick = (_annotation_float(root, "Scenario", "tick") or _osp_step(experiment)
                   or min((c.md.step for c in system.components.values() if c.md.step),
                          default=None))


def _osp_step(experiment: Any) -> float | None:
    """OSP's baseStepSize (libcosim's files) from the DefaultExperiment's annotations."""
    if experiment is None:
        return None
    for node in experiment.iter():
        if isinstance(node.tag, str) and node.tag.endswith("}FixedStepAlgorithm"):
            return _float(node.get("baseStepSize"))
    return None


def _float(text: str | None) -> float | None:
    try:
        return float(text) if text is not None else None
    except ValueError:
        return None


def system_document(system: SspSystem) -> dict[str, Any]:
    """The scenario fields an SSP system gives: name, timing, components, connections."""
    document: dict[str, Any] = {"name": system.name}
    for key in ("duration", "tick", "start_time"):
        if getattr(system, key) is not None:
            document[key] = getattr(system, key)
    components = {}
    for name, component in system.components.items():
        spec: dict[str, Any] = {"fmu": str(component.fmu)}
        if component.parameters:
            spec["parameters"] = dict(component.parameters)
        if component.period is not None:
            spec["period"] = component.period
        components[name] = spec
    document["components"] = components
    document["connections"] = [dict(c) for c in system.connections]
    return document
