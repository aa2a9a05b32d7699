"""Bouc-Wen hysteresis: exact increments, closed loops, rate independence."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from piezofmu import actuator
from piezofmu import hysteresis as hy
from piezofmu.amplifier import Amplifier
from piezofmu.hysteresis import BoucWen, HysteresisError

BW = BoucWen.scaled(alpha=0.25, beta_v0=3.0, gamma_v0=1.0, v0=100.0)


def test_monotone_sweep_from_zero_is_analytic():
    # dh/dv = alpha - (beta + gamma) h for dv > 0, h >= 0:
    # h(v) = alpha / (beta + gamma) (1 - exp(-(beta + gamma) v)).
    dv = np.linspace(0, 300, 31)
    h = [hy.increment(BW, 0.0, x) for x in dv]
    k = BW.beta + BW.gamma
    np.testing.assert_allclose(h, BW.alpha / k * (1 - np.exp(-k * dv)), rtol=1e-14, atol=1e-15)


def test_zero_crossing_continues_on_the_other_branch():
    # From h0 < 0 upward: dh/dv = alpha - (beta - gamma) h until h = 0, then beta + gamma.
    h0 = -5.0
    k1, k2 = BW.beta - BW.gamma, BW.beta + BW.gamma
    w0 = math.log1p(-h0 * k1 / BW.alpha) / k1
    assert hy.increment(BW, h0, w0) == pytest.approx(0.0, abs=1e-12)
    extra = 17.0
    expected = BW.alpha / k2 * (1 - math.exp(-k2 * extra))
    assert hy.increment(BW, h0, w0 + extra) == pytest.approx(expected, rel=1e-12)


@settings(max_examples=200, deadline=None)
@given(h0=st.floats(-8, 8), a=st.floats(-200, 200), frac=st.floats(0, 1))
def test_splitting_a_monotone_increment_changes_nothing(h0, a, frac):
    whole = hy.increment(BW, h0, a)
    split = hy.increment(BW, hy.increment(BW, h0, frac * a), a - frac * a)
    assert split == pytest.approx(whole, rel=1e-12, abs=1e-12)


def sine_loop(n_per_cycle, cycles=25, amp=50.0):
    """h at the quarter-period points of the last cycle of v = amp sin(2 pi k / n)."""
    k = np.arange(cycles * n_per_cycle + 1)
    v = amp * np.sin(2 * np.pi * k / n_per_cycle)
    v[::n_per_cycle // 4] = amp * np.round(np.sin(2 * np.pi * k[::n_per_cycle // 4]
                                                  / n_per_cycle))
    h = np.empty_like(v)
    h[0] = 0.0
    for j in range(1, len(v)):
        h[j] = hy.increment(BW, h[j - 1], v[j] - v[j - 1])
    return v, h


def test_periodic_input_gives_a_closed_loop():
    n = 400
    v, h = sine_loop(n)
    # Start and end of the last two cycles coincide: the loop is closed.
    assert h[-1] == pytest.approx(h[-1 - n], abs=1e-12 * BW.h_max)
    # The loop has area and runs counter-clockwise in (v, stroke ~ v - h): at v = 0 the
    # ascending branch lies below the descending one.
    up, down = h[-1], h[-1 - n // 2]  # v = 0 going up, v = 0 going down
    assert v[-1] == 0.0 and v[-1 - n // 2] == 0.0
    assert (0 - up) < (0 - down) - 0.1 * BW.h_max


def test_loop_does_not_depend_on_sampling_rate():
    # The same sine sampled 400 and 1000 times per cycle (i.e. two frequencies at a fixed
    # internal step): h at the shared quarter-period points agrees to round-off.
    v1, h1 = sine_loop(400)
    v2, h2 = sine_loop(1000)
    np.testing.assert_array_equal(v1[-401::100], v2[-1001::250])
    np.testing.assert_allclose(h1[-401::100], h2[-1001::250], rtol=1e-12, atol=1e-12)


def test_actuator_loop_same_at_two_frequencies():
    # Through the whole actuator with a fast amplifier: the loop of force versus applied
    # voltage at 1 Hz and 4 Hz is the same (the amplifier lag changes the voltage path only
    # by ~1e-6 relative).
    act = actuator.actuator_preset("P-845.37", hysteresis=True).replace(
        amplifier=Amplifier(bandwidth=20e3, order=1, internal_step=1e-5))
    loops = []
    for f in (1.0, 4.0):
        n = 200
        dt = 1.0 / (f * n)
        s = actuator.initial_state(act)
        hs = []
        for k in range(1, 6 * n + 1):
            s, out = actuator.step(act, s, 40.0 * math.sin(2 * math.pi * k / n), dt)
            hs.append(s.h_bw)
        loops.append(np.array(hs[-n:]))
    np.testing.assert_allclose(loops[0], loops[1], atol=1e-4 * act.hysteresis.h_max)
    assert np.ptp(loops[0]) > 0.1 * act.hysteresis.h_max


@pytest.mark.parametrize("kwargs", [
    {"alpha": 0.0, "beta": 1.0, "gamma": 0.0},
    {"alpha": 0.2, "beta": 1.0, "gamma": 1.0},
    {"alpha": 0.2, "beta": 1.0, "gamma": -2.0},
])
def test_invalid_parameters_raise(kwargs):
    with pytest.raises(HysteresisError) as info:
        BoucWen(**kwargs)
    assert isinstance(info.value, ValueError)
