"""Actuator chain: force law, stroke limit, strain gauge, state, presets."""

import math

import numpy as np
import pytest

from piezofmu import actuator as ac
from piezofmu.actuator import ActuatorState, StateArrayError, StrainGauge
from piezofmu.stack import preset


def drive(act, cmds, dt, state=None):
    state = ac.initial_state(act) if state is None else state
    outs = []
    for u in cmds:
        state, out = ac.step(act, state, u, dt)
        outs.append(out)
    return state, outs


@pytest.mark.parametrize("name", ["P-243.30", "P-243.40", "P-845.37"])
def test_force_is_ch_times_voltage(name):
    # Eq. (1): f_c = c h v, with c h = k_e d0 / V0 from the datasheet.
    act = ac.actuator_preset(name)
    cmds = 30.0 * np.sin(np.linspace(0, 6, 40))
    _, outs = drive(act, cmds, 1e-3)
    v = np.array([o.voltage for o in outs])
    f = np.array([o.force for o in outs])
    np.testing.assert_allclose(f, act.stack.ch * v, rtol=1e-15)
    np.testing.assert_allclose(f, act.stack.stiffness * act.stack.stroke
                               / act.stack.rated_voltage * v, rtol=1e-14)
    assert np.ptp(v) > 10.0


def test_force_with_hysteresis_uses_effective_voltage():
    act = ac.actuator_preset("P-845.37", hysteresis=True)
    state, outs = drive(act, 40.0 * np.sin(np.linspace(0, 9, 60)), 1e-3)
    assert state.h_bw != 0.0
    out = outs[-1]
    assert out.force == pytest.approx(act.stack.ch * (out.voltage - state.h_bw), rel=1e-14)
    assert out.free_stroke == pytest.approx(out.force / act.stack.stiffness, rel=1e-14)


def test_stroke_limit_clips_force_and_raises_flag():
    act = ac.actuator_preset("P-845.37").replace(stroke_limit=10e-6)
    _, outs = drive(act, [60.0] * 20, 1e-3)  # clipped to 50 V: 20 um of free stroke
    out = outs[-1]
    assert out.voltage == 50.0 and out.sat_voltage is True
    assert out.free_stroke == pytest.approx(10e-6, rel=1e-14)
    assert out.force == pytest.approx(act.stack.stiffness * 10e-6, rel=1e-14)
    assert out.sat_stroke is True
    _, outs = drive(act, [-10.0] * 20, 1e-3)
    assert outs[-1].sat_stroke is False


def test_current_is_capacitance_times_rate_and_hits_i_max():
    act = ac.actuator_preset("P-243.30")
    s = act.amplifier.slew_rate(act.stack.capacitance)
    state, outs = drive(act, [1400.0] * 3, 1e-3)  # needs ~9 ms at 148.8 kV/s
    assert outs[-1].sat_slew is True
    assert outs[-1].current == pytest.approx(act.amplifier.i_max, rel=1e-12)
    assert outs[-1].current == pytest.approx(act.stack.capacitance * s, rel=1e-12)
    assert outs[-1].voltage - outs[-2].voltage == pytest.approx(s * 1e-3, rel=1e-9)


def test_step_size_independence_of_the_whole_chain():
    act = ac.actuator_preset("P-243.40", hysteresis=True).replace(
        gauge=StrainGauge(0.3, noise_std=1e-6, seed=3), stroke_limit=50e-6)
    rng = np.random.default_rng(7)
    cmds = rng.uniform(-1600, 1600, 30)
    a = b = ac.initial_state(act)
    seen = set()
    for u in cmds:
        a, out_a = ac.step(act, a, u, 0.004)
        any_b = [False, False]   # the rail and current flags of the short steps, or-ed
        for _ in range(4):
            b, out_b = ac.step(act, b, u, 0.001)
            any_b = [any_b[0] or out_b.sat_voltage, any_b[1] or out_b.sat_slew]
        keep = [0, 1, 4, 5, 6]   # the state without its flags
        np.testing.assert_allclose(a.to_array()[keep], b.to_array()[keep], rtol=1e-12,
                                   atol=1e-9)
        assert ac.strain(act, a, 1e-6) == ac.strain(act, b, 1e-6)
        # a step's rail and current flags: the limit acted at any of its sub-steps; the
        # stroke flag is the end state's
        assert [out_a.sat_voltage, out_a.sat_slew] == any_b
        assert out_a.sat_stroke == out_b.sat_stroke
        seen.add((out_a.sat_voltage, out_a.sat_slew, out_a.sat_stroke))
    assert {flag for flags in seen for flag in flags} == {False, True}
    assert a.tick == 30 * 400


def test_strain_is_elongation_over_gauge_length():
    act = ac.actuator_preset("P-243.30")
    state = ac.initial_state(act)
    assert act.gauge.length == pytest.approx(0.254)
    assert ac.strain(act, state, 2.54e-6) == pytest.approx(1e-5, rel=1e-14)


