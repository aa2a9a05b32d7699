"""fmukit.state: serialized FMU state is data only, checked on restore."""

import struct
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).parent))  # toyslave.py

from toyslave import ToyFilter  # noqa: E402

from fmukit.state import (  # noqa: E402
    MAGIC,
    VERSION,
    FmuStateError,
    decode_state,
    encode_state,
    seal,
)

H = 1e-3


def crafted_pickle(marker: Path) -> bytes:
    """The attack of issue 12: a protocol-4 pickle whose global is the dotted name
    ``os.system`` looked up through the allowed module ``numpy.lib._datasource``,
    called with ``touch <marker>``."""
    def short(s: bytes) -> bytes:
        return b"\x8c" + bytes([len(s)]) + s + b"\x94"  # SHORT_BINUNICODE, MEMOIZE

    cmd = f"touch {marker}".encode()
    return (b"\x80\x04" + short(b"numpy.lib._datasource") + short(b"os.system")
            + b"\x93\x94" + short(cmd) + b"\x85\x94R\x94.")


def test_crafted_pickle_runs_nothing_and_gets_one_clear_error(tmp_path):
    marker = tmp_path / "pwned"
    with pytest.raises(FmuStateError, match="invalid: it starts with"):
        ToyFilter._fmu_state_from_bytes(crafted_pickle(marker))
    assert not marker.exists()


def test_plain_values_round_trip_exactly():
    value = {
        "none": None, "yes": True, "no": False, "k": -(2**70), "zero": 0,
        "x": -0.0, "nan": float("nan"), "inf": float("inf"), "z": 1 - 2j,
        "s": "µ-rad ✓", "b": b"\x00\xff", "l": [1, (2.5, "a"), []],
        "np_scalars": [np.float64(1.5), np.int64(-3), np.bool_(True)],
        "f8": np.arange(6.0).reshape(2, 3), "i8": np.array([-1, 2**40]),
        "b1": np.array([True, False]), "c16": np.array([1j]), "empty": np.zeros((0, 4)),
        "fortran": np.asfortranarray(np.arange(6.0).reshape(2, 3)),
        "big_endian": np.arange(3, dtype=">f8"),
    }
    back = decode_state(encode_state(value))
    assert set(back) == set(value)
    for key in ("none", "yes", "no", "k", "zero", "inf", "z", "s", "b", "l"):
        assert back[key] == value[key] and type(back[key]) is type(value[key])
    assert np.isnan(back["nan"]) and str(back["x"]) == "-0.0"
    assert back["np_scalars"] == [1.5, -3, True]
    for key in ("f8", "i8", "b1", "c16", "empty", "fortran", "big_endian"):
        np.testing.assert_array_equal(back[key], value[key])
        assert back[key].shape == value[key].shape and back[key].flags.writeable
    assert back["f8"].dtype == np.float64 and back["i8"].dtype == np.int64


@pytest.mark.parametrize("value, what", [
    (object(), "is a object"),
    ({"f": print}, "state\\['f'\\] is a builtin_function_or_method"),
    (np.array([object()]), "array of object"),
    ({1: 2}, "key 1"),
])
def test_values_that_are_not_data_are_refused_on_save(value, what):
    with pytest.raises(FmuStateError, match=what):
        encode_state(value)


def _good() -> bytes:
    return encode_state({"real": np.arange(3.0), "other": {}, "attrs": {}})


@pytest.mark.parametrize("mutate, reason", [
    (lambda b: b[:5], "fewer than the 18-byte header"),
    (lambda b: b"XXXXXXXX" + b[8:], "starts with b'XXXXXXXX'"),
    (lambda b: b[:8] + struct.pack("<H", VERSION + 1) + b[10:],
     f"layout version is {VERSION + 1}"),
    (lambda b: b[:-1], "announces"),
    (lambda b: b + b"\x00", "announces"),
    (lambda b: seal(b[:18] + b"?" + b[19:-4]), "unknown value tag"),
    (lambda b: b[:-12] + bytes([b[-12] ^ 1]) + b[-11:], "checksum does not match"),
])
def test_bad_bytes_give_one_clear_error(mutate, reason):
    with pytest.raises(FmuStateError, match=f"serialized FMU state is invalid: .*{reason}"):
        decode_state(mutate(_good()))


def test_huge_counts_and_shapes_are_refused_without_allocating():
    body = b"a" + bytes([0, 2]) + struct.pack("<2Q", 2**40, 2**40)
    blob = seal(struct.pack("<8sHQ", MAGIC, VERSION, len(body)) + body)
    with pytest.raises(FmuStateError, match="larger than the state"):
        decode_state(blob)
    body = b"l" + struct.pack("<I", 2**31)
    blob = seal(struct.pack("<8sHQ", MAGIC, VERSION, len(body)) + body)
    with pytest.raises(FmuStateError, match="claims 2147483648 items"):
        decode_state(blob)
    body = b"l\x01\x00\x00\x00" * 40 + b"N"
    blob = seal(struct.pack("<8sHQ", MAGIC, VERSION, len(body)) + body)
    with pytest.raises(FmuStateError, match="nested deeper"):
        decode_state(blob)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=200))
