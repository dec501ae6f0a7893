"""What an FMU offers, read from its modelDescription.xml, checked before t = 0.

`describe_fmu` reads an FMU file (FMI 2.0 or 3.x, co-simulation or model
exchange) with fmpy,
without loading its binary, and gives its inputs and outputs as cosim Ports,
its parameters, and value references, all under canonical names: a foreign
FMU's variables are renamed through the scenario's `variables:` map
(canonical name -> FMU variable name). `check_parameters` holds a scenario's
parameter values against the FMU (names, types, min/max).
"""

from __future__ import annotations

import hashlib
import math
import zipfile
from xml.etree import ElementTree
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from fmpy import read_model_description
from fmpy.model_description import ModelVariable

from cosim.component import Port
from cosim.errors import FmuInterfaceError, did_you_mean
from cosim.signal_types import FLOAT64, FLOAT_TYPES, NOT_RECORDED_TYPES, NUMERIC_TYPES

if TYPE_CHECKING:
    from cosim.scenario.models import Scenario

SIGNAL_CAUSALITIES = ("input", "output", "parameter")
# model descriptions read in this process, by the SHA-256 of their FMU file: the samples
# of a sweep that follow each other on a worker read an FMU's XML once (fmpy's parse and
# schema check cost ~2.5 ms a time); the file's bytes, not its path, are the key
DESCRIPTIONS_KEPT = 16
_descriptions: dict[str, Any] = {}


class ParameterInfo(NamedTuple):
    """One Float64/Real parameter of an FMU (min/max None when not declared)."""

    vr: int
    start: float | None
    unit: str
    min: float | None
    max: float | None


@dataclass(frozen=True)
class FmuInterface:
    """The interface of one FMU, under canonical names.

    Attributes:
        path: the .fmu file.
        fmi_version: "2.0" or "3.x".
        model_name, model_identifier, guid: from the model description
            (guid is the instantiationToken in FMI 3).
        sha256: hex digest of the .fmu file.
        inputs, outputs: the numeric inputs and outputs as Ports, each with its
            FMI type (`Port.type`, see `cosim.signal_types`; size > 1 for FMI 3
            arrays; an input's default is its start value).
        parameters: Float64/Real scalar parameters by name.
        value_references: canonical name -> value reference (inputs, outputs,
            parameters, unsupported ones included).
        fmu_names: canonical name -> the FMU's own variable name.
        unsupported: inputs, outputs and parameters that cannot be connected or
            set (name -> why, e.g. "a String variable"); connecting one is an error.
        not_recorded: String and Binary outputs (name -> type), listed once as
            not recorded.
        model_description: fmpy's ModelDescription, for instantiating the FMU.
        fmi_type: "CoSimulation" or "ModelExchange": the interface the run uses.
    """

    path: Path
    fmi_version: str
    model_name: str
    model_identifier: str
    guid: str
    sha256: str
    inputs: tuple[Port, ...]
    outputs: tuple[Port, ...]
    parameters: dict[str, ParameterInfo]
    value_references: dict[str, int]
    fmu_names: dict[str, str] = field(default_factory=dict)
    unsupported: dict[str, str] = field(default_factory=dict)
    not_recorded: dict[str, str] = field(default_factory=dict)
    model_description: Any = field(default=None, repr=False, compare=False)
    fmi_type: str = "CoSimulation"

    @property
    def ports(self) -> tuple[tuple[Port, ...], tuple[Port, ...]]:
        """(inputs, outputs), the form cosim.engine.wiring.resolve_wiring takes."""
        return self.inputs, self.outputs


