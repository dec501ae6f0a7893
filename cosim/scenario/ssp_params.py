"""Parameter bindings of an SSP system: .ssv values (files or inline), .ssm renames, precedence.

A binding on a component names that component's FMU variables; one on the
system names them hierarchically (`component.variable`). A binding's
`prefix` is put in front of every name, then its parameter mapping (`.ssm`,
a file or inline) renames names and may apply an ssc:LinearTransformation to
the value. Later bindings override earlier ones on the same level, and the
system's override the components' (as SSP specifies).

SSP says a name that matches no variable is ignored; here it is an error, as
an unknown parameter is in a scenario YAML, because a silently dropped value
is a wrong run. Only Real/Float64/Float32 values of FMU parameters can be set.
"""

from __future__ import annotations

from typing import Any

from cosim.errors import did_you_mean
from cosim.scenario.ssp_xml import NS, SspPackage, q

FLOAT_VALUES = ("Real", "Float64", "Float32")
OTHER_VALUES = ("Integer", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64",
                "UInt64", "Boolean", "String", "Enumeration", "Binary")


def bind_parameters(package: SspPackage, member: str, system: Any, components: dict) -> None:
    """Fill each component's `parameters` from the bindings, recording every problem."""
    path = "ssd:ParameterBindings/ssd:ParameterBinding"
    for name, component in components.items():
        for binding in component.element.iterfind(path, namespaces=NS):
            for target, value, where in _values(package, member, binding):
                _assign(package, components, name, target, value, where)
    for binding in system.iterfind(path, namespaces=NS):
        for target, value, where in _values(package, member, binding):
            component, _, variable = target.partition(".")
            if not variable:
                package.error(*where, f"system-level parameter {target!r} names no component "
                              "(system connectors are not supported; write component.parameter)")
                continue
            _assign(package, components, component, variable, value, where)


def _assign(package: SspPackage, components: dict, name: str, variable: str,
            value: tuple[str, float | None, str | None], where: tuple) -> None:
    """Set one parameter value on a component after checking it against the FMU."""
    component = components.get(name)
    if component is None:
        package.error(*where, f"no FMU component named {name!r}{did_you_mean(name, components)}")
        return
    kind, number, unit = value
    var = component.md.variables.get(variable)
    if var is None or var[0] != "parameter":
        names = [n for n, v in component.md.variables.items() if v[0] == "parameter"]
        found = "has no parameter" if var is None else f"has {variable!r} as an {var[0]}, not"
        package.error(*where, f"FMU of {name!r} {found} {variable!r}{did_you_mean(variable, names)}"
                      f"; its parameters: {', '.join(names) or 'none'}")
        return
    if kind not in FLOAT_VALUES or var[1] not in ("Real", "Float64"):
        package.error(*where, f"{name}.{variable} is of type {var[1]} (value given as {kind}); "
                      "only Real/Float64 parameters can be set")
        return
    if unit and var[2] and unit != var[2]:
        package.error(*where, f"{name}.{variable}: value in {unit!r}, the FMU's parameter is in "
                      f"{var[2]!r} (the platform converts no units)")
        return
    component.parameters[variable] = number


def _values(package: SspPackage, member: str, binding: Any) -> list:
    """(name, (type, value, unit), where) of a binding, prefixed and mapped."""
    sets = []
    source = binding.get("source")
    if source is not None:
        root = _referenced(package, member, binding, source, "ssv")
        if root is not None:
            sets.append((package.resolve(source, member), root))
    sets += [(member, s) for s in binding.iterfind("ssd:ParameterValues/ssv:ParameterSet",
                                                   namespaces=NS)]
    mapping = _mapping(package, member, binding)
    prefix = binding.get("prefix", "")
    result = []
    for set_member, parameter_set in sets:
        for parameter in parameter_set.iterfind("ssv:Parameters/ssv:Parameter", namespaces=NS):
            where = (set_member, parameter, f"ssv:Parameter {parameter.get('name')!r}")
            value = _value(package, parameter, where)
            if value is None:
                continue
            name, value = _mapped(prefix + (parameter.get("name") or ""), value, mapping)
            result.append((name, value, where))
    return result


def _value(package: SspPackage, parameter: Any, where: tuple) -> tuple | None:
    """(type, float or None, unit) of one ssv:Parameter, or None after a problem."""
    for child in parameter:
        kind = child.tag.rpartition("}")[2]
        if kind in FLOAT_VALUES:
            try:
                return kind, float(child.get("value")), child.get("unit")
            except (TypeError, ValueError):
                package.error(*where, f"value {child.get('value')!r} is not a number")
                return None
        if kind in OTHER_VALUES:
            return kind, None, None
    package.error(*where, "the parameter has no value element (ssv:Real, ssv:Float64, ...)")
    return None


def _referenced(package: SspPackage, member: str, element: Any, source: str, kind: str) -> Any:
    """The root of a .ssv/.ssm file a binding names, or None after recording why not."""
    what = f"ssd:{'ParameterBinding' if kind == 'ssv' else 'ParameterMapping'} source={source!r}"
    if element.get("sourceBase", "SSD") == "component":
        package.error(member, element, what, "sourceBase=\"component\" (a file inside the FMU) "
                      "is not supported")
        return None
    resolved = package.resolve(source, member)
    if resolved is None or not package.exists(resolved):
        package.error(member, element, what, f"unresolved resource: {source!r} is not a file "
                      f"in {package.path.name}")
        return None
    return package.xml(resolved, kind)


def _mapping(package: SspPackage, member: str, binding: Any) -> dict[str, tuple]:
    """source name -> (target name, scale, offset) of a binding's parameter mapping."""
    element = binding.find(q("ssd:ParameterMapping"))
    if element is None:
        return {}
    roots = list(element.iterfind("ssm:ParameterMapping", namespaces=NS))
    if element.get("source") is not None:
        root = _referenced(package, member, element, element.get("source"), "ssm")
        roots += [root] if root is not None else []
    result = {}
    for root in roots:
        for entry in root.iterfind("ssm:MappingEntry", namespaces=NS):
            linear = entry.find(q("ssc:LinearTransformation"))
            if len(entry) and linear is None and entry.find(q("ssm:Annotations")) is None:
                package.error(member, entry, f"ssm:MappingEntry {entry.get('source')!r}",
                              "only ssc:LinearTransformation mappings are supported")
                continue
            scale = float(linear.get("factor", 1.0)) if linear is not None else None
            offset = float(linear.get("offset", 0.0)) if linear is not None else None
            result[entry.get("source")] = (entry.get("target"), scale, offset)
    return result


def _mapped(name: str, value: tuple, mapping: dict[str, tuple]) -> tuple[str, tuple]:
    """A parameter's name and value after the mapping (unchanged when it maps nothing)."""
    if name not in mapping:
        return name, value
    target, scale, offset = mapping[name]
    kind, number, unit = value
    if number is not None and scale is not None:
        number = scale * number + offset
    return target, (kind, number, unit)