def test_arbitrary_bytes_decode_or_give_fmu_state_error(data):
    for blob in (data, seal(struct.pack("<8sHQ", MAGIC, VERSION, len(data)) + data)):
        try:
            decode_state(blob)
        except FmuStateError:
            pass


@settings(max_examples=200, deadline=None)
@given(st.integers(min_value=0, max_value=400), st.integers(min_value=0, max_value=255))
def test_every_single_byte_corruption_of_a_slave_state_is_caught_or_harmless(pos, byte):
    s = ToyFilter(instance_name="t")
    s.u = 0.7
    s.do_step(0.0, H)
    blob = bytearray(ToyFilter._fmu_state_to_bytes(s._get_fmu_state()))
    blob[pos % len(blob)] = byte
    before = (s._real_values.copy(), s.x.copy(), s.n_steps, s.label)
    try:
        s._set_fmu_state(ToyFilter._fmu_state_from_bytes(bytes(blob)))
    except FmuStateError:
        np.testing.assert_array_equal(s._real_values, before[0])  # nothing was written
        np.testing.assert_array_equal(s.x, before[1])
        assert (s.n_steps, s.label) == before[2:]


def _state_after_steps(n):
    s = ToyFilter(instance_name="t")
    s.u = 0.7
    for k in range(n):
        s.do_step(k * H, H)
    return s, s._get_fmu_state()


@pytest.mark.parametrize("edit, message", [
    (lambda st_: st_["attrs"].pop("n_steps"), "state attributes \\['x'\\]; expected \\['n_steps', 'x'\\]"),
    (lambda st_: st_["attrs"].update(x=np.zeros(5)), "attribute 'x' as \\(5,\\)"),
    (lambda st_: st_["other"].update(gain_mode="2"), "Integer 'gain_mode' to a str"),
    (lambda st_: st_["other"].update(extra=1), "Integer/Boolean/String variables"),
    (lambda st_: st_.update(real=st_["real"][:-1]), "holds 9 Real values; slave .t. \\(ToyFilter\\) has 10"),
    (lambda st_: st_.update(real=list(st_["real"])), "expected a 1-d float64 array"),
])
def test_state_of_another_slave_is_refused_before_anything_changes(edit, message):
    s, _ = _state_after_steps(3)
    _, other = _state_after_steps(7)
    other = ToyFilter._fmu_state_from_bytes(ToyFilter._fmu_state_to_bytes(other))
    edit(other)
    x, n = s.x.copy(), s.n_steps
    with pytest.raises(FmuStateError, match=message):
        s._set_fmu_state(other)
    np.testing.assert_array_equal(s.x, x)
    assert s.n_steps == n == 3


def test_restore_writes_arrays_in_place_so_aliases_stay_valid():
    s, state = _state_after_steps(4)
    alias = s.x
    s.do_step(4 * H, H)
    s._set_fmu_state(ToyFilter._fmu_state_from_bytes(ToyFilter._fmu_state_to_bytes(state)))
    assert s.x is alias
    np.testing.assert_array_equal(alias, state["attrs"]["x"])
    assert s.n_steps == 4 and type(s.n_steps) is int


def test_one_flipped_bit_in_a_value_is_refused():
    """A bit of the state's float payload flipped (x[0] = 0.7 becomes another finite
    number): the checksum refuses it, whichever bit."""
    s, state = _state_after_steps(3)
    blob = ToyFilter._fmu_state_to_bytes(state)
    at = blob.index(np.float64(s.x[0]).tobytes())
    for bit in range(64):
        bad = bytearray(blob)
        bad[at + bit // 8] ^= 1 << (bit % 8)
        with pytest.raises(FmuStateError, match="checksum does not match"):
            ToyFilter._fmu_state_from_bytes(bytes(bad))


@pytest.mark.parametrize("where", ["real", "attr"])
@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_non_finite_state_values_are_refused_before_anything_changes(where, value):
    s, _ = _state_after_steps(3)
    _, other = _state_after_steps(7)
    if where == "real":
        other["real"][0] = value
    else:
        other["attrs"]["x"][0] = value
    other = ToyFilter._fmu_state_from_bytes(ToyFilter._fmu_state_to_bytes(other))
    before = s._real_values.copy(), s.x.copy(), s.n_steps
    with pytest.raises(FmuStateError, match="not finite|expected finite"):
        s._set_fmu_state(other)
    np.testing.assert_array_equal(s._real_values, before[0])
    np.testing.assert_array_equal(s.x, before[1])
    assert s.n_steps == before[2] == 3