def describe_fmu(path: str | Path, variables: Mapping[str, str] | None = None,
                 origin: str | None = None, kind: str | None = None) -> FmuInterface:
    """Read and check an FMU's interface.

    Args:
        path: the .fmu file.
        variables: canonical name -> FMU variable name, for foreign FMUs.
        origin: where the name map comes from, prefixed to its errors
            (e.g. "lane.yaml:12: components.vehicle.variables").
        kind: "co_simulation" or "model_exchange" (the scenario's `interface:`);
            None: co-simulation when the FMU offers it, else model exchange.
    Raises:
        FmuInterfaceError: not a zip / no modelDescription.xml / invalid XML,
            the interface asked for missing, FMI version other than 2.0 and 3.x, a mapped
            name missing from the FMU or not a numeric input, output or parameter.
    """
    fmu = Path(path)
    md, digest = _description(fmu)
    fmi_type, identity = _fmi_type(md, kind, fmu)
    names = _canonical_names(md.modelVariables, dict(variables or {}), fmu, origin)
    inputs: list[Port] = []
    outputs: list[Port] = []
    parameters: dict[str, ParameterInfo] = {}
    unsupported: dict[str, str] = {}
    not_recorded: dict[str, str] = {}
    refs: dict[str, int] = {}
    for var in md.modelVariables:
        name = names.get(var.name)
        if name is None:
            continue
        refs[name] = var.valueReference
        problem = _unsupported_reason(var)
        if problem:
            unsupported[name] = problem
            if var.causality == "output" and var.type in NOT_RECORDED_TYPES:
                not_recorded[name] = var.type
        elif var.causality == "parameter":
            parameters[name] = _parameter_info(var)
        else:
            (inputs if var.causality == "input" else outputs).append(_port(name, var))
    return FmuInterface(
        path=fmu, fmi_version=md.fmiVersion, model_name=md.modelName or "",
        model_identifier=identity.modelIdentifier, guid=md.guid or "",
        sha256=digest, inputs=tuple(inputs), outputs=tuple(outputs),
        parameters=parameters, value_references=refs,
        fmu_names={canonical: fmu_name for fmu_name, canonical in names.items()},
        unsupported=unsupported, not_recorded=not_recorded, model_description=md, fmi_type=fmi_type)


def _fmi_type(md: Any, kind: str | None, fmu: Path) -> tuple[str, Any]:
    """The interface a run uses ("CoSimulation"/"ModelExchange") and its XML element."""
    offered = {"co_simulation": md.coSimulation, "model_exchange": md.modelExchange}
    if kind is None:
        kind = "co_simulation" if md.coSimulation is not None else "model_exchange"
    if offered[kind] is None:
        has = [k for k, v in offered.items() if v is not None]
        raise FmuInterfaceError(f"{fmu}: the FMU does not offer {kind.replace('_', ' ')} "
                                f"(it offers: {', '.join(has) or 'neither interface'})")
    return ("CoSimulation" if kind == "co_simulation" else "ModelExchange"), offered[kind]


def _description(fmu: Path) -> tuple[Any, str]:
    """(fmpy's model description, SHA-256) of an FMU file; a description already read in
    this process from the same bytes is reused (callers only read it)."""
    if not fmu.is_file():
        raise FmuInterfaceError(f"{fmu}: FMU file not found")
    before = file_sha256(fmu)
    md = _descriptions.get(before)
    if md is not None:
        return md, before
    md = _read_description(fmu)
    after = file_sha256(fmu)
    if after == before:  # kept only if the file did not change while it was read
        if len(_descriptions) >= DESCRIPTIONS_KEPT:
            _descriptions.pop(next(iter(_descriptions)))  # the oldest
        _descriptions[after] = md
    return md, after


def _read_description(fmu: Path) -> Any:
    """fmpy's model description of an FMU file, or a clear FmuInterfaceError."""
    if not zipfile.is_zipfile(fmu):
        raise FmuInterfaceError(f"{fmu}: not an FMU (an FMU is a zip archive; this file is not)")
    with zipfile.ZipFile(fmu) as archive:
        if "modelDescription.xml" not in archive.namelist():
            raise FmuInterfaceError(f"{fmu}: not an FMU (no modelDescription.xml in the archive)")
        version = _declared_version(archive, fmu)
    if not (version == "2.0" or version.startswith("3.")):
        raise FmuInterfaceError(f"{fmu}: FMI version {version} is not supported "
                                "(only FMI 2.0 and 3.x co-simulation FMUs)")
    try:
        return read_model_description(str(fmu), validate=True)
    except Exception as exc:  # fmpy raises bare Exceptions, lxml its own: all mean a bad FMU
        raise FmuInterfaceError(f"{fmu}: cannot read modelDescription.xml: {exc}") from None


