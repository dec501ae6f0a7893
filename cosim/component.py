"""The Python component contract: declared ports, parameters, and a pure step.

A component knows nothing of transports. The master (in-process) or a thin
runner (in its own OS process, speaking Zenoh) hosts it and calls, in order:

    comp = SomeComponent(**parameters)      # parameters from the scenario YAML
    comp.inputs, comp.outputs               # port declarations, fixed after __init__
    comp.use_outputs(names)                 # optional: the outputs something reads
    outputs_0 = comp.initialize(t0, inputs_0)
    outputs_k = comp.step(t_k, inputs_k)    # every period, t_k = t0 + k * tick

`inputs` is a mapping from input port name to a Python float (size 1) or a
read-only float64 numpy array of the declared size. The returned mapping must
hold every output port: a float for size 1, a 1-D float64 array of the declared
size otherwise. Returning a missing name, a wrong size or a non-finite value is
an error the master reports with the component's name and the tick.

`step` receives the values of the inputs at time t (Gauss-Seidel: the plant has
already been advanced to t) and returns the outputs valid from t until its next
step. The component keeps its own state between calls.

`use_outputs` tells the component, once before `initialize`, which of its
outputs the run reads: every scalar output, and each array output that is
connected to an input, recorded, or shown by an extra observer (with one, such
as the Foxglove live view, every output counts as read). A component whose
unread outputs are costly may skip computing them; it must still return them,
finite and of the declared size (holding one value is simplest), and its read
outputs must not change. The default ignores the call.

A component whose outputs are all scalars may also define the same step on
plain sequences, which the in-process host then calls instead of `step` (no
mapping built on either side; `initialize` keeps the mapping):

    values_k = comp.step_values(t_k, inputs_k)  # optional

`inputs_k` is a tuple with one value per declared input, in `inputs` order:
the float or read-only array the mapping would hold. The result is a sequence
(list or tuple) of Python floats, one per declared output, in `outputs` order.
It must be exactly what `step` returns, the same state change included: write
one in terms of the other (`step` as `dict(zip(names, self.step_values(...)))`).
The master tests the result with one sum: a result that does not add up to a
float (numpy scalars in it) is converted with `float()` as `step`'s mapping
would be, but values are not looked at one by one, so an int among floats
stays an int in the store. Over Zenoh the component is stepped with `step`.

A class names its parameter model with `ModelReference("module:Name")`, imported
when first read: a component process, which only constructs and steps its
component, then starts without pydantic.

While its host constructs it, a component may ask `expected_steps()` how many
steps the process that hosts it will ask of it: the run's, when the process
hosts only that run (a component process; the master's own process under `cosim
run`); in a sweep's own Dask workers, the run's times the sweep's samples (an
estimate: a worker runs some of them, and samples that vary the duration or a
period differ in length); else None (a Python session may run again). A component with a costly
set-up that only pays off over many steps (loading compiled code) can then do
without it for a short run.

A host whose component waits between steps (a component process: its thread sits
in the transport's receive while the rest of the run computes) and that may use more
than one CPU also tells the constructor `may_load_beside()`: the component may then
start that set-up on a thread of its own (`start_beside`, from cosim.beside) and step
without it until it is ready, so that tick 0 does not wait for it. The steps must give
the same results either way. In the master's own process it is False: the loop would
share the interpreter with the set-up. A host that pins its lockstep chain to one CPU
gives such a thread the other CPUs (it works beside the lockstep, not in it).
"""

from __future__ import annotations

import contextlib
import contextvars
import importlib
from collections.abc import Callable, Iterator, Mapping, Sequence, Set
from dataclasses import dataclass
from typing import Any, ClassVar, Union

import numpy as np

from cosim.beside import BESIDE_THREAD_PREFIX, start_beside  # noqa: F401 - part of the contract

Value = Union[float, np.ndarray]


class ComponentError(Exception):
    """A user-facing error raised by a component (bad parameter, bad input).

    The message is shown as is, prefixed with the component's name; no traceback.
    """


@dataclass(frozen=True)
class Port:
    """One declared input or output signal.

    Args:
        name: signal name, snake_case, unique among the component's ports.
        size: 1 for a scalar, N > 1 for a fixed-size float64 array.
        unit: SI unit string as in the FMU unit definitions ("m", "rad", "m/s", "1").
        description: one line for humans and for the recorder's manifest.
        default: value an unconnected input holds (scalars; arrays get zeros).
        type: the FMI type of the signal's values ("Float64" for Python
            components and FMI 2 Real; else an FMU's variable type, e.g.
            "Integer", "Int32", "Boolean", see `cosim.signal_types`); the store
            holds every type as float64.
    """

    name: str
    size: int = 1
    unit: str = "1"
    description: str = ""
    default: float = 0.0
    type: str = "Float64"

    def zero(self) -> Value:
        """The default value of this port (float or zero array)."""
        if self.size == 1:
            return float(self.default)
        return np.full(self.size, float(self.default))


