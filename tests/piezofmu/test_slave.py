"""The piezo slave as a plain Python object (no FMU build)."""

import math

import numpy as np
import pytest

from piezofmu import actuator as ac
from piezofmu.actuator import ActuatorState
from piezofmu.fmuspec import MODELS, UnknownModelError, specs
from piezofmu.slave import PiezoParameterError, PiezoSlave

STATE_OUTPUTS = ["voltage", "current", "free_stroke", "sat_voltage", "sat_slew",
                 "sat_stroke"]


def make(preset="P-243.30", **params):
    cls = type("PiezoTest", (PiezoSlave,), {"preset_name": preset})
    slave = cls(instance_name="piezo")
    for name, value in params.items():
        setattr(slave, name, value)
    slave.enter_initialization_mode()
    slave.exit_initialization_mode()
    return slave


def vr(slave, name):
    return next(s.value_reference for s in slave.variable_specs if s.name == name)


def get(slave, names):
    return slave.get_real([vr(slave, n) for n in names])


def drive(slave, cmds, elong, dt):
    rows = []
    for k, (u, e) in enumerate(zip(cmds, elong)):
        slave.set_real([vr(slave, "v_cmd"), vr(slave, "elongation")], [u, e])
        slave.do_step(k * dt, dt)
        rows.append(get(slave, ["force"] + STATE_OUTPUTS + ["strain"]))
    return np.array(rows)


def signals(n=60, amp=1800.0):
    k = np.arange(n)
    return amp * np.sin(2 * np.pi * k / 25), 3e-6 * np.cos(2 * np.pi * k / 17)


@pytest.mark.parametrize("coupling", [1, 0])
def test_slave_equals_the_pure_step(coupling):
    slave = make("P-243.40", hysteresis=True, noise_std=1e-7, seed=5, stroke_limit=45e-6,
                 v_min=-900.0, v_max=900.0, coupling=coupling)
    cmds, elong = signals()
    got = drive(slave, cmds, elong, 1e-3)
    act = slave.actuator()
    assert act.hysteresis is not None and act.stroke_limit == 45e-6
    state = ac.initial_state(act)
    for k, (u, e) in enumerate(zip(cmds, elong)):
        state, out = ac.step(act, state, u, 1e-3)
        # after the step the force is the one held over the next step, v_cmd still u
        force = ac.step_mean(act, state, u, 1e-3)[2] if coupling else out.force
        want = [force, out.voltage, out.current, out.free_stroke, float(out.sat_voltage),
                float(out.sat_slew), float(out.sat_stroke), ac.strain(act, state, e)]
        assert got[k].tolist() == want
    # The run exercised every flag.
    assert got[:, 4:7].max(axis=0).tolist() == [1.0, 1.0, 1.0]


def test_step_mean_is_the_exact_impulse_of_the_linear_amplifier():
    # First-order amplifier from rest, command u held: v(t) = u (1 - exp(-w t)), whose
    # mean over h is u (1 - (1 - exp(-w h)) / (w h)).  The trapezoidal mean over the
    # 10 us sub-steps is within (w h_s)^2 / 12 of the transient part.
    act = ac.actuator_preset("P-845.37")
    u, h, w = 0.1, 1e-3, act.amplifier.omega   # 0.1 V: far from the slew limit
    state, _, mean = ac.step_mean(act, ac.initial_state(act), u, h)
    exact = act.stack.force(u) * (1 - (1 - math.exp(-w * h)) / (w * h))
    transient = act.stack.force(u) - exact
    assert abs(mean - exact) <= (w * 1e-5) ** 2 / 12 * transient * 1.01
    assert state == ac.step(act, ac.initial_state(act), u, h)[0]


def test_coupling_refuses_another_step_and_bad_values():
    slave = make("P-845.37")
    slave.set_real([vr(slave, "v_cmd")], [1.0])
    with pytest.raises(PiezoParameterError, match="hold_step"):
        slave.do_step(0.0, 2e-3)
    slave.do_step(0.0, 1e-3 * (1 + 1e-12))   # within rounding: the same step
    old = make("P-845.37", coupling=0)
    old.do_step(0.0, 2e-3)                   # the old coupling takes any step
    with pytest.raises(PiezoParameterError, match="coupling"):
        make("P-845.37", coupling=2)


