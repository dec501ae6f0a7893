"""The lockstep master: integer ticks, multi-rate periods, Gauss-Seidel order.

Time is an integer tick k and t = t0 + k * tick (never accumulated). A
component with a period of n ticks steps at k = n, 2n, ...; at k = 0 every
component starts (initialization phase, same order). Between its steps a
component's outputs are held (zero-order hold) in the signal store
(`cosim.engine.signals`). A component without direct feedthrough (an FMU) steps
from t_{k-n} to t_k with its inputs as they stand at the start of tick k,
i.e. the values of tick k-1 (for n = 1: the implicit one-tick delay of the
feedback edge). After every call the outputs are checked: a missing signal,
a wrong size or a non-finite value stops the run with a `ComponentFailure`
naming the component, the tick, the signal and the value.

Observers (recorder, progress bar, live publisher, real-time pacer) see the
signal store (`values` list of scalars, `arrays` numpy buffer, indexed by
`master.layout`) after every tick; they must not modify it.

Before each call of a component the master writes one 64-bit word, the
breadcrumb (`crumb_code`: which component, which call, which tick), and 0 when
the tick's calls are done: a plain memory write, read by a supervisor in
another process through shared memory, which so knows what the master was
doing if it dies or hangs inside a component's native code.

A host whose `step` raises `cosim.errors.StopRequested` (an FMU asking to
terminate) ends the run normally: its outputs are used, the tick completes
and is observed, and `stop_request` says who asked.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence, Set
from dataclasses import dataclass
from math import isfinite as _isfinite
from typing import Any, Protocol

import numpy as np

from cosim.errors import ComponentFailure, StopRequested
from cosim.engine.crumb import CALL_START, CALL_STEP, CALL_STOP, crumb_code
from cosim.engine.hosting import HostedComponent
from cosim.engine.movers import FrozenArrays, block_writer, input_builder, output_reader, values_picker
from cosim.engine.schedule import step_order
from cosim.engine.signals import ComponentSlots, SignalLayout, build_layout, transformed
from cosim.engine.values import lane_result_problem, value_problem

_add_reduce = np.add.reduce


class Observer(Protocol):
    """Something that watches the run tick by tick."""

    def begin(self, master: "Master") -> None:
        """Called once before the initialization phase."""

    def after_tick(self, tick: int, t: float, values: list[float], arrays: np.ndarray) -> None:
        """Called after tick `tick` (0 = after initialization); read-only store."""


@dataclass
class _Plan:
    """Everything the loop needs for one component, precomputed."""

    name: str
    hosted: HostedComponent
    period: int
    slots: ComponentSlots
    out_start: int
    out_stop: int
    frozen: FrozenArrays  # the master's read-only array copies, which the lane's mover reads
    index: int = 0  # position in step order, for the breadcrumb

    def __post_init__(self) -> None:
        self.crumb_step = crumb_code(self.index, CALL_STEP)
        self.step = self.hosted.step
        # (values, frozen arrays) -> the inputs mapping; outputs mapping -> scalar outputs as floats
        self.build_inputs = input_builder(
            list(zip(self.slots.in_scalar_names, self.slots.in_scalar_index)),
            [(name, off) for name, off, _ in self.slots.in_arrays])
        self.read_outputs = output_reader(self.slots.out_scalar_names)
        self.has_array_outputs = bool(self.slots.out_arrays)
        self.transforms = self.slots.transforms  # empty unless an input edge has scale/offset
        # the values lane, when the host offers it for these ports: values -> the inputs tuple
        self.step_values, self.pick_values = _values_lane(self.hosted, self.slots, self.frozen) or (None, None)
        self.out_count = self.out_stop - self.out_start
        # a host that vouches for its lane's results (a list of as many Python floats as outputs)
        self.lane_exact = bool(getattr(self.hosted, "values_exact", False))
        self.out_block = _array_block(self.slots.out_arrays)
        self.write_arrays = block_writer(self.slots.out_arrays)   # None: port by port


class Master:
    """Drives hosted components in lockstep over the signal store.

    Args:
        components: name -> HostedComponent, in declaration order.
        edges: resolved connections (src, src_port, dst, dst_port, delay).
        tick: base step in seconds (> 0).
        total_ticks: number of ticks after the initialization phase.
        t0: start time.
        observers: called after every tick (see Observer).
        trace: when True, `self.trace` lists (tick, component, inputs copy)
            for every start and step, for tests.
        crumb: a writable memoryview of int64 (format "q") whose item 0 gets
            the breadcrumb (shared memory a supervisor reads); None: a private word.
        outputs_read: component -> the outputs the run reads
            (`cosim.engine.wiring.outputs_read`), told to every host that has
            `use_outputs` before any starts; None: nothing is told.
    """

    def __init__(self, components: Mapping[str, HostedComponent], edges: Iterable[Any],
                 tick: float, total_ticks: int, t0: float = 0.0,
                 observers: Sequence[Observer] = (), trace: bool = False,
                 crumb: Any = None, outputs_read: Mapping[str, Set[str]] | None = None) -> None:
        edges = list(edges)
        self.components = dict(components)
        self.tick = float(tick)
        self.total_ticks = int(total_ticks)
        self.t0 = float(t0)
        self.observers = list(observers)
        self.outputs_read = outputs_read
        self.trace: list[tuple[int, str, dict[str, Any]]] | None = [] if trace else None
        self.layout: SignalLayout = build_layout(self.components, edges)
        feedthrough = {n: bool(getattr(c, "direct_feedthrough", True))
                       for n, c in self.components.items()}
        self.order = step_order(list(self.components), feedthrough, edges)
        self.values: list[float] = list(self.layout.initial_values)
        self.arrays: np.ndarray = self.layout.initial_arrays.copy()
        # read-only array objects by offset in `arrays`, handed to readers without a
        # copy: a new object is made each time the owner writes, never mutated
        self.ticks_done = -1  # last completed tick; -1 before initialization
        self.crumb = crumb if crumb is not None else memoryview(bytearray(8)).cast("q")
        self.stop_request: StopRequested | None = None  # a component asked to end the run
        self._frozen = FrozenArrays(
            self.arrays,
            {off: size for slots in self.layout.slots.values() for _, off, size in slots.in_arrays},
            [span for slots in self.layout.slots.values() for span in _array_block(slots.out_arrays)])
        self._plans = [self._plan(i, name) for i, name in enumerate(self.order)]
        self._scalar_delays = self.layout.scalar_delays
        self._array_delays = self.layout.array_delays
        self._delayed_transforms = self.layout.delayed_transforms
        self._has_delays = bool(self._scalar_delays or self._array_delays
                                or self._delayed_transforms)
        self._due = _due_table(self._plans)
        self._started: list[str] = []  # components whose start was called, to stop

    def _plan(self, index: int, name: str) -> _Plan:
        comp = self.components[name]
        period = int(comp.period_ticks)
        if period < 1:
            raise ValueError(f"component {name!r}: period_ticks must be >= 1, got {period}")
        slots = self.layout.slots[name]
        start = slots.out_scalar_start
        return _Plan(name, comp, period, slots, start, start + len(slots.out_scalar_names),
                     self._frozen, index)

    def value(self, component: str, signal: str) -> Any:
        """Current value of an output signal (float, or a copy of the array)."""
        offset, size = self.layout.outputs[(component, signal)]
        if size == 1:
            return self.values[offset]
        return self.arrays[offset:offset + size].copy()

    def time_of(self, tick: int) -> float:
        """t = t0 + tick * h, computed from the integer tick."""
        return self.t0 + tick * self.tick

    def run(self, after_initialize: Callable[[], None] | None = None) -> None:
        """Initialize, then run every tick up to total_ticks.

        Args:
            after_initialize: called once when tick 0 (the initialization phase)
                is complete, e.g. to time the start-up.
        """
        try:
            self.initialize()
            if after_initialize is not None:
                after_initialize()
            for k in range(1, self.total_ticks + 1):
                self.step_tick(k)
                if self.stop_request is not None:
                    break
        finally:
            self.crumb[0] = 0  # out of any call: whatever follows is the caller's

    def initialize(self) -> None:
        """Initialization phase at t0: start every component in step order."""
        for observer in self.observers:
            observer.begin(self)
        t0 = self.t0
        if self.outputs_read is not None:
            self._tell_outputs_read()
        for plan in self._plans:
            inputs = self._gather(plan)
            if self.trace is not None:
                self.trace.append((0, plan.name, _copy_inputs(inputs)))
            self._started.append(plan.name)
            self.crumb[0] = crumb_code(plan.index, CALL_START)
            outputs = plan.hosted.start(t0, inputs)
            self.crumb[0] = 0
            self._scatter(plan, outputs, None, t0)
        self._finish_tick(0, t0)

    def _tell_outputs_read(self) -> None:
        outputs_read = self.outputs_read
        assert outputs_read is not None
        for plan in self._plans:
            tell = getattr(plan.hosted, "use_outputs", None)
            if tell is not None:
                self.crumb[0] = crumb_code(plan.index, CALL_START)
                tell(outputs_read[plan.name])
        self.crumb[0] = 0

    def step_tick(self, k: int) -> None:
        """Run tick k: refresh delayed inputs, step the due components in order.

        This is the hot loop: a host that offers the values lane is stepped on plain
        sequences (`_step_on_values`), the others on mappings (`_step_on_mapping`).
        """
        t = self.t0 + k * self.tick
        if self._has_delays:
            self._refresh_delays()
        values = self.values
        due = self._due
        plans = (due[k % len(due)] if due is not None
                 else [p for p in self._plans if k % p.period == 0])
        crumb, tick_bits = self.crumb, k << 20
        for plan in plans:
            if plan.transforms:
                _apply_transforms(plan.transforms, values)
            crumb[0] = tick_bits | plan.crumb_step
            if plan.step_values is not None and self.trace is None:
                self._step_on_values(plan, k, t, values)
            else:
                self._step_on_mapping(plan, k, t, values)
        crumb[0] = 0
        self.ticks_done = k
        for observer in self.observers:
            observer.after_tick(k, t, values, self.arrays)

    def _step_on_values(self, plan: _Plan, k: int, t: float, values: list[float]) -> None:
        """One step through the host's values lane: a tuple in, scalar outputs out, no mapping."""
        try:
            new = plan.step_values(k, t, plan.pick_values(values))
        except StopRequested as request:  # the tick completes; `run` ends after it
            self.stop_request = request
            self._scatter(plan, request.outputs, k, t)
            return
        if plan.lane_exact:  # floats, as many as outputs: only finiteness to test
            fine = _isfinite(sum(new)) or all(map(_isfinite, new))
        else:
            try:  # one sum tests them all: floats (a numpy scalar makes it another type), finite
                fine = (len(new) == plan.out_count and type(total := sum(new, 0.0)) is float
                        and (_isfinite(total) or all(map(_isfinite, new))))
            except Exception:  # not a sequence, or not numbers
                fine = False
        if not fine:
            new = _lane_outputs(plan, new, k, t)
        values[plan.out_start:plan.out_stop] = new

    def _step_on_mapping(self, plan: _Plan, k: int, t: float, values: list[float]) -> None:
        """One step through the host's `step`: inputs as a mapping, outputs checked and stored."""
        inputs = plan.build_inputs(values, self._frozen)
        if self.trace is not None:
            self.trace.append((k, plan.name, _copy_inputs(inputs)))
        try:
            outputs = plan.step(k, t, inputs)
        except StopRequested as request:  # the tick completes; `run` ends after it
            self.stop_request, outputs = request, request.outputs
        try:
            new = plan.read_outputs(outputs)
        except Exception:  # missing name, not a mapping, not a number: diagnose
            raise _diagnose(plan, outputs, k, t) from None
        if not _isfinite(sum(new)) and not all(map(_isfinite, new)):
            raise _diagnose(plan, outputs, k, t)
        values[plan.out_start:plan.out_stop] = new
        if plan.has_array_outputs:
            self._scatter_arrays(plan, outputs, k, t)

    def _refresh_delays(self) -> None:
        values, arrays = self.values, self.arrays
        for src, dst in self._scalar_delays:
            values[dst] = values[src]
        _apply_transforms(self._delayed_transforms, values)
        for src, dst, size in self._array_delays:
            arrays[dst:dst + size] = arrays[src:src + size]
            self._frozen.pop(dst, None)

    def _finish_tick(self, k: int, t: float) -> None:
        self.ticks_done = k
        for observer in self.observers:
            observer.after_tick(k, t, self.values, self.arrays)

    def _gather(self, plan: _Plan) -> dict[str, Any]:
        """The inputs of one component as a fresh mapping (floats, read-only arrays)."""
        _apply_transforms(plan.transforms, self.values)
        return plan.build_inputs(self.values, self._frozen)

    def _scatter(self, plan: _Plan, outputs: Any, k: int | None, t: float) -> None:
        """Check a component's outputs and write them into the store."""
        try:
            values = plan.read_outputs(outputs)
        except Exception:  # missing name, not a mapping, not a number: diagnose
            raise _diagnose(plan, outputs, k, t) from None
        if not all(map(_isfinite, values)):
            raise _diagnose(plan, outputs, k, t)
        self.values[plan.out_start:plan.out_stop] = values
        self._scatter_arrays(plan, outputs, k, t)

    def _scatter_arrays(self, plan: _Plan, outputs: Any, k: int | None, t: float) -> None:
        """Write a component's array outputs straight into the store, then test them once.

        The read-only copies readers get are made when a reader gathers them
        (`FrozenArrays`); a rejected output fails the run (the store is not read again).
        """
        arrays, frozen = self.arrays, self._frozen
        if plan.write_arrays is not None and plan.write_arrays(arrays, outputs):
            for _, off, _ in plan.slots.out_arrays:
                frozen.pop(off, None)
        else:
            for name, off, size in plan.slots.out_arrays:
                try:
                    value = outputs[name]
                    if getattr(value, "shape", None) != (size,) and np.shape(value) != (size,):
                        raise ValueError(name)
                    arrays[off:off + size] = value
                except Exception:
                    raise _diagnose(plan, outputs, k, t) from None
                frozen.pop(off, None)
        for start, stop in plan.out_block:  # one sum per block; each element only if it is not finite
            block = arrays[start:stop]
            if not _isfinite(_add_reduce(block)) and not np.isfinite(block).all():
                raise _diagnose(plan, outputs, k, t)

    def stop_all(self) -> tuple[dict[str, dict[str, float]], list[ComponentFailure]]:
        """Stop every started component (reverse step order), even after a failure.

        Returns:
            (metrics by component, the failures of components whose stop failed: a
            host's own ComponentFailure, or one made here at the last tick).
        """
        metrics: dict[str, dict[str, float]] = {}
        failures: list[ComponentFailure] = []
        started = set(self._started)
        last = max(self.ticks_done, 0)
        for plan in reversed(self._plans):
            if plan.name not in started:
                continue
            self.crumb[0] = crumb_code(plan.index, CALL_STOP, last)
            try:
                metrics[plan.name] = dict(plan.hosted.stop() or {})
            except ComponentFailure as exc:  # keep stopping the others
                if exc.tick is None and self.ticks_done > 0:  # a host that did not say when
                    exc = ComponentFailure(exc.component, last, self.t0 + last * self.tick,
                                           exc.cause, exc.details)
                failures.append(exc)
            except Exception as exc:
                failures.append(ComponentFailure(
                    plan.name, last, self.t0 + last * self.tick, f"stop failed: {exc}",
                    {"kind": "exception", "exception": type(exc).__name__}))
            finally:
                self.crumb[0] = 0
        return metrics, failures


