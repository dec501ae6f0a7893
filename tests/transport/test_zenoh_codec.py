"""Wire format of the Zenoh transport: bit-exact round trips, layout, error messages."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from cosim.component import Port
from cosim.transport.zenoh import config
from cosim.transport.zenoh.codec import (HEADER, CodecError, Kind, Layout, decode_json,
                                         encode_json, ports_from_json, ports_to_json)

PORTS = (Port("a"), Port("b", size=3), Port("c"), Port("d", size=2))


def random_finite(rng: np.random.Generator, n: int) -> np.ndarray:
    """Floats from random bit patterns (subnormals, huge, tiny, -0.0), NaN removed."""
    bits = rng.integers(0, 2**64, size=4 * n, dtype=np.uint64).view(np.float64)
    values = bits[~np.isnan(bits)][:n]
    assert values.size == n
    return values


def test_scalar_layout_round_trips_every_bit():
    rng = np.random.default_rng(11)
    layout = Layout(tuple(Port(f"s{i}") for i in range(8)), "input")
    special = [0.0, -0.0, 5e-324, -2.2250738585072014e-308, 1.7976931348623157e308,
               float("inf"), float("-inf"), 1 / 3]
    for row in [special, *random_finite(rng, 8 * 200).reshape(200, 8).tolist()]:
        values = dict(zip(layout.names, row))
        message = layout.encode(Kind.STEP, 7, 123456789012, 0.1 * 3, values)
        decoded = layout.decode(message)
        assert np.array(list(decoded.values())).tobytes() == np.array(row).tobytes()
        assert HEADER.unpack_from(message) == (Kind.STEP, 7, 123456789012, 0.1 * 3)


def test_array_layout_is_mask_scalars_then_arrays_and_exact():
    rng = np.random.default_rng(12)
    sender, receiver = Layout(PORTS), Layout(PORTS)
    flat = random_finite(rng, 7)
    values = {"d": flat[5:7], "a": flat[0], "c": flat[4], "b": flat[1:4]}  # any dict order
    message = sender.encode(Kind.OUTPUTS, 1, -1, 0.0, values)
    # one byte per array port (both sent), padded to 8; scalars a, c; arrays b, d
    assert message[HEADER.size:HEADER.size + 8] == bytes([1, 1, 0, 0, 0, 0, 0, 0])
    assert message[HEADER.size + 8:] == flat[[0, 4, 1, 2, 3, 5, 6]].astype("<f8").tobytes()
    decoded = receiver.decode(message)
    assert list(decoded) == ["a", "c", "b", "d"]   # scalars, then arrays: as the in-process master
    assert isinstance(decoded["a"], float) and isinstance(decoded["c"], float)
    assert decoded["b"].shape == (3,) and not decoded["b"].flags.writeable
    assert np.concatenate([[decoded["a"]], decoded["b"], [decoded["c"]], decoded["d"]]).tobytes() \
        == flat.tobytes()


def _frozen(values) -> np.ndarray:
    array = np.array(values, dtype=np.float64)
    array.flags.writeable = False
    return array


def test_an_array_with_the_same_bytes_is_held_and_the_receiver_gives_the_same_object():
    sender, receiver = Layout(PORTS), Layout(PORTS)
    b, d = _frozen([1.0, 2.0, 3.0]), [0.5, -0.0]
    first = receiver.decode(sender.encode(Kind.STEP, 1, 1, 0.01, {"a": 1.0, "b": b, "c": 2.0, "d": d}))
    # b: the same read-only object; d: a new list with the same bits: both held
    message = sender.encode(Kind.STEP, 2, 2, 0.02, {"a": 3.0, "b": b, "c": 4.0, "d": [0.5, -0.0]})
    assert message[HEADER.size:HEADER.size + 2] == bytes([0, 0])
    assert len(message) == HEADER.size + 8 + 2 * 8
    second = receiver.decode(message)
    assert (second["a"], second["c"]) == (3.0, 4.0)
    assert second["b"] is first["b"] and second["d"] is first["d"]
    # 0.0 == -0.0 but their bits differ: sent again, and the receiver has the new bits
    message = sender.encode(Kind.STEP, 3, 3, 0.03, {"a": 3.0, "b": b, "c": 4.0, "d": [0.5, 0.0]})
    assert message[HEADER.size:HEADER.size + 2] == bytes([0, 1])
    third = receiver.decode(message)
    assert third["b"] is first["b"] and third["d"].tobytes() == np.array([0.5, 0.0]).tobytes()


def _writeable(base: np.ndarray) -> np.ndarray:
    return base[:3]


def _read_only_view(base: np.ndarray) -> np.ndarray:
    view = base[:3]
    view.flags.writeable = False  # read-only, but its owner can still write
    return view


@pytest.mark.parametrize("sent", [_writeable, _read_only_view])
def test_an_array_changed_in_place_is_sent_again(sent):
    sender, receiver = Layout(PORTS), Layout(PORTS)
    base = np.array([1.0, 2.0, 3.0, 9.0])
    b = sent(base)
    receiver.decode(sender.encode(Kind.STEP, 1, 1, 0.0, {"a": 0.0, "b": b, "c": 0.0, "d": [0, 0]}))
    base[1] = 7.0
    decoded = receiver.decode(sender.encode(Kind.STEP, 2, 2, 0.0, {"a": 0.0, "b": b, "c": 0.0,
                                                                   "d": [0, 0]}))
    assert decoded["b"].tolist() == [1.0, 7.0, 3.0]


def test_a_view_of_a_read_only_copy_is_held_by_identity():
    sender, receiver = Layout(PORTS), Layout(PORTS)
    block = _frozen([1.0, 2.0, 3.0, 4.0, 5.0])
    b, d = block[:3], block[3:]   # as the master hands out one component's array block
    first = receiver.decode(sender.encode(Kind.STEP, 1, 1, 0.0, {"a": 0.0, "b": b, "c": 0.0, "d": d}))
    message = sender.encode(Kind.STEP, 2, 2, 0.0, {"a": 0.0, "b": b, "c": 0.0, "d": d})
    assert message[HEADER.size:HEADER.size + 2] == bytes([0, 0])
    second = receiver.decode(message)
    assert second["b"] is first["b"] and second["d"].tolist() == [4.0, 5.0]


def test_forget_sends_and_expects_every_array_afresh():
    sender, receiver = Layout(PORTS), Layout(PORTS)
    values = {"a": 0.0, "b": _frozen([1, 2, 3]), "c": 0.0, "d": _frozen([4, 5])}
    receiver.decode(sender.encode(Kind.START, 1, -1, 0.0, values))
    held = sender.encode(Kind.STEP, 2, 1, 0.0, values)
    fresh_receiver = Layout(PORTS)
    with pytest.raises(CodecError, match=r"^output 'b' held before it was ever sent$"):
        fresh_receiver.decode(held)
    sender.forget()
    again = sender.encode(Kind.START, 3, -1, 0.0, values)
    assert again[HEADER.size:HEADER.size + 2] == bytes([1, 1])
    assert fresh_receiver.decode(again)["d"].tolist() == [4.0, 5.0]


@pytest.mark.parametrize("values, message", [
    ({"a": 1.0, "b": [1, 2, 3], "c": 2.0}, "output 'd' missing"),
    ({"a": 1.0, "b": [1, 2], "c": 2.0, "d": [0, 0]}, "output 'b' has shape (2,), expected (3,)"),
    ({"a": "x", "b": [1, 2, 3], "c": 2.0, "d": [0, 0]}, "output 'a' is not a number: 'x'"),
    ({"a": 1.0, "b": [1, 2, 3], "c": float("nan"), "d": [0, 0]}, "output 'c' is non-finite: nan"),
    ({"a": 1.0, "b": [1, float("inf"), 3], "c": 2.0, "d": [0, 0]},
     "output 'b' is non-finite at [1]: inf"),
    ([1.0], "returned list, expected a mapping of output signals"),
])
def test_bad_values_are_named(values, message):
    with pytest.raises(CodecError) as error:
        Layout(PORTS).encode(Kind.OUTPUTS, 1, 4, 0.04, values, finite=True)
    assert str(error.value) == message


def test_scalar_only_layout_rejects_nan_and_missing_by_name():
    layout = Layout((Port("u"), Port("v")), "input")
    with pytest.raises(CodecError, match=r"^input 'v' is non-finite: nan$"):
        layout.encode(Kind.STEP, 1, 1, 0.0, {"u": 1.0, "v": float("nan")}, finite=True)
    with pytest.raises(CodecError, match=r"^input 'u' missing$"):
        layout.encode(Kind.STEP, 1, 1, 0.0, {"v": 1.0})
    # without the check NaN travels (the master checks the values it produced)
    assert np.isnan(layout.decode(layout.encode(Kind.STEP, 1, 1, 0.0,
                                                {"u": 1.0, "v": float("nan")}))["v"])


def test_the_values_lane_is_the_same_message_in_declared_order():
    rng = np.random.default_rng(13)
    flat = random_finite(rng, 7)
    by_name = {"a": flat[0], "b": _frozen(flat[1:4]), "c": flat[4], "d": _frozen(flat[5:7])}
    in_order = (by_name["a"], by_name["b"], by_name["c"], by_name["d"])
    named, ordered = Layout(PORTS), Layout(PORTS)
    for tick in (1, 2):  # the second time both hold b and d
        message = ordered.encode_values(Kind.STEP, tick, tick, 0.01, in_order)
        assert message == named.encode(Kind.STEP, tick, tick, 0.01, by_name)
    receiver = Layout(PORTS)
    first = receiver.decode_values(Layout(PORTS).encode_values(Kind.STEP, 1, 1, 0.0, in_order))
    assert [type(v) for v in first] == [float, np.ndarray, float, np.ndarray]
    assert np.concatenate([[first[0]], first[1], [first[2]], first[3]]).tobytes() == flat.tobytes()
    scalars = Layout((Port("u"), Port("v")))
    assert scalars.decode_values(scalars.encode_values(Kind.OUTPUTS, 1, 1, 0.0, (-0.0, 5e-324))) \
        == (-0.0, 5e-324)


@pytest.mark.parametrize("ports, values, message", [
    ((Port("u"), Port("v")), (1.0,), "returned 1 values for 2 outputs ['u', 'v']"),
    ((Port("u"), Port("v")), (1.0, float("nan")), "output 'v' is non-finite: nan"),
    ((Port("u"), Port("v")), (1.0, "x"), "output 'v' is not a number: 'x'"),
    ((Port("u"), Port("v")), 3.0, "returned float, expected a sequence of 2 values"),
    (PORTS, (1.0, [1, 2], 2.0, [0, 0]), "output 'b' has shape (2,), expected (3,)"),
    (PORTS, (1.0, [1, 2, 3]), "returned 2 values for 4 outputs ['a', 'b', 'c', 'd']"),
])
def test_bad_values_on_the_lane_are_named(ports, values, message):
    with pytest.raises(CodecError) as error:
        Layout(ports).encode_values(Kind.OUTPUTS, 1, 4, 0.04, values, finite=True)
    assert str(error.value) == message


def test_decode_rejects_a_message_of_the_wrong_size():
    layout = Layout(PORTS)
    mask = bytes([1, 1, 0, 0, 0, 0, 0, 0])
    message = HEADER.pack(Kind.OUTPUTS, 1, 1, 0.0) + mask + struct.pack("<3d", 1, 2, 3)
    with pytest.raises(CodecError, match="message of 64 bytes ends inside output 'b'"):
        layout.decode(message)
    message = HEADER.pack(Kind.OUTPUTS, 1, 1, 0.0) + mask + struct.pack("<8d", *range(8))
    with pytest.raises(CodecError, match="message of 104 bytes, expected 96"):
        layout.decode(message)
    scalars = Layout((Port("u"), Port("v")))
    with pytest.raises(CodecError, match="message of 40 bytes, expected 48"):
        scalars.decode(HEADER.pack(Kind.OUTPUTS, 1, 1, 0.0) + struct.pack("<d", 1))


def test_ports_and_json_documents_round_trip():
    ports = (Port("delta", unit="rad", description="steering", default=0.5), Port("w", size=4))
    assert ports_from_json(ports_to_json(ports)) == ports
    message = encode_json(Kind.ERROR, 3, 9, 0.09, {"cause": "boom é"})
    assert HEADER.unpack_from(message) == (Kind.ERROR, 3, 9, 0.09)
    assert decode_json(message) == {"cause": "boom é"}


@pytest.mark.parametrize("bad", ["", "a/b", "*", "x y", "run$1", "**"])
def test_key_chunks_are_checked(bad):
    with pytest.raises(ValueError, match="run_id"):
        config.check_key_chunk(bad, "run_id")


def test_keys_are_scoped_by_run():
    assert config.request_key("r1", "controller") == "cosim/r1/ctl/controller/req"
    assert config.reply_key("r1", "*") == "cosim/r1/ctl/*/rep"
    assert config.run_id_of_live_key(config.live_data_key("run-7")) == "run-7"
