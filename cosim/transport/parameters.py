"""Scenario parameters of a Python component, checked against its constructor.

Before a component class is constructed, each scenario parameter is held
against the constructor's signature: an unknown name is refused with the known
ones, and a value that does not fit the parameter's annotation (`ke: x` for a
`float`, `adaptive: "yes please"` for a `bool`) is refused strictly, as the
scenario schema does: a bool or a string is never a number. The check only
reads the values, so a run's numbers are unchanged. Annotations it does not
know (a class, a protocol) are left to the constructor.

A refused parameter is a `ParameterProblem`, which the master maps to the
parameter's YAML file, line and path (`cosim.execution.abort`).
"""

from __future__ import annotations

import collections.abc
import inspect
import types
import typing
from typing import Any

from cosim.errors import UserError, did_you_mean
from cosim.transport.launch import PythonComponentLaunch


class ParameterProblem(UserError):
    """A component's constructor rejects one of its scenario parameters.

    The master maps it to the parameter's YAML file, line and path
    (`cosim.execution.abort.locate_parameter_problem`); its plain text names the component.

    Args:
        component: the component's scenario name.
        parameter: the parameter's name.
        problem: what is wrong with it.
    """

    def __init__(self, component: str, parameter: str, problem: str) -> None:
        super().__init__(f"component {component!r}: parameters.{parameter}: {problem}")
        self.component, self.parameter, self.problem = component, parameter, problem


def check_parameters(cls: type, launch: PythonComponentLaunch) -> None:
    """Reject a parameter the constructor does not take, or of the wrong type.

    Args:
        cls: the component class.
        launch: the component's launch (name and parameters).
    Raises:
        ParameterProblem for the first unknown or ill-typed parameter.
    """
    try:
        signature = inspect.signature(cls)
    except (TypeError, ValueError):
        return  # no signature to hold the names against: the constructor decides
    params = signature.parameters
    if not any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        known = [p.name for p in params.values()
                 if p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD,
                               inspect.Parameter.KEYWORD_ONLY)]
        for name in launch.parameters:
            if name not in known and not known:
                raise ParameterProblem(launch.name, name, f"unknown parameter {name!r}: "
                                       f"{launch.class_path} takes no parameters")
            if name not in known:
                raise ParameterProblem(launch.name, name, f"unknown parameter {name!r}"
                                       f"{did_you_mean(name, known)}; known: {', '.join(known)}")
    hints = _hints(cls)
    for name, value in launch.parameters.items():
        if name in hints and name in params:
            wanted = _mismatch(hints[name], value)
            if wanted is not None:
                raise ParameterProblem(launch.name, name,
                                       f"expected {wanted}, got {_shown(value)}")


def _hints(cls: type) -> dict[str, Any]:
    """The constructor's resolved annotations ({} when they cannot be resolved)."""
    try:
        return typing.get_type_hints(cls.__init__)
    except Exception:  # an annotation naming what the module does not import: no check
        return {}


def _shown(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


_NAMES = {float: "a number", int: "an integer", bool: "true or false", str: "a string"}


def _mismatch(hint: Any, value: Any) -> str | None:
    """What `hint` expects, in words, when `value` does not fit it; None when it fits
    (or when the hint is not one this check knows)."""
    if hint is Any or hint is inspect.Parameter.empty:
        return None
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        options = typing.get_args(hint)
        wanted = [_mismatch(option, value) for option in options]
        if any(w is None for w in wanted):
            return None
        return " or ".join(dict.fromkeys(w for w in wanted if w))
    if hint is type(None):
        return None if value is None else "null"
    if origin is typing.Literal:
        choices = typing.get_args(hint)
        if any(type(value) is type(c) and value == c for c in choices):
            return None
        return "one of " + ", ".join(repr(c) for c in choices)
    if hint in _NAMES:
        return None if _fits_scalar(hint, value) else _NAMES[hint]
    return _container_mismatch(hint, origin, value)


def _fits_scalar(hint: type, value: Any) -> bool:
    if hint is bool or hint is str:
        return isinstance(value, hint)
    if isinstance(value, bool):
        return False
    return isinstance(value, int) if hint is int else isinstance(value, (int, float))


_SEQUENCES = (list, tuple, collections.abc.Sequence, collections.abc.Iterable)
_MAPPINGS = (dict, collections.abc.Mapping)


def _container_mismatch(hint: Any, origin: Any, value: Any) -> str | None:
    """Lists and mappings (items checked); None for any hint not known here."""
    kind = origin or hint
    args = typing.get_args(hint)
    if kind in _SEQUENCES:
        item = args[0] if args and (kind is not tuple or args[-1] is Ellipsis) else None
        noun = f"a list of {_plural(item)}" if item is not None else "a list"
        if not isinstance(value, (list, tuple)):
            return noun
        if item is not None and any(_mismatch(item, v) is not None for v in value):
            return noun
        return None
    if kind in _MAPPINGS:
        return None if isinstance(value, dict) else "a mapping"
    return None


def _plural(hint: Any) -> str:
    words = {float: "numbers", int: "integers", bool: "booleans", str: "strings"}
    return words.get(hint, "values")
