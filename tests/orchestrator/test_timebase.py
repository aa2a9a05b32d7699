"""Exact rational time grid."""

from fractions import Fraction

import pytest
from hypothesis import given, strategies as st

from orchestrator.timebase import TimebaseError, make_timebase, to_fraction


def test_decimal_floats_become_exact_rationals():
    assert to_fraction(1e-3) == Fraction(1, 1000)
    assert to_fraction(4e-3) == Fraction(1, 250)
    assert to_fraction(0.1) == Fraction(1, 10)
    assert to_fraction("2.5e-4") == Fraction(1, 4000)
    # 1/3 as a float: the simplest rational rounding to the same double is used
    assert to_fraction(1 / 3) == Fraction(1, 3)


def test_base_is_gcd_and_hyperperiod_is_lcm():
    tb = make_timebase({"a": 1e-3, "b": 4e-3, "c": 2.5e-3}, 1e-3, 1.0)
    assert tb.base == Fraction(1, 2000)
    assert tb.period_ticks == {"a": 2, "b": 8, "c": 5}
    assert tb.output_ticks == 2
    assert tb.hyperperiod == 40
    assert tb.n_ticks == 2000
    pattern = tb.due_pattern(["a", "b", "c"])
    assert pattern[0] == ("a", "b", "c")
    assert pattern[1] == ()
    assert pattern[5] == ("c",)
    assert pattern[8] == ("a", "b")


def test_times_are_never_accumulated():
    tb = make_timebase({"a": 1e-4}, 1e-4, 100.0)
    # 0.1 added 10**6 times drifts; tick * base does not
    assert tb.time(10**6) == 100.0
    assert tb.time(3) == 3e-4
    acc = 0.0
    for _ in range(3):
        acc += 1e-4
    assert acc != 3e-4  # the drift the grid avoids


@given(st.integers(1, 10**6), st.integers(0, 10**7))
def test_tick_time_is_correctly_rounded(den, k):
    tb = make_timebase({"a": Fraction(1, den)}, Fraction(1, den), Fraction(10**7, den))
    assert tb.time(k) == float(Fraction(k, den))


def test_ticks_of_off_grid_time_is_an_error():
    tb = make_timebase({"a": 1e-3}, 1e-3, 1.0)
    assert tb.ticks_of(2.4) == 2400
    with pytest.raises(TimebaseError, match="not on the base grid"):
        tb.ticks_of(2.4005)


@pytest.mark.parametrize(
    "periods, out, stop, match",
    [
        ({"a": 0.0}, 1e-3, 1.0, "period of instance 'a' is 0.0 s; expected > 0"),
        ({"a": -1e-3}, 1e-3, 1.0, "expected > 0"),
        ({"a": 1e-3}, 0.0, 1.0, "output interval is 0.0 s"),
        ({"a": 1e-3}, 1e-3, 0.0, "stop time 0.0 s is not after start"),
        ({"a": 1e-3}, 1e-3, 1.0005, "not a multiple of the base step"),
        ({"a": 1e-3, "b": 0.1234567890123}, 1e-3, 1.0, "share no base step"),
        ({"a": 1e-9}, 1e-9, 10.0, "at most"),
    ],
)
def test_bad_grids_are_clear_errors(periods, out, stop, match):
    with pytest.raises(TimebaseError, match=match):
        make_timebase(periods, out, stop)
