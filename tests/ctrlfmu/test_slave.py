"""The controller slave as a plain Python object: timing, parameters, state, structure."""

import numpy as np
import pytest

from ctrlfmu.designs import design
from ctrlfmu.law import DiscreteLaw, save_law, simulate
from ctrlfmu.slave import ControllerParameterError, ControllerSlave


def make_slave(tmp_path, law, start_time=0.0, **params):
    save_law(law, tmp_path / "law.npz")
    slave = ControllerSlave(instance_name="ctrl", resources=str(tmp_path))
    for name, value in params.items():
        setattr(slave, name, value)
    slave.setup_experiment(start_time, None, None)
    slave.enter_initialization_mode()
    slave.exit_initialization_mode()
    return slave


def outputs(slave):
    return np.array([getattr(slave, f"u{i + 1}") for i in range(slave.law.n_outputs)])


def run(slave, y, h, t0=0.0):
    """Set y[k] and step from t0 + k h (never accumulated); outputs after each step."""
    y = np.asarray(y, dtype=float).reshape(len(y), -1)
    out = []
    for k, yk in enumerate(y):
        for j, v in enumerate(yk):
            setattr(slave, f"y{j + 1}", v)
        slave.do_step(t0 + k * h, h)
        out.append(outputs(slave))
    return np.array(out)


def direct_law():
    """Non-delayed 1-state law with feedthrough from y1 only (D = [[0.5, 0]])."""
    return DiscreteLaw([[0.8]], [[1.0, 0.2]], [[0.3]], [[0.5, 0.0]], 0.01, delayed=False,
                       name="direct")


def test_variables_units_and_dependencies(tmp_path):
    slave = make_slave(tmp_path, design("testbed_isolation"))
    specs = {s.name: s for s in slave.variable_specs}
    assert (specs["y1"].unit, specs["y2"].unit, specs["u1"].unit) == ("m/s2", "m/s2", "V")
    assert specs["u1"].depends_on == ("r1",)   # Eq. (11): none from y; r1 is added directly
    assert specs["enable"].type == "Boolean" and specs["enable"].causality == "input"
    assert (slave.u_min, slave.u_max) == (-50.0, 50.0)
    direct = make_slave(tmp_path, direct_law())
    assert {s.name: s for s in direct.variable_specs}["u1"].depends_on == ("y1", "r1", "enable")


@pytest.mark.parametrize("name", ["truss10_strain_long", "testbed_isolation"])
def test_synchronous_steps_equal_the_pure_law(tmp_path, name):
    law = design(name)
    y = np.random.default_rng(3).standard_normal((80, law.n_inputs)) * (
        1e-6 if law.input_units[0] == "1" else 0.1)
    slave = make_slave(tmp_path, law)
    out = run(slave, y, law.dt)
    u, _ = simulate(law, y)
    # Output after step k (at t_{k+1}) is u(k+1) of Eq. (11), bit for bit.
    np.testing.assert_array_equal(out[:-1], u[1:])
    assert np.ptp(out) > 0


def test_slow_master_holds_input_over_several_samples(tmp_path):
    law = design("eos_isolation")
    y = 1e-5 * np.sin(np.arange(30))
    slave = make_slave(tmp_path, law)
    out = run(slave, y, 3 * law.dt)
    u, _ = simulate(law, np.repeat(y, 3))
    np.testing.assert_array_equal(out[:-1, 0], u[3::3, 0][: len(out) - 1])


@pytest.mark.parametrize("ratio", [0.5, 0.7, 2.5])
def test_sub_sample_and_uneven_steps_act_as_zero_order_hold(tmp_path, ratio):
    law = design("truss10_strain_diag").with_limits(-np.inf, np.inf)
    slave = make_slave(tmp_path, law)
    h = ratio * law.dt
    n = 60
    y_step = 1e-6 * np.cos(0.4 * np.arange(n))
    out = run(slave, y_step, h)
    # Reference: sample j sees the input held over the step containing t_j; the command
    # at tau is the one applied in the sample interval containing tau.
    n_samples = int(np.ceil(n * ratio)) + 1
    t_samples = np.arange(n_samples) * law.dt
    step_of_sample = np.floor(t_samples / h + 1e-9).astype(int)
    u, _ = simulate(law, y_step[np.minimum(step_of_sample, n - 1)])
    tau = (np.arange(n) + 1) * h
    idx = np.floor(tau / law.dt + 1e-9).astype(int)
    np.testing.assert_array_equal(out[:, 0], u[idx, 0])
    if ratio < 1:
        assert np.sum(np.diff(out[:, 0]) == 0) >= n * (1 - ratio) - 2   # held between samples


def test_gain_limits_and_activation_parameters(tmp_path):
    law = design("truss10_strain_diag")
    y = 1e-6 * np.ones(100)
    base = run(make_slave(tmp_path, law), y, law.dt)
    scaled = run(make_slave(tmp_path, law, gain=-2.0, u_min=-1e9, u_max=1e9), y, law.dt)
    np.testing.assert_allclose(scaled, -2.0 * base, rtol=1e-12)
    square = 1e-6 * np.sign(np.sin(0.1 * np.arange(100)) + 1e-3)
    limited = run(make_slave(tmp_path, law, u_min=-0.5, u_max=0.25), square, law.dt)
    assert limited.max() == 0.25 and limited.min() == -0.5
    late = run(make_slave(tmp_path, law, t_on=0.1), y, law.dt)      # 25 samples at 250 Hz
    np.testing.assert_array_equal(late[:25], 0.0)   # outputs at t_1..t_25
    np.testing.assert_array_equal(late[25:], base[:75])


