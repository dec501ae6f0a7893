"""The master's generated movers and its read-only array copies (cosim.engine.movers)."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.engine.movers import FrozenArrays, block_writer, input_builder, output_reader, values_picker


def test_inputs_are_a_fresh_dict_scalars_first_in_slot_order_then_arrays():
    arrays = np.arange(6, dtype=np.float64)
    frozen = FrozenArrays(arrays, {2: 3})
    build = input_builder([("b", 2), ("a", 0), ("it's", 1)], [("ref", 2)])
    values = [10.0, 11.0, 12.0]
    first, second = build(values, frozen), build(values, frozen)
    assert list(first) == ["b", "a", "it's", "ref"]
    assert (first["b"], first["a"], first["it's"]) == (12.0, 10.0, 11.0)
    assert first is not second and first["ref"] is second["ref"]  # one copy, shared
    assert first["ref"].tolist() == [2.0, 3.0, 4.0] and not first["ref"].flags.writeable
    assert input_builder([], [])(values, frozen) == {}


def test_the_values_lane_inputs_are_a_tuple_in_the_given_order_arrays_shared():
    arrays = np.arange(6, dtype=np.float64)
    frozen = FrozenArrays(arrays, {2: 3, 5: 1})
    pick = values_picker([(False, 2), (True, 2), (False, 0), (True, 5)], frozen)
    values = [10.0, 11.0, 12.0]
    first, second = pick(values), pick(values)
    assert type(first) is tuple and first[0] == 12.0 and first[2] == 10.0
    assert first[1].tolist() == [2.0, 3.0, 4.0] and not first[1].flags.writeable
    assert first[1] is second[1] and first[3].tolist() == [5.0]
    assert values_picker([(False, 1)], frozen)(values) == (11.0,)
    assert values_picker([(False, 1), (False, 0)], frozen)(values) == (11.0, 10.0)
    assert values_picker([], frozen)(values) == ()


def test_outputs_are_read_as_floats_in_order_and_bad_ones_raise():
    read = output_reader(["y", "x"])
    assert read({"x": 1, "y": np.float64(2.5), "z": 0.0}) == [2.5, 1.0]
    assert all(type(v) is float for v in read({"x": 1, "y": True}))
    assert output_reader([])({}) == []
    for bad in ({"x": 1.0}, [1.0, 2.0], {"x": 1.0, "y": "two"}):
        with pytest.raises((KeyError, TypeError, ValueError)):
            read(bad)


def test_a_block_is_copied_once_and_each_reader_gets_a_read_only_view():
    arrays = np.arange(10, dtype=np.float64)
    frozen = FrozenArrays(arrays, {0: 2, 2: 3, 7: 2}, blocks=[(0, 5)])
    first = frozen[2]
    assert first.tolist() == [2.0, 3.0, 4.0] and not first.flags.writeable
    assert 0 in frozen and frozen[0].base is first.base  # the block's other slot, same copy
    assert frozen[7].tolist() == [7.0, 8.0]  # outside any block: a copy of its own
    with pytest.raises(ValueError):
        first[0] = 1.0
    arrays[0:5] = -1.0  # the owner writes: the copies it held are dropped, new ones made on read
    assert first.tolist() == [2.0, 3.0, 4.0]
    frozen.pop(0), frozen.pop(2)
    assert frozen[0].tolist() == [-1.0, -1.0] and frozen[2].tolist() == [-1.0] * 3


def test_a_block_of_array_outputs_is_written_in_one_copy_as_port_by_port():
    write = block_writer([("a", 2, 3), ("b", 5, 2), ("c", 7, 1)])
    arrays, expected = np.full(9, -1.0), np.full(9, -1.0)
    outputs = {"a": np.array([0.5, 1.5, 2.5]), "b": [3, 4], "c": np.array([True]), "x": 1.0}
    assert write(arrays, outputs) is True
    for name, offset, size in (("a", 2, 3), ("b", 5, 2), ("c", 7, 1)):
        expected[offset:offset + size] = outputs[name]
    assert arrays.tobytes() == expected.tobytes()


@pytest.mark.parametrize("bad", [
    {"b": [3.0, 4.0]},                                        # a missing
    {"a": np.zeros(2), "b": np.zeros(3)},                     # the sizes swapped, the total the same
    {"a": np.zeros((3, 1)), "b": np.zeros((2, 1))},           # not 1-D
    {"a": "abc", "b": [1.0, 2.0]},                            # text
    {"a": np.array([1, 2, 3], dtype=complex), "b": [1.0, 2.0]},   # not safely float64
    {"a": [1.0, None, 2.0], "b": [1.0, 2.0]},
])
def test_a_block_it_cannot_vouch_for_is_left_to_the_port_by_port_path(bad):
    write = block_writer([("a", 0, 3), ("b", 3, 2)])
    assert write(np.zeros(5), bad) is False
    assert write(np.zeros(5), [1.0, 2.0]) is False           # not a mapping


def test_only_two_or_more_outputs_side_by_side_in_port_order_are_a_block():
    assert block_writer([("a", 0, 3)]) is None
    assert block_writer([("a", 0, 3), ("b", 4, 2)]) is None   # a gap
    assert block_writer([("b", 3, 2), ("a", 0, 3)]) is None   # not in port order
    assert block_writer([]) is None


class _TakesOverConcatenate:
    """A sequence type whose __array_function__ answers np.concatenate without writing `out`."""

    def __init__(self, values):
        self.values = values

    def __len__(self):
        return len(self.values)

    def __array_function__(self, func, types, args, kwargs):
        return np.array(self.values, dtype=float)


def test_a_block_whose_concatenation_is_taken_over_is_not_vouched_for():
    write = block_writer([("a", 0, 2), ("b", 2, 1)])
    assert write(np.zeros(3), {"a": _TakesOverConcatenate([1.0, 2.0]), "b": [3.0]}) is False