def _declared_version(archive: zipfile.ZipFile, fmu: Path) -> str:
    """The fmiVersion attribute of the archive's modelDescription.xml root element."""
    try:
        with archive.open("modelDescription.xml") as stream:
            _, root = next(ElementTree.iterparse(stream, events=("start",)))
    except (ElementTree.ParseError, StopIteration) as exc:
        raise FmuInterfaceError(f"{fmu}: modelDescription.xml is not valid XML ({exc})") from None
    version = root.get("fmiVersion")
    if version is None:
        raise FmuInterfaceError(f"{fmu}: modelDescription.xml has no fmiVersion attribute")
    return version


def _canonical_names(model_variables: list[ModelVariable], mapping: dict[str, str],
                     fmu: Path, origin: str | None) -> dict[str, str]:
    """FMU variable name -> canonical name, for inputs, outputs and parameters."""
    by_name = {v.name: v for v in model_variables}
    prefix = f"{origin}: " if origin else f"{fmu}: "
    problems: list[str] = []
    renamed: dict[str, str] = {}
    for canonical, fmu_name in mapping.items():
        var = by_name.get(fmu_name)
        if var is None:
            problems.append(f"{canonical!r} maps to {fmu_name!r}, which the FMU does not "
                            f"have{did_you_mean(fmu_name, by_name, n=3)}")
        elif var.causality not in SIGNAL_CAUSALITIES:
            problems.append(f"{canonical!r} maps to {fmu_name!r}, a {var.causality} variable; "
                            "only inputs, outputs and parameters can be mapped")
        elif fmu_name in renamed:
            problems.append(f"{canonical!r} and {renamed[fmu_name]!r} both map to {fmu_name!r}")
        elif var.type not in NUMERIC_TYPES:
            problems.append(f"{canonical!r} maps to {fmu_name!r} of type {var.type}; "
                            "only numeric signals can be used")
        else:
            renamed[fmu_name] = canonical
    names = {v.name: renamed.get(v.name, v.name) for v in model_variables
             if v.causality in SIGNAL_CAUSALITIES}
    for canonical in mapping:
        if canonical in by_name and canonical not in renamed and canonical in names:
            problems.append(f"{canonical!r} is mapped to another variable, but the FMU also "
                            f"has its own variable {canonical!r}")
    if problems:
        raise FmuInterfaceError("\n".join(prefix + p for p in problems))
    return names


def _unsupported_reason(var: ModelVariable) -> str | None:
    """Why a variable cannot be connected or set, or None if it can."""
    if var.type not in NUMERIC_TYPES:
        return f"a variable of type {var.type} (only numeric signals are recorded or connected)"
    if var.causality == "parameter" and var.type not in FLOAT_TYPES:
        return f"a parameter of type {var.type} (only Float64/Real parameters can be set)"
    if var.causality == "parameter" and var.shape:
        return "an array parameter (only scalar parameters can be set)"
    if any(d is None for d in (var.shape or ())):
        return "an array of variable size"
    return None


def _unit(var: ModelVariable) -> str:
    """The variable's unit: its own, else its declared type's, else ''."""
    if var.unit:
        return var.unit
    if var.declaredType is not None and var.declaredType.unit:
        return var.declaredType.unit
    return ""


def _float_or_none(text: Any) -> float | None:
    """A float from an XML attribute (None when absent or unparsable)."""
    if text is None:
        return None
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


