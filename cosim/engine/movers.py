"""The master's per-component movers between the signal store and a component's mappings.

A component steps on a mapping of its inputs and returns a mapping of its
outputs (`cosim.component`), so the master builds one dict per call and reads
one per call. Generic code (`dict(zip(names, getter(values)))`, then a loop
over the array inputs; `list(map(float, getter(outputs)))`) spends most of the
master's time per tick in zip, map and the loop. The movers here are instead
generated once per component, as namedtuple and dataclasses generate their
methods: a dict display whose keys are the port names (as constants) and whose
values are subscripts of the store, and a list display of `float(outputs[name])`.
They do exactly what the generic code does, in the same order (scalar inputs in
slot order, then the array inputs), with a few bytecodes per port. For a host
on the master's values lane (`cosim.engine.hosting`) the inputs are a tuple
display instead, in the host's own port order (`values_picker`).

Array inputs are read from `FrozenArrays`, the read-only copies of the array
slots handed to readers: made when first read after their owner writes (a
dict's `__missing__`), shared by every reader until the next write. The array
outputs of one component that lie side by side in the store are copied at
once, on the first read of any of them: one copy of the block, and each reader
gets a read-only view of its slot in it. They are written at once too
(`block_writer`): one concatenation into the block instead of a copy per port.
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from cosim.component import frozen_copy
from cosim.engine.values import picker


class FrozenArrays(dict):
    """offset in the store's `arrays` -> a read-only float64 copy of that slot.

    A missing entry (never read, or dropped by `pop` when the slot was written)
    is made on first read from the store's current content: with every other
    read slot of its block (`blocks`), which the writer drops together.

    Args:
        arrays: the store's array buffer.
        sizes: offset -> size of every array slot that an input reads.
        blocks: (start, stop) spans of `arrays` whose slots are always written
            together (one component's contiguous array outputs).
    """

    def __init__(self, arrays: np.ndarray, sizes: Mapping[int, int],
                 blocks: Sequence[tuple[int, int]] = ()) -> None:
        super().__init__()
        self.arrays = arrays
        self.sizes = dict(sizes)
        # read offset -> (start, stop, [(offset, size) of the block's read slots])
        self.block_of: dict[int, tuple[int, int, list[tuple[int, int]]]] = {}
        for start, stop in blocks:
            members = [(off, size) for off, size in sorted(self.sizes.items())
                       if start <= off and off + size <= stop]
            if len(members) > 1:
                for off, _ in members:
                    self.block_of[off] = (start, stop, members)

    def __missing__(self, offset: int) -> np.ndarray:
        block = self.block_of.get(offset)
        if block is None:
            value = self[offset] = frozen_copy(self.arrays[offset:offset + self.sizes[offset]])
            return value
        start, stop, members = block
        copy = frozen_copy(self.arrays[start:stop])
        for off, size in members:
            self[off] = copy[off - start:off - start + size]  # views of a read-only copy
        return self[offset]


def input_builder(scalars: Sequence[tuple[str, int]],
                  arrays: Sequence[tuple[str, int]]) -> Callable[[list[float], FrozenArrays],
                                                                 dict[str, Any]]:
    """A function of (values, frozen) returning a component's inputs as a fresh dict.

    Args:
        scalars: (input name, slot in `values`) of the scalar inputs, in order.
        arrays: (input name, offset in `arrays`) of the array inputs, in order.
    """
    items = [f"{name!r}: values[{int(slot)}]" for name, slot in scalars]
    items += [f"{name!r}: frozen[{int(offset)}]" for name, offset in arrays]
    return _compile("build_inputs", "values, frozen", "{" + ", ".join(items) + "}")


def values_picker(sources: Sequence[tuple[bool, int]],
                  frozen: FrozenArrays) -> Callable[[list[float]], tuple]:
    """A function of `values` returning a component's inputs as a tuple (the values lane).

    Args:
        sources: per input, in the order the host wants them: (True, offset in
            `arrays`) for an array input, (False, slot in `values`) for a scalar.
        frozen: the read-only copies the array inputs are read from (bound in).
    """
    if not any(is_array for is_array, _ in sources):  # scalars only: one C call
        return picker([at for _, at in sources])
    items = [f"frozen[{int(at)}]" if is_array else f"values[{int(at)}]" for is_array, at in sources]
    return _compile("pick_values", "values", "(" + "".join(f"{item}, " for item in items) + ")",
                    frozen=frozen)


def block_writer(out_arrays: Sequence[tuple[str, int, int]]) -> Callable[[np.ndarray, Any], bool] | None:
    """For two or more array outputs that lie side by side in the store in port order: a function
    of (arrays, outputs) that writes them all in one copy (np.concatenate into the span) and
    returns True; False, with nothing promised written, when an output is missing, is not a
    sequence of its port's size or is not of a type numpy casts safely to float64 (the caller
    then writes them one by one, which diagnoses them). Else None: no such block.

    Args:
        out_arrays: (name, offset in `arrays`, size) of the array outputs, in port order.
    """
    if len(out_arrays) < 2:
        return None
    start = out_arrays[0][1]
    stop = start
    for _, offset, size in out_arrays:
        if offset != stop:
            return None
        stop += size
    pick = operator.itemgetter(*(name for name, _, _ in out_arrays))
    sizes = tuple(size for _, _, size in out_arrays)
    concatenate = np.concatenate

    def write(arrays: np.ndarray, outputs: Any) -> bool:
        try:
            fields = pick(outputs)
            if tuple(map(len, fields)) != sizes:
                return False
            span = arrays[start:stop]
            # `is span`: an output type that takes over np.concatenate (__array_function__)
            # may return something else and leave the span unwritten
            return concatenate(fields, out=span, casting="safe") is span
        except Exception:  # not a mapping, a name missing, not sequences, not numbers
            return False

    return write


def output_reader(names: Sequence[str]) -> Callable[[Any], list[float]]:
    """A function of a component's outputs mapping returning its scalar outputs as floats, in order.

    It raises what `float(outputs[name])` raises (missing name, not a mapping,
    not a number): the master then diagnoses the outputs.
    """
    return _compile("read_outputs", "outputs",
                    "[" + ", ".join(f"float(outputs[{name!r}])" for name in names) + "]")


def _compile(name: str, arguments: str, expression: str, **bound: Any) -> Callable[..., Any]:
    """def name(arguments): return expression, compiled; the names in it are literals (repr),
    `float` and the `bound` objects (globals of the function)."""
    source = f"def {name}({arguments}):\n    return {expression}\n"
    namespace: dict[str, Any] = {}
    exec(compile(source, f"<cosim.engine.movers.{name}>", "exec"), {"float": float, **bound}, namespace)
    return namespace[name]