def test_strain_noise_is_seeded_and_reproducible():
    act = ac.actuator_preset("P-243.30").replace(gauge=StrainGauge(0.254, 2e-7, seed=11))
    states = [ActuatorState(tick=k) for k in range(4000)]
    first = np.array([ac.strain(act, s, 0.0) for s in states])
    again = np.array([ac.strain(act, s, 0.0) for s in states])
    other = ac.actuator_preset("P-243.30").replace(gauge=StrainGauge(0.254, 2e-7, seed=12))
    third = np.array([ac.strain(other, s, 0.0) for s in states])
    np.testing.assert_array_equal(first, again)
    assert not np.allclose(first, third)
    # 4000 samples: the sample standard deviation is within ~3 % (5 sigma < 6 %).
    assert np.std(first) == pytest.approx(2e-7, rel=0.06)
    assert abs(np.mean(first)) < 5 * 2e-7 / math.sqrt(4000)


def test_strain_quantisation():
    act = ac.actuator_preset("P-845.37").replace(
        gauge=StrainGauge(0.04, noise_std=3e-7, resolution=1e-7, seed=0))
    vals = np.array([ac.strain(act, ActuatorState(tick=k), 1.234e-6) for k in range(200)])
    np.testing.assert_allclose(vals / 1e-7, np.round(vals / 1e-7), atol=1e-9)
    assert len(np.unique(vals)) > 3


def test_state_array_round_trip_and_errors():
    act = ac.actuator_preset("P-243.30", hysteresis=True)
    state, _ = drive(act, [1600.0] * 2, 1e-3)
    back = ActuatorState.from_array(state.to_array())
    assert back == state
    with pytest.raises(StateArrayError, match="shape"):
        ActuatorState.from_array(np.zeros(5))
    with pytest.raises(StateArrayError, match="not a valid state"):
        ActuatorState.from_array([0, 0, 0, 0, 0, 1.5, 0])


def test_presets():
    assert set(ac.ACTUATORS) == {"P-243.30", "P-243.40", "P-845.37"}
    assert ac.actuator_preset("P243.30").stack == preset("P-243.30")
    assert ac.actuator_preset("P-243.40").amplifier.name == "Trek 50/750"
    act = ac.actuator_preset("P-845.37")
    assert act.amplifier.name == "P-865.10"
    assert act.hysteresis is None and ac.actuator_preset("P-845.37", True).hysteresis
    # +-50 V on the P-845.37 gives the paper's "up to 20 microns".
    _, outs = drive(act, [80.0] * 10, 1e-3)
    assert outs[-1].free_stroke == pytest.approx(20e-6, rel=1e-12)


@pytest.mark.parametrize("kwargs, word", [
    ({"length": 0.0}, "length"),
    ({"length": 0.1, "noise_std": -1.0}, "noise_std"),
    ({"length": 0.1, "seed": -1}, "seed"),
])
def test_invalid_gauge_raises(kwargs, word):
    with pytest.raises(ValueError, match=word):
        StrainGauge(**kwargs)


def test_counter_based_gaussian_is_standard_normal():
    from scipy import stats

    x = np.array([ac.gaussian(4, k) for k in range(20000)])
    # Kolmogorov-Smirnov against N(0, 1): a deterministic sample, so a fixed p-value.
    assert stats.kstest(x, "norm").pvalue > 0.01
    assert abs(np.mean(x)) < 5 / math.sqrt(x.size)
    assert np.std(x) == pytest.approx(1.0, abs=5 * math.sqrt(0.5 / x.size))
    # Neighbouring counters and seeds are uncorrelated.
    assert abs(np.corrcoef(x[:-1], x[1:])[0, 1]) < 5 / math.sqrt(x.size)
    y = np.array([ac.gaussian(5, k) for k in range(20000)])
    assert abs(np.corrcoef(x, y)[0, 1]) < 5 / math.sqrt(x.size)
    # Golden value: the sequence is fixed across platforms and versions.
    assert ac.gaussian(0, 0) == 0.5948276824468888
    assert ac.gaussian(7, 123456) == 1.0575546891808585


@pytest.mark.parametrize("order,servo", [(2, 0.0), (1, 0.0), (2, 100.0)])
def test_inner_rows_give_every_sub_step_of_a_step(order, servo):
    """The sub-step values of a 1 ms step from its start state and held inputs equal the
    same step taken one internal sub-step a call (an independent computation)."""
    amp = ac.actuator_preset("P-243.40").amplifier.replace(order=order, i_max=math.inf,
                                                           v_min=-1e4, v_max=1e4)
    act = ac.actuator_preset("P-243.40").replace(amplifier=amp)
    if servo:
        act = act.replace(servo_bandwidth=servo, servo_plant_gain=2e-8)
    state = ac.initial_state(act)
    state, _ = ac.step(act, state, 300.0, 1e-3, 1e-6)   # not at rest
    u, e, h = -200.0, 3e-6, amp.internal_step
    v, r = [], []
    fine = state
    for _ in range(100):
        fine, _ = ac.step(act, fine, u, h, e)
        v.append(fine.amp.voltage)
        r.append(fine.amp.rate)
    start = [state.amp.voltage] + ([state.amp.rate] if order == 2 else [])
    x = np.array(start + ([state.z] if servo else []) + [u, e])
    rows = ac.inner_rows(act, 1e-3)
    np.testing.assert_allclose(rows["voltage"] @ x, v, rtol=1e-9, atol=1e-9 * max(map(abs, v)))
    cap = act.stack.capacitance
    want = cap * np.diff([state.amp.voltage] + v) / h
    if order == 2:
        want = np.concatenate([want, cap * np.array(r)])
    got = rows["current"] @ x
    np.testing.assert_allclose(got, want, rtol=1e-7, atol=1e-7 * np.abs(want).max())
