"""In-process hosting of Python components (the `inproc` transport).

`PythonComponentLaunch` (from `cosim.transport.launch`) says which component to host and
how; `InprocComponent` imports the class, constructs it with the scenario
parameters and drives it in this process behind the
`cosim.engine.hosting.HostedComponent` protocol. `describe_exception` is the one-line
text of a component's exception, shared with the Zenoh runner.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping, Sequence, Set

from cosim.component import (Component, ComponentError, Port, Value, constructing_for, ports_by_name,
                             values_step)
from cosim.errors import ComponentFailure, UserError, did_you_mean
from cosim.transport.launch import PythonComponentLaunch  # re-exported: its historical home
from cosim.transport.parameters import ParameterProblem, check_parameters  # ParameterProblem re-exported

# What a component's code may raise that fails the component: sys.exit() in a step or a
# module must not end the host's process (nor set its exit status). KeyboardInterrupt is
# not here: in the master's process it is the user's Ctrl-C.
USER_CODE_ERRORS = (Exception, SystemExit)


def import_component_class(class_path: str, component: str) -> type[Component]:
    """Import "module:Class" and check it is a Component subclass.

    Args:
        class_path: "package.module:ClassName".
        component: the component's scenario name, for error messages.
    """
    module_name, sep, class_name = class_path.partition(":")
    if not sep or not module_name or not class_name:
        raise UserError(f"component {component!r}: python class {class_path!r} "
                        f"is not of the form 'module:Class'")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise UserError(f"component {component!r}: cannot import module "
                        f"{module_name!r}: {exc}") from exc
    except USER_CODE_ERRORS as exc:  # the module's own code failed while it was imported
        raise UserError(f"component {component!r}: importing module {module_name!r} failed"
                        f"{_where_raised(exc)}: {describe_exception(exc)}") from exc
    cls = getattr(module, class_name, None)
    if cls is None:
        classes = sorted(name for name, value in vars(module).items()
                         if isinstance(value, type) and issubclass(value, Component)
                         and value is not Component and not name.startswith("_"))
        raise UserError(f"component {component!r}: module {module_name!r} has no class "
                        f"{class_name!r}" + did_you_mean(class_name, classes)
                        + (f"; its components: {', '.join(classes)}" if classes else ""))
    if not isinstance(cls, type) or not issubclass(cls, Component):
        raise UserError(f"component {component!r}: {class_path!r} is not a "
                        f"cosim.component.Component subclass")
    return cls


def _where_raised(exc: BaseException) -> str:
    """" (FILE, line N)" of the innermost frame that raised `exc`, for a module's own
    error; "" for a SyntaxError, whose message names them already."""
    import traceback

    frames = traceback.extract_tb(exc.__traceback__)
    if isinstance(exc, SyntaxError) or not frames:
        return ""
    return f" ({frames[-1].filename}, line {frames[-1].lineno})"


def _problem_of(launch: PythonComponentLaunch, exc: Exception) -> ParameterProblem | None:
    """The parameter a constructor's error message starts with ("ke[0] must be > 0",
    "parameter road.radius: ..."), if any; the problem keeps the field path it names."""
    message = str(exc)
    text = message.removeprefix("parameter ")
    for name in sorted(map(str, launch.parameters), key=len, reverse=True):
        if text.startswith(name) and text[len(name):len(name) + 1] in ("", ":", ".", "[", " "):
            problem = text if isinstance(exc, ComponentError) else describe_exception(exc)
            return ParameterProblem(launch.name, name, problem)
    return None


def construct_component(launch: PythonComponentLaunch, load_beside: bool = False) -> Component:
    """Import and construct the component of `launch`, checking its ports.

    Args:
        launch: what to construct.
        load_beside: the constructor may load a costly part on a thread beside the run
            (`cosim.component.may_load_beside`): a host whose component waits between steps.
    Raises:
        UserError naming the component when the class is missing, rejects its
        parameters or declares invalid ports.
    """
    cls = import_component_class(launch.class_path, launch.name)
    check_parameters(cls, launch)
    try:
        with constructing_for(launch.steps, load_beside):
            instance = cls(**dict(launch.parameters))
        ports_by_name(tuple(instance.inputs))
        ports_by_name(tuple(instance.outputs))
    except (ComponentError, ValueError) as exc:
        problem = _problem_of(launch, exc)
        if problem is not None:
            raise problem from exc
        if not isinstance(exc, ComponentError):
            raise UserError(f"component {launch.name!r}: constructor failed: "
                            f"{describe_exception(exc)}") from exc
        raise UserError(f"component {launch.name!r}: {exc}") from exc
    except TypeError as exc:
        raise UserError(f"component {launch.name!r}: bad parameters for "
                        f"{launch.class_path}: {exc}") from exc
    except USER_CODE_ERRORS as exc:  # user code in __init__: report it, no traceback
        raise UserError(f"component {launch.name!r}: constructor failed: "
                        f"{describe_exception(exc)}") from exc
    for port in (*instance.inputs, *instance.outputs):
        if not isinstance(port, Port) or port.size < 1:
            raise UserError(f"component {launch.name!r}: invalid port declaration {port!r}")
    return instance


class InprocComponent:
    """A Python component hosted in the master's own process.

    Exceptions raised by the component's `initialize`/`step` become
    `ComponentFailure` naming the component, the tick and the cause. A
    component that defines `step_values` and has no array output is offered
    on the master's values lane (`value_names`, `step_values`); else
    `value_names` is None and the master steps it on mappings.
    """

    def __init__(self, launch: PythonComponentLaunch) -> None:
        """Construct the component described by `launch` (see construct_component)."""
        self.launch = launch
        self.name = launch.name
        self.period_ticks = int(launch.period_ticks)
        self.component = construct_component(launch)
        self.inputs: tuple[Port, ...] = tuple(self.component.inputs)
        self.outputs: tuple[Port, ...] = tuple(self.component.outputs)
        self._step_values = values_step(self.component)
        self.value_names: tuple[tuple[str, ...], tuple[str, ...]] | None = None
        if self._step_values is not None:
            self.value_names = (tuple(p.name for p in self.inputs), tuple(p.name for p in self.outputs))
        self._last: tuple[int | None, float] = (None, 0.0)  # (tick, t) of the last call, for finish() errors

    def use_outputs(self, names: Set[str]) -> None:
        """Tell the component which outputs the run reads (`Component.use_outputs`)."""
        try:
            self.component.use_outputs(frozenset(names))
        except USER_CODE_ERRORS as exc:
            raise ComponentFailure(self.name, None, 0.0,
                                   f"use_outputs() failed: {describe_exception(exc)}") from exc

    def start(self, t0: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Call the component's `initialize(t0, inputs)`."""
        self._last = (None, t0)
        try:
            return self.component.initialize(t0, inputs)
        except USER_CODE_ERRORS as exc:  # any failure of user code is reported, not raised raw
            raise ComponentFailure(self.name, None, t0, describe_exception(exc)) from exc

    def step(self, tick: int, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Call the component's `step(t, inputs)`."""
        self._last = (tick, t)
        try:
            return self.component.step(t, inputs)
        except USER_CODE_ERRORS as exc:
            raise ComponentFailure(self.name, tick, t, describe_exception(exc)) from exc

    def step_values(self, tick: int, t: float, inputs: Sequence[Value]) -> Sequence[float]:
        """Call the component's `step_values(t, inputs)` (the master's values lane, see `value_names`)."""
        self._last = (tick, t)
        try:
            return self._step_values(t, inputs)
        except USER_CODE_ERRORS as exc:
            raise ComponentFailure(self.name, tick, t, describe_exception(exc)) from exc

    def stop(self) -> dict[str, float]:
        """Call the component's `finish()` and return its metrics."""
        try:
            metrics = self.component.finish() or {}
        except USER_CODE_ERRORS as exc:
            raise ComponentFailure(self.name, *self._last,
                                   f"finish() failed: {describe_exception(exc)}") from exc
        return {str(k): float(v) for k, v in metrics.items()}


def describe_exception(exc: BaseException) -> str:
    """One line for an exception: its type (unless a ComponentError) and message.

    Args:
        exc: an exception raised by a component's code.
    """
    if isinstance(exc, ComponentError):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"