def _due_table(plans: Sequence[_Plan], limit: int = 4096) -> list[list[_Plan]] | None:
    """Plans due at each tick residue modulo the periods' lcm (in step order).

    None when the lcm exceeds `limit` (the loop then filters by period each tick).
    """
    cycle = math.lcm(*(p.period for p in plans)) if plans else 1
    if cycle > limit:
        return None
    return [[p for p in plans if r % p.period == 0] for r in range(cycle)]


def _values_lane(hosted: Any, slots: ComponentSlots,
                 frozen: FrozenArrays) -> tuple[Callable[..., Any], Callable] | None:
    """(the host's `step_values`, the mover of its inputs tuple) when the host offers the lane for
    exactly this component's ports (every input in declared order; scalar outputs only, in slot
    order), else None."""
    lane = getattr(hosted, "step_values", None)
    names = getattr(hosted, "value_names", None)
    if lane is None or names is None or slots.out_arrays:
        return None
    declared = tuple(port.name for port in hosted.inputs)
    if tuple(names) != (declared, tuple(slots.out_scalar_names)):
        return None
    sources = {name: (False, slot) for name, slot in zip(slots.in_scalar_names, slots.in_scalar_index)}
    sources.update((name, (True, offset)) for name, offset, _ in slots.in_arrays)
    return lane, values_picker([sources[name] for name in declared], frozen)