class Component:
    """Base class of every Python component (controllers, planner, sources).

    Subclasses set `inputs` and `outputs` (tuples of Port), either as class
    attributes or in `__init__` when they depend on parameters, and override
    `step`. `initialize` defaults to calling `step` at t0.

    Optional, not defined here: `step_values(t, inputs) -> sequence of floats`,
    the same step as `step` on a tuple of the inputs in declared order,
    returning the outputs in declared order (all scalars); the in-process host
    calls it instead of `step` (see the module docstring).

    Class attributes:
        default_period: period in seconds used when the scenario names none
            (None: every master tick).
        parameters_model: optional pydantic model of the constructor's keyword
            arguments (extra fields forbidden, each described with unit, default
            and range), or a `ModelReference` to it. For the shipped classes
            (cosim.scenario.known_classes) the scenario loader validates
            `parameters:` with it, and the scenario JSON schema describes them;
            None: checked against the constructor's annotations when the
            component is constructed.
    """

    inputs: tuple[Port, ...] = ()
    outputs: tuple[Port, ...] = ()
    default_period: ClassVar[float | None] = None
    parameters_model: ClassVar[type | None] = None

    def use_outputs(self, names: Set[str]) -> None:
        """Called once before `initialize` with the names of the outputs the run reads (see
        the module docstring); the others may be held instead of computed. Default: ignored."""

    def initialize(self, t0: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Set up state at t0 from the initial inputs and return the initial outputs."""
        return self.step(t0, inputs)

    def step(self, t: float, inputs: Mapping[str, Value]) -> dict[str, Value]:
        """Advance to time t with the given inputs; return every output."""
        raise NotImplementedError

    def finish(self) -> dict[str, float]:
        """Called once after the last step; may return scalar metrics for the run."""
        return {}


class ModelReference:
    """A class attribute naming a model as "module:Name", which reading imports.

    `parameters_model = ModelReference("my_pkg.parameters:MyParameters")` reads as
    the model class itself (`MyController.parameters_model`), but only the
    scenario loader and the schema read it: the component's module does not
    import the model, nor pydantic (about 0.15 s of a component process's start).

    Args:
        path: "module:Name" of the model.
    """

    def __init__(self, path: str) -> None:
        self.path = path

    def __get__(self, instance: Any, owner: type | None = None) -> Any:
        module, _, name = self.path.partition(":")
        return getattr(importlib.import_module(module), name)


def values_step(component: Component) -> Callable[[float, tuple], Sequence[float]] | None:
    """The component's `step_values` (bound), if it defines one and all its outputs are scalars."""
    step_values = getattr(component, "step_values", None)
    if not callable(step_values) or any(port.size != 1 for port in component.outputs):
        return None
    return step_values


def frozen_copy(value: Any) -> np.ndarray:
    """A read-only float64 copy of `value` (what a host hands out, and what a component may hold)."""
    array = np.array(value, dtype=np.float64)
    array.flags.writeable = False
    return array


def is_frozen(value: Any) -> bool:
    """Whether `value`'s bytes cannot change: a read-only float64 array that owns its data, or a
    read-only view of one (the in-process master hands out views of one copy of a component's
    array block). Such an array, received again, is known to hold the same values."""
    if not isinstance(value, np.ndarray) or value.flags.writeable or value.dtype != np.float64:
        return False
    base = value.base
    return value.flags.owndata or (isinstance(base, np.ndarray) and base.flags.owndata
                                   and not base.flags.writeable)


_expected_steps: contextvars.ContextVar[int | None] = contextvars.ContextVar("expected_steps",
                                                                           default=None)


def expected_steps() -> int | None:
    """During the construction of a component by its host: the steps its process will ask
    of it (see the module docstring); None when unknown, and outside a construction."""
    return _expected_steps.get()


_may_load_beside: contextvars.ContextVar[bool] = contextvars.ContextVar("may_load_beside", default=False)


def may_load_beside() -> bool:
    """During the construction of a component by its host: whether the component may load a
    costly part on a thread beside the run (`start_beside`) and step without it meanwhile
    (see the module docstring); False outside a construction."""
    return _may_load_beside.get()


@contextlib.contextmanager
def constructing_for(steps: int | None, load_beside: bool = False) -> Iterator[None]:
    """Around a host's construction of a component: `expected_steps()` gives `steps`,
    `may_load_beside()` gives `load_beside`."""
    token = _expected_steps.set(steps)
    beside = _may_load_beside.set(load_beside)
    try:
        yield
    finally:
        _may_load_beside.reset(beside)
        _expected_steps.reset(token)


def ports_by_name(ports: tuple[Port, ...]) -> dict[str, Port]:
    """Index a port tuple by name, rejecting duplicates."""
    index: dict[str, Port] = {}
    for port in ports:
        if port.name in index:
            raise ComponentError(f"port {port.name!r} declared twice")
        index[port.name] = port
    return index
