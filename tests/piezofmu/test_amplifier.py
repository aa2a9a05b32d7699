"""Amplifier model against analytic responses."""

import math

import numpy as np
import pytest

from piezofmu import amplifier as amp
from piezofmu.amplifier import Amplifier, AmplifierError

C = 1e-6  # load capacitance (F)


def run(a, v_cmd, dt, n, state=None):
    """Step n times with a constant command; return voltages, currents, final state."""
    state = amp.initial_state(a) if state is None else state
    v, i = [], []
    for _ in range(n):
        state, out = amp.step(a, C, state, v_cmd, dt)
        v.append(out.voltage)
        i.append(out.current)
    return np.array(v), np.array(i), state


def test_first_order_step_response_is_analytic():
    # v(t) = u (1 - exp(-t / tau)), i(t) = C u / tau exp(-t / tau), tau = 1 / (2 pi f_c)
    a = Amplifier(bandwidth=100.0, order=1)
    dt, n, u = 2e-4, 100, 3.0
    v, i, _ = run(a, u, dt, n)
    t = dt * np.arange(1, n + 1)
    tau = 1.0 / (2 * math.pi * 100.0)
    np.testing.assert_allclose(v, u * (1 - np.exp(-t / tau)), rtol=1e-12, atol=1e-13 * u)
    # i = C w (u - v) loses relative accuracy as v -> u; the bound is round-off of v times C w.
    np.testing.assert_allclose(i, C * u / tau * np.exp(-t / tau), rtol=1e-11,
                               atol=1e-12 * C * u / tau)