def _limit(var: ModelVariable, which: str) -> float | None:
    """The variable's min or max, falling back on its declared type's."""
    value = _float_or_none(getattr(var, which, None))
    if value is None and var.declaredType is not None:
        value = _float_or_none(getattr(var.declaredType, which, None))
    return value


def _parameter_info(var: ModelVariable) -> ParameterInfo:
    """ParameterInfo of a scalar float parameter."""
    return ParameterInfo(var.valueReference, _float_or_none(var.start), _unit(var),
                         _limit(var, "min"), _limit(var, "max"))


def _port(name: str, var: ModelVariable) -> Port:
    """A Port for a numeric input or output (arrays: size is the product of the shape;
    an array's default is its start value when every element starts the same, else 0)."""
    size = math.prod(var.shape) if var.shape else 1
    starts = {_start_value(s) for s in str(var.start).split()} if var.start is not None else set()
    start = starts.pop() if len(starts) == 1 else None
    return Port(name=name, size=size, unit=_unit(var), description=var.description or "",
                default=start if start is not None else 0.0,
                type=FLOAT64 if var.type in FLOAT_TYPES else var.type)  # FMI 2 Real is Float64


def _start_value(text: Any) -> float | None:
    """A scalar start value as a float (Booleans: "true"/"false" are 1 and 0)."""
    if isinstance(text, str) and text.strip().lower() in ("true", "false"):
        return float(text.strip().lower() == "true")
    return _float_or_none(text)


def file_sha256(path: Path) -> str:
    """Hex SHA-256 of a file."""
    digest = hashlib.sha256()
    with path.open("rb") as stream:
        for chunk in iter(lambda: stream.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def check_parameters(interface: FmuInterface, parameters: Mapping[str, float],
                     component_name: str, scenario: Scenario | None = None) -> None:
    """Check parameter values against an FMU: names exist, are settable floats, in min/max.

    Args:
        interface: the FMU's interface (canonical names).
        parameters: name -> value, e.g. Scenario.plant_parameters(name).
        component_name: the component's name, for messages.
        scenario: when given, each message starts with the YAML file, line
            and path of the parameter (or of its uncertainty entry).
    Raises:
        FmuInterfaceError: listing every bad parameter, one per line.
    """
    lines = []
    for name, value in parameters.items():
        message = _parameter_problem(interface, name, value)
        if message:
            lines.append(f"{_where(scenario, component_name, name)}: {message}")
    if lines:
        raise FmuInterfaceError("\n".join(lines))


def _parameter_problem(interface: FmuInterface, name: str, value: float) -> str | None:
    """What is wrong with setting one parameter, or None."""
    fmu = interface.model_name or interface.path.name
    if name in interface.unsupported:
        return f"parameter {name!r} of FMU {fmu!r} cannot be set: it is {interface.unsupported[name]}"
    info = interface.parameters.get(name)
    if info is None:
        hint = did_you_mean(name, interface.parameters, n=3)
        if not hint:  # nothing close: list what can be set instead
            hint = "; its parameters: " + (", ".join(sorted(interface.parameters)) or "none")
        return f"FMU {fmu!r} has no parameter {name!r}{hint}"
    if not math.isfinite(value):
        return f"parameter {name!r} = {value!r} is not finite"
    if info.min is not None and value < info.min:
        return f"parameter {name!r} = {value:g} is below its minimum {info.min:g}"
    if info.max is not None and value > info.max:
        return f"parameter {name!r} = {value:g} is above its maximum {info.max:g}"
    return None


def _where(scenario: Scenario | None, component: str, parameter: str) -> str:
    """Where a parameter value comes from: YAML file, line and path, or the component."""
    if scenario is None:
        return f"component {component!r}"
    spec = scenario.fmu_components().get(component)
    section = "uncertainty" if spec is not None and parameter in spec.uncertainty else "parameters"
    if spec is not None and parameter not in spec.uncertainty and parameter not in spec.parameters:
        return f"component {component!r}"
    return scenario.where(("components", component, section, parameter))