def _lane_outputs(plan: _Plan, new: Any, k: int, t: float) -> list[float]:
    """Outputs of the values lane that failed the quick test: as floats (what `float()` makes of each,
    as the mapping path reads them), or the failure naming the bad output."""
    problem = lane_result_problem(new, plan.out_count)
    if problem:
        raise ComponentFailure(plan.name, k, t, problem)
    outputs = dict(zip(plan.slots.out_scalar_names, new))
    try:
        floats = plan.read_outputs(outputs)
    except Exception:
        raise _diagnose(plan, outputs, k, t) from None
    if not all(map(_isfinite, floats)):
        raise _diagnose(plan, outputs, k, t)
    return floats


def _array_block(out_arrays: Sequence[tuple[str, int, int]]) -> list[tuple[int, int]]:
    """(start, stop) spans of `arrays` holding a component's array outputs: one when contiguous."""
    spans = sorted((off, off + size) for _, off, size in out_arrays)
    if spans and spans[-1][1] - spans[0][0] == sum(stop - start for start, stop in spans):
        return [(spans[0][0], spans[-1][1])]
    return spans


def _apply_transforms(transforms: Sequence[tuple], values: list[float]) -> None:
    """Write each transformed input slot from its source slot (see signals.Transform)."""
    for src, dst, scale, offset in transforms:
        values[dst] = transformed(values[src], scale, offset)


def _copy_inputs(inputs: Mapping[str, Any]) -> dict[str, Any]:
    return {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in inputs.items()}


def _diagnose(plan: _Plan, outputs: Any, k: int | None, t: float) -> ComponentFailure:
    """The precise reason a component's outputs were rejected."""
    if not isinstance(outputs, Mapping):
        return ComponentFailure(plan.name, k, t, f"returned {type(outputs).__name__}, "
                                f"expected a mapping of output signals")
    ports = [(n, 1) for n in plan.slots.out_scalar_names]
    ports += [(n, size) for n, _, size in plan.slots.out_arrays]
    for name, size in ports:
        if name not in outputs:
            return ComponentFailure(plan.name, k, t, f"output {name!r} missing")
        problem = value_problem(outputs[name], size)
        if problem:
            return ComponentFailure(plan.name, k, t, f"output {name!r} {problem}",
                                    {"kind": "bad_output", "output": name, "problem": problem})
    return ComponentFailure(plan.name, k, t, "invalid outputs")  # pragma: no cover