def test_strain_and_force_feed_through_and_state_outputs_do_not():
    slave = make("P-845.37")
    slave.set_real([vr(slave, "v_cmd")], [20.0])
    slave.do_step(0.0, 1e-3)
    before = get(slave, STATE_OUTPUTS)
    state = ActuatorState.from_array(slave.x)
    slave.set_real([vr(slave, "elongation"), vr(slave, "v_cmd")], [4e-6, -30.0])
    # strain = elongation / gauge length at once; the force is at once the mean over the
    # coming step of the new command; state outputs wait for the next step.
    assert get(slave, ["strain"])[0] == pytest.approx(4e-6 / slave.gauge_length, rel=1e-15)
    assert get(slave, ["force"])[0] == ac.step_mean(slave.actuator(), state, -30.0, 1e-3)[2]
    assert get(slave, STATE_OUTPUTS) == before
    specs_by_name = {s.name: s for s in slave.variable_specs}
    assert specs_by_name["strain"].depends_on == ("elongation",)
    # the force depends on the elongation through the stack's servo loop (when it is on)
    assert specs_by_name["force"].depends_on == ("v_cmd", "elongation")
    for name in STATE_OUTPUTS:
        assert specs_by_name[name].depends_on == ()


def test_fmu_state_round_trip_covers_all_internal_state():
    slave = make("P-243.30", hysteresis=True, noise_std=2e-7, seed=9)
    cmds, elong = signals(80)
    drive(slave, cmds[:30], elong[:30], 1e-3)
    saved = slave._fmu_state_to_bytes(slave._get_fmu_state())
    first = drive(slave, cmds[30:], elong[30:], 1e-3)
    assert slave.x[4] != 0.0  # hysteresis state is non-trivial
    slave._set_fmu_state(slave._fmu_state_from_bytes(saved))
    again = drive(slave, cmds[30:], elong[30:], 1e-3)
    np.testing.assert_array_equal(first, again)


def test_tunable_limit_takes_effect_between_steps():
    slave = make("P-845.37")
    drive(slave, [45.0] * 20, [0.0] * 20, 1e-3)
    assert get(slave, ["voltage", "sat_voltage"]) == [pytest.approx(45.0, rel=1e-12), 0.0]
    slave.set_real([vr(slave, "v_max")], [30.0])
    drive(slave, [45.0], [0.0], 1e-3)
    assert get(slave, ["voltage", "sat_voltage"]) == [30.0, 1.0]


def test_second_order_default_and_parameters_reach_the_model():
    slave = make("P-243.30", bandwidth=800.0, damping=0.9, amp_order=1, i_max=0.01)
    act = slave.actuator()
    assert (act.amplifier.bandwidth, act.amplifier.order, act.amplifier.i_max) == (800.0, 1, 0.01)
    assert act.hysteresis is None and math.isinf(act.stroke_limit)
    assert make("P-243.30").actuator().amplifier.order == 2


def test_bad_parameter_raises_a_value_error():
    with pytest.raises(PiezoParameterError, match="stroke_limit"):
        make("P-845.37", stroke_limit=-1e-6)
    with pytest.raises(ValueError, match="v_min"):
        make("P-845.37", v_min=60.0)


def test_state_array_is_the_actuator_state():
    slave = make("P-845.37")
    drive(slave, [10.0] * 3, [0.0] * 3, 1e-3)
    state = ActuatorState.from_array(slave.x)
    assert state.tick == 300
    assert state.amp.voltage == get(slave, ["voltage"])[0]


def test_specs_one_fmu_per_preset():
    all_specs = specs(None)
    assert [s.model_identifier for s in all_specs] == list(MODELS)
    assert MODELS == {"piezo_p243_30": "P-243.30", "piezo_p243_40": "P-243.40",
                      "piezo_p845_37": "P-845.37"}
    one = specs(["piezo_p845_37"])
    assert len(one) == 1 and one[0].init_kwargs == {"preset_name": "P-845.37"}
    assert len({s.module_name for s in all_specs}) == 3
    # Other packages' names are ignored; a list with no piezo FMU is an error (a KeyError,
    # which the project registry reads as "not this package").
    assert [s.model_identifier for s in specs(["truss10", "piezo_p243_40"])] == ["piezo_p243_40"]
    with pytest.raises(UnknownModelError, match="piezo_p999") as info:
        specs(["piezo_p999"])
    assert isinstance(info.value, KeyError)


@pytest.mark.parametrize("index, value", [(5, 2.5), (2, 0.5), (5, -1.0)])
def test_an_invalid_actuator_state_is_refused_and_changes_nothing(index, value):
    """As the native kernel: a whole non-negative tick and 0/1 flags, else the previous
    state is kept."""
    from fmukit.state import FmuStateError

    slave = make("P-243.30")
    cmds, elong = signals(20)
    drive(slave, cmds, elong, 1e-3)
    state = slave._get_fmu_state()
    before = slave.x.copy()
    state["attrs"]["x"] = state["attrs"]["x"].copy()
    state["attrs"]["x"][index] = value
    with pytest.raises(FmuStateError, match="previous state is kept"):
        slave._set_fmu_state(state)
    np.testing.assert_array_equal(slave.x, before)
