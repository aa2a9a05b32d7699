"""Native ACS with its filters and per-axis bandwidths against the Python FMU, the pure
law and the linear engine's block; refusals with the Python sentence.

The C kernel computes the biquad coefficients with the same formulas in the same order
as :mod:`acsfmu.filters` and steps them in the same order, so the builds agree to a few
units of round-off (asserted at 1e-12 of each signal's peak, as in ``test_native.py``).
"""

from dataclasses import replace

import numpy as np
import pytest

from acsfmu.pid import AcsConfigError, acs_advance, acs_outputs, initial_state
from acsfmu.slave import AcsSlave
from tests.nativefmu.test_native import _initialisation_messages, assert_close, run

pytestmark = pytest.mark.slow

INPUTS = ["roll", "pitch", "yaw", "rate_x", "rate_y", "rate_z"]
TORQUE = ["Tx", "Ty", "Tz"]
OUTPUTS = TORQUE + ["wheel_speed_x", "wheel_speed_y", "wheel_speed_z"]
T = 0.1
N = 400
#: every filter on, all different, per-axis bandwidths, limits out of reach
PARAMS = {"bandwidth_y": 0.05, "bandwidth_z": 0.12, "torque_limit": 1e9,
          "momentum_limit": 1e9, "notch_hz_x": 1.3, "notch_hz_y": 0.9, "notch_hz_z": 2.2,
          "notch_zeta_num_x": 0.05, "notch_zeta_num_y": 0.1, "notch_zeta_num_z": 0.02,
          "notch_zeta_den_x": 0.5, "notch_zeta_den_y": 0.3, "notch_zeta_den_z": 0.7,
          "lowpass_hz_x": 0.8, "lowpass_hz_y": 2.0, "lowpass_hz_z": 3.0,
          "lowpass_zeta_x": 0.7, "lowpass_zeta_y": 0.5, "lowpass_zeta_z": 0.9,
          "antialias_hz": 2.5, "antialias_zeta": 0.6}


@pytest.fixture(scope="module")
def acs(suite_fmus):
    """{"py": Python acs.fmu, "native": native acs.fmu}."""
    return {"py": suite_fmus("acs", kind="python")["acs"], "native": suite_fmus("acs")["acs"]}


def _inputs():
    rng = np.random.default_rng(11)
    return np.hstack([1e-4 * np.cumsum(rng.normal(size=(N, 3)), axis=0),
                      1e-4 * rng.normal(size=(N, 3))])


def _slave(params):
    s = AcsSlave(instance_name="t")
    for name, value in params.items():
        setattr(s, name, value)
    return s


def test_native_python_pure_law_and_linear_block_agree_with_every_filter_on(acs):
    from orchestrator.analysis.blocks import _acs_block

    u = _inputs()
    kw = dict(inputs={n: u[:, i] for i, n in enumerate(INPUTS)}, outputs=OUTPUTS,
              step_size=T, n_steps=N, parameters=PARAMS)
    native, python = run(acs["native"], **kw), run(acs["py"], **kw)
    assert_close(native, python)
    # the pure law, as the slave configures it
    slave = _slave(PARAMS)
    cfg = slave.config()
    state, pure = initial_state(cfg), []
    for k in range(N):
        state = acs_advance(cfg, replace(state, time=k * T), T, u[k, :3], u[k, 3:])
        pure.append(np.concatenate(acs_outputs(cfg, state)))
    assert_close(native, np.array(pure))
    # the linear engine's block, simulated
    b = _acs_block(slave, "acs", 1, T, np.zeros(6, bool))
    x, lin = np.zeros(b.n), []
    for k in range(N):
        x = b.A @ x + b.B @ u[k]
        lin.append(b.C[:3] @ x)
    assert_close(native[:, :3], np.array(lin))
    err = np.max(np.abs(native[:, :3] - np.array(lin))) / np.max(np.abs(lin))
    print(f"native vs linear block: {err:.2e} of the peak torque")
    # and the filters did something: the unfiltered native FMU differs
    plain = run(acs["native"], **{**kw, "parameters": {
        k: v for k, v in PARAMS.items() if not k.startswith(("notch", "lowpass", "anti"))}})
    assert np.max(np.abs(plain[:, :3] - native[:, :3])) > 0.05 * np.max(np.abs(plain[:, :3]))


def test_native_sub_steps_saturates_and_restores_its_filter_states(acs):
    """Steps of 0.03 s (samples inside steps), the torque limit reached, anti-windup on,
    and a state saved mid-run and restored: the filter states are in it."""
    u = np.repeat(_inputs()[:150] * 50, 3, axis=0)[:400]
    params = {**PARAMS, "torque_limit": 0.3, "momentum_limit": 75.0}
    kw = dict(inputs={n: u[:, i] for i, n in enumerate(INPUTS)}, outputs=OUTPUTS,
              step_size=0.03, n_steps=400, parameters=params)
    (native, again), python = run(acs["native"], state_at=200, **kw), run(acs["py"], **kw)
    assert_close(native, python)
    assert np.max(np.abs(native[:, :3])) == 0.3
    np.testing.assert_array_equal(again, native)


def test_defaults_give_the_unfiltered_law(acs):
    """Filters off and per-axis bandwidths 0 equal the plain parameters: same bits."""
    u = _inputs()
    kw = dict(inputs={n: u[:, i] for i, n in enumerate(INPUTS)}, outputs=OUTPUTS,
              step_size=0.05, n_steps=N, parameters={"torque_limit": 0.01})
    spelled = {**kw["parameters"], "bandwidth_x": 0.0, "notch_hz_y": 0.0, "lowpass_hz_z": 0.0,
               "antialias_hz": 0.0, "notch_zeta_den_x": 0.9, "lowpass_zeta_y": 0.3}
    native = run(acs["native"], **kw)
    np.testing.assert_array_equal(run(acs["native"], **{**kw, "parameters": spelled}), native)
    assert_close(native, run(acs["py"], **kw))


@pytest.mark.parametrize("params", [
    {"notch_hz_y": 6.0},
    {"sample_time": 0.01, "lowpass_hz_z": 50.0},
    {"antialias_hz": -0.5},
    {"antialias_hz": 1.0, "antialias_zeta": 0.0},
    {"notch_hz_x": 1.0, "notch_zeta_num_x": -0.05},
])
def test_native_refuses_a_filter_with_the_python_sentence(acs, params):
    with pytest.raises(AcsConfigError) as info:
        _slave(params).exit_initialization_mode()
    messages = _initialisation_messages(acs["native"], params)
    assert str(info.value) in messages, messages
    assert "Nyquist frequency" in str(info.value) and len(messages) == 1