@pytest.mark.parametrize("zeta", [0.2, 0.6, 1.0, 1.5])
def test_second_order_step_response_is_analytic(zeta):
    # Standard second-order step response (e.g. Ogata, Modern Control Engineering, Sec. 5-3).
    f = 200.0
    w = 2 * math.pi * f
    a = Amplifier(bandwidth=f, order=2, damping=zeta)
    dt, n, u = 1e-4, 150, -2.0
    v, i, _ = run(a, u, dt, n)
    t = dt * np.arange(1, n + 1)
    if zeta < 1:
        wd = w * math.sqrt(1 - zeta**2)
        y = 1 - np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2)
                                          * np.sin(wd * t))
        dy = w / math.sqrt(1 - zeta**2) * np.exp(-zeta * w * t) * np.sin(wd * t)
    elif zeta == 1:
        y = 1 - np.exp(-w * t) * (1 + w * t)
        dy = w**2 * t * np.exp(-w * t)
    else:
        s1 = -w * (zeta - math.sqrt(zeta**2 - 1))
        s2 = -w * (zeta + math.sqrt(zeta**2 - 1))
        y = 1 + (s2 * np.exp(s1 * t) - s1 * np.exp(s2 * t)) / (s1 - s2)
        dy = s1 * s2 * (np.exp(s1 * t) - np.exp(s2 * t)) / (s1 - s2)
    np.testing.assert_allclose(v, u * y, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(i, C * u * dy, rtol=1e-9, atol=1e-11 * C * abs(u) * w)


@pytest.mark.parametrize("order", [1, 2])
def test_slew_limited_ramp_has_slope_i_max_over_c(order):
    i_max = 2e-3
    a = Amplifier(bandwidth=1000.0, order=order, damping=0.7, i_max=i_max)
    s = i_max / C  # 2000 V/s, so a 100 V step needs 50 ms
    dt, n = 1e-3, 30
    v, i, state = run(a, 100.0, dt, n)
    t = dt * np.arange(1, n + 1)
    # After a short start-up for order 2 (the rate state must first reach S) the ramp is exact.
    start = 0 if order == 1 else 5
    np.testing.assert_allclose(np.diff(v[start:]) / dt, s, rtol=1e-9)
    np.testing.assert_allclose(i[start:], i_max, rtol=1e-12)
    if order == 1:
        np.testing.assert_allclose(v, s * t, rtol=1e-12)
    assert state.sat_slew is True
    assert np.all(v <= s * t * (1 + 1e-12))


def test_slew_flag_clears_after_the_ramp():
    a = Amplifier(bandwidth=1000.0, order=1, i_max=2e-3)
    v, _, state = run(a, 10.0, 1e-3, 100)
    assert state.sat_slew is False
    assert v[-1] == pytest.approx(10.0, rel=1e-12)


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("u, rail", [(250.0, 100.0), (-400.0, -100.0)])
def test_voltage_clips_at_the_rails(order, u, rail):
    a = Amplifier(bandwidth=500.0, order=order, damping=0.5, v_min=-100.0, v_max=100.0)
    v, i, state = run(a, u, 1e-3, 50)
    assert np.all(np.abs(v) <= 100.0)
    assert v[-1] == rail
    assert i[-1] == 0.0
    assert state.sat_voltage is True
    # Back inside the rails: the flag clears and the output leaves the rail at once (no windup).
    state, out = amp.step(a, C, state, 0.0, 1e-3)
    assert out.sat_voltage is False
    assert abs(out.voltage) < 100.0


def test_step_size_independence_with_all_limits_active():
    a = Amplifier(bandwidth=300.0, order=2, damping=0.3, v_min=-40.0, v_max=60.0, i_max=5e-3)
    rng = np.random.default_rng(1)
    cmds = rng.uniform(-100, 100, 50)
    s1 = s4 = amp.initial_state(a)
    flags = set()
    for u in cmds:
        s1, _ = amp.step(a, C, s1, u, 0.004)
        seen = [False, False]   # the flags of the four short steps, or-ed
        for _ in range(4):
            s4, _ = amp.step(a, C, s4, u, 0.001)
            seen = [seen[0] or s4.sat_voltage, seen[1] or s4.sat_slew]
        np.testing.assert_allclose([s1.voltage, s1.rate], [s4.voltage, s4.rate],
                                   rtol=1e-12, atol=1e-12 * 100)
        # a step's flag says the limit acted at any of its sub-steps
        assert [s1.sat_voltage, s1.sat_slew] == seen
        flags.add((s1.sat_voltage, s1.sat_slew))
    # The sequence did exercise the limits.
    assert (True, False) in flags or (True, True) in flags
    assert any(slew for _, slew in flags)


def test_substep_rule():
    assert amp.substeps(0.004, 1e-5) == (400, 1e-5)
    assert amp.substeps(1e-5, 1e-5) == (1, 1e-5)
    n, h = amp.substeps(2.5e-5, 1e-5)
    assert n == 3 and h == pytest.approx(2.5e-5 / 3, rel=1e-15)
    n, h = amp.substeps(3e-6, 1e-5)
    assert (n, h) == (1, 3e-6)
    with pytest.raises(AmplifierError, match="dt"):
        amp.substeps(0.0, 1e-5)


def test_linear_response_is_exact_for_steps_that_are_not_multiples():
    # The low-pass is discretised exactly, so without active limits any step size agrees.
    a = Amplifier(bandwidth=150.0, order=2, damping=0.4)
    s_a, _ = amp.step(a, C, amp.initial_state(a), 1.0, 0.00137)
    s_b = amp.initial_state(a)
    for _ in range(7):
        s_b, _ = amp.step(a, C, s_b, 1.0, 0.00137 / 7)
    np.testing.assert_allclose([s_a.voltage, s_a.rate], [s_b.voltage, s_b.rate], rtol=1e-11)


def test_presets_match_the_paper():
    trek = amp.amplifier_preset("Trek 50/750")
    assert (trek.v_min, trek.v_max, trek.i_max) == (-1500.0, 1500.0, 50e-3)
    pi = amp.amplifier_preset("P-865.10")
    assert (pi.v_min, pi.v_max) == (-50.0, 50.0)
    assert pi.i_max * 100.0 == pytest.approx(30.0)  # 30 W at 100 V
    assert trek.slew_rate(336e-9) == pytest.approx(50e-3 / 336e-9)
    with pytest.raises(KeyError, match="unknown amplifier"):
        amp.amplifier_preset("E-500")


@pytest.mark.parametrize("changes, word", [
    ({"v_min": 10.0, "v_max": -10.0}, "v_min"),
    ({"order": 3}, "order"),
    ({"bandwidth": 0.0}, "bandwidth"),
    ({"i_max": -1.0}, "i_max"),
])
def test_invalid_parameters_raise_value_errors(changes, word):
    with pytest.raises(AmplifierError, match=word) as info:
        Amplifier(**changes)
    assert isinstance(info.value, ValueError)


def test_bad_capacitance_and_command_raise():
    a = Amplifier()
    with pytest.raises(AmplifierError, match="capacitance"):
        amp.step(a, 0.0, amp.initial_state(a), 1.0, 1e-3)
    with pytest.raises(AmplifierError, match="v_cmd"):
        amp.step(a, C, amp.initial_state(a), math.nan, 1e-3)


def test_own_matrix_exponential_matches_scipy():
    """The amplifier's Taylor scaling-and-squaring expm (kept so that the FMU need not
    import scipy) against scipy.linalg.expm, entry by entry, and the coefficients of the
    second-order amplifier against scipy's expm of the unscaled system."""
    from scipy.linalg import expm

    from piezofmu.amplifier import Amplifier, _coefficients, _expm

    rng = np.random.default_rng(11)
    for n, scale in ((2, 0.1), (3, 1.0), (3, 3.0), (5, 20.0)):
        a = rng.standard_normal((n, n)) * scale
        want = expm(a)
        np.testing.assert_allclose(_expm(a), want, rtol=0, atol=1e-12 * np.abs(want).max())
    # the amplifier's discretisation, from the default regime (w h = 0.13) to a sub-step
    # ten times the period (w h = 63): every coefficient to 1e-13 of its natural size
    # (1 for volts per volt, 1/w for volts per V/s, w for V/s per volt)
    for bw, z, h in ((2e3, 0.7, 1e-5), (500.0, 0.6, 1e-5), (2e3, 0.7, 1e-4),
                     (2e3, 0.7, 1e-3), (1e4, 1.0, 1e-3)):
        w = 2 * np.pi * bw
        amp = Amplifier(name="t", bandwidth=bw, order=2, damping=z, internal_step=h)
        e = expm(h * np.array([[0.0, 1.0, 0.0], [-w * w, -2 * z * w, w * w], [0, 0, 0.0]]))
        want = np.array([e[0, 0], e[0, 1], e[1, 0], e[1, 1], e[0, 2], e[1, 2]])
        scale = np.array([1.0, 1 / w, w, 1.0, 1.0, w])
        got = np.array(_coefficients(amp, h))
        assert np.all(np.abs(got - want) <= 1e-13 * scale), (bw, h, (got - want) / scale)


@pytest.mark.parametrize("order", [1, 2])
def test_a_limit_reached_and_released_inside_a_step_flags_that_step(order):
    """A small command step: the current limit acts in the first sub-steps only and the
    step ends below it.  The 1 ms step's flags are those of its 100 sub-steps taken one
    call each, or-ed (an independent computation: one sub-step per call)."""
    a = Amplifier(bandwidth=1000.0, order=order, damping=0.7, i_max=2e-3, v_min=-10.0,
                  v_max=3.0)
    s1, out = amp.step(a, C, amp.initial_state(a), 1.0, 1e-3)
    fine, flags = amp.initial_state(a), [False, False]
    for _ in range(100):
        fine, o = amp.step(a, C, fine, 1.0, 1e-5)
        flags = [flags[0] or o.sat_voltage, flags[1] or o.sat_slew]
    assert flags[1] and not fine.sat_slew   # the limit acted mid-step only
    assert abs(out.current) < a.i_max       # the step's end is inside the limit
    assert [s1.sat_voltage, s1.sat_slew] == flags == [False, True]