def test_t_on_is_absolute_time_with_a_nonzero_start(tmp_path):
    law = design("truss10_strain_diag")
    y = 1e-6 * np.ones(60)
    slave = make_slave(tmp_path, law, start_time=1.0, t_on=1.04)      # 10 samples after start
    out = run(slave, y, law.dt, t0=1.0)
    base = run(make_slave(tmp_path, law), y, law.dt)
    np.testing.assert_array_equal(out[:10], 0.0)
    np.testing.assert_array_equal(out[10:], base[:50])


def test_enable_input_switches_off_and_resets(tmp_path):
    law = design("truss10_strain_diag")
    slave = make_slave(tmp_path, law)
    y = 1e-6 * np.ones(40)
    first = run(slave, y[:20], law.dt)
    slave.enable = False
    off = run(slave, y[:5], law.dt, t0=20 * law.dt)
    slave.enable = True
    again = run(slave, y[:20], law.dt, t0=25 * law.dt)
    np.testing.assert_array_equal(off, 0.0)
    np.testing.assert_array_equal(again, first)       # restarted from rest


def test_non_delayed_law_has_feedthrough_at_sample_instants(tmp_path):
    law = direct_law()
    slave = make_slave(tmp_path, law)
    slave.set_real([vr_of(slave, "y1")], [2.0])
    assert slave.u1 == 1.0                                  # D y at t_0, x = 0
    slave.set_real([vr_of(slave, "y2")], [5.0])
    assert slave.u1 == 1.0                                  # D[0, 1] = 0
    slave.set_real([vr_of(slave, "y1")], [4.0])
    assert slave.u1 == 2.0                                  # recomputed on setReal
    slave.do_step(0.0, 0.005)                               # half a sample: hold u(0)
    slave.set_real([vr_of(slave, "y1")], [0.0])
    assert slave.u1 == 2.0
    slave.do_step(0.005, 0.005)                             # at t_1: C x(1) + D y
    x1 = 0.8 * 0 + 4.0 + 0.2 * 5.0
    assert slave.u1 == pytest.approx(0.3 * x1, rel=1e-15)
    slave.set_boolean([vr_of(slave, "enable")], [False])
    assert slave.u1 == 0.0


def vr_of(slave, name):
    return {s.name: s.value_reference for s in slave.variable_specs}[name]


def test_fmu_state_round_trip_is_exact(tmp_path):
    law = design("testbed_isolation")
    slave = make_slave(tmp_path, law, t_on=0.01)
    y = np.random.default_rng(5).standard_normal((200, 2))
    run(slave, y[:50], law.dt)
    blob = slave._fmu_state_to_bytes(slave._get_fmu_state())
    first = run(slave, y[50:], law.dt, t0=50 * law.dt)
    slave._set_fmu_state(slave._fmu_state_from_bytes(blob))
    again = run(slave, y[50:], law.dt, t0=50 * law.dt)
    np.testing.assert_array_equal(first, again)
    # into a fresh instance too
    fresh = ControllerSlave(instance_name="other", resources=str(tmp_path))
    fresh._set_fmu_state(fresh._fmu_state_from_bytes(blob))
    np.testing.assert_array_equal(run(fresh, y[50:], law.dt, t0=50 * law.dt), first)


def test_a_state_the_controller_refuses_changes_nothing(tmp_path):
    """A saved state whose limits are crossed (u_min > u_max): refused as a whole, and
    the controller continues exactly as if no restore had been tried."""
    from fmukit.state import FmuStateError

    law = design("testbed_isolation")
    slave = make_slave(tmp_path, law)
    twin = make_slave(tmp_path, law)
    y = np.random.default_rng(6).standard_normal((100, 2))
    run(slave, y[:20], law.dt)
    run(twin, y[:20], law.dt)
    state = slave._get_fmu_state()
    state["attrs"]["_x"] = state["attrs"]["_x"] + 1.0     # a state that would change x
    state["real"][slave._real_slot[vr_of(slave, "u_min")]] = 5.0
    state["real"][slave._real_slot[vr_of(slave, "u_max")]] = -5.0
    with pytest.raises(FmuStateError, match="u_min <= u_max.*previous state is kept"):
        slave._set_fmu_state(state)
    np.testing.assert_array_equal(run(slave, y[20:], law.dt, t0=20 * law.dt),
                                  run(twin, y[20:], law.dt, t0=20 * law.dt))


def test_bad_parameters_are_reported(tmp_path):
    with pytest.raises(ControllerParameterError, match="u_min <= u_max"):
        make_slave(tmp_path, design("eos_isolation"), u_min=1.0, u_max=-1.0)
    with pytest.raises(ControllerParameterError, match="t_on"):
        make_slave(tmp_path, design("eos_isolation"), t_on=-1.0)
    mixed = DiscreteLaw(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((2, 0)), np.ones((2, 1)),
                        0.01, u_min=[-1.0, -2.0], u_max=[1.0, 2.0])
    with pytest.raises(ControllerParameterError, match="different limits per output"):
        make_slave(tmp_path, mixed)
