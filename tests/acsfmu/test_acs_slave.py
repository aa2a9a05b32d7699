"""ACS slave as a Python object, then the built ``acs`` FMU in fmpy, C host, libcosim."""

from dataclasses import replace
from xml.etree.ElementTree import tostring

import numpy as np
import pytest

from acsfmu.design import pid_gains_for
from acsfmu.fmuspec import specs
from acsfmu.pid import AcsConfig, PidGains, acs_advance, acs_outputs, initial_state
from acsfmu.slave import AcsSlave
from fmukit.modeldesc import check_model_description

INPUTS = ["roll", "pitch", "yaw", "rate_x", "rate_y", "rate_z"]
OUTPUTS = ["Tx", "Ty", "Tz", "wheel_speed_x", "wheel_speed_y", "wheel_speed_z"]
N = 120


def _inputs():
    rng = np.random.default_rng(5)
    att = 1e-4 * np.cumsum(rng.normal(size=(N, 3)), axis=0)
    rate = 1e-5 * rng.normal(size=(N, 3))
    return np.hstack([att, rate])


def _reference(u, h=0.1, inertia=(7600.0, 36000.0, 36000.0), momentum0=(1.0, 0.0, -1.0)):
    """The pure stepping functions, driven like a master would."""
    gains = [pid_gains_for(j, 0.1, 50.0, 0.1) for j in inertia]
    cfg = AcsConfig(PidGains(*(list(g) for g in zip(*gains))), sample_time=0.1,
                    torque_limit=0.4, momentum_limit=75.0, wheel_inertia=0.2)
    state = initial_state(cfg, 0.0, momentum0)
    y = []
    for k in range(u.shape[0]):
        state = acs_advance(cfg, replace(state, time=k * h), h, u[k, :3], u[k, 3:])
        torque, speed = acs_outputs(cfg, state)
        y.append(np.concatenate([torque, speed]))
    return np.array(y)


def test_outputs_have_no_dependencies():
    root = AcsSlave(instance_name="a").to_xml()
    assert check_model_description(tostring(root)) == []
    names = [sv.get("name") for sv in root.iter("ScalarVariable")]
    deps = {names[int(x.get("index")) - 1]: x.get("dependencies")
            for x in root.iterfind("ModelStructure/Outputs/Unknown")}
    assert deps == {n: "" for n in OUTPUTS}


def test_slave_matches_pure_functions_and_saves_state():
    s = AcsSlave(instance_name="a")
    s.momentum0_x, s.momentum0_z = 1.0, -1.0
    s.setup_experiment(0.0)
    s.exit_initialization_mode()
    np.testing.assert_allclose(s.wheel_speed, [5.0, 0.0, -5.0])  # h0 / J_wheel
    u = _inputs()
    y = []
    for k in range(N):
        s.attitude[:], s.rate[:] = u[k, :3], u[k, 3:]
        s.do_step(k * 0.1, 0.1)
        y.append(np.concatenate([s.torque, s.wheel_speed]))
        if k == 59:
            saved = s._get_fmu_state()
    np.testing.assert_allclose(np.array(y), _reference(u), rtol=1e-12, atol=1e-15)
    s._set_fmu_state(saved)
    s.attitude[:], s.rate[:] = u[60, :3], u[60, 3:]
    s.do_step(6.0, 0.1)
    np.testing.assert_array_equal(np.concatenate([s.torque, s.wheel_speed]), y[60])


def test_bandwidth_too_high_for_the_rate_names_the_instance():
    s = AcsSlave(instance_name="acs1")
    s.bandwidth = 5.0
    with pytest.raises(ValueError, match="'acs1'.*too high for sample time"):
        s.exit_initialization_mode()


@pytest.fixture(scope="module")
def fmu(suite_fmus):
    (spec,) = specs(None)
    assert spec.model_identifier == "acs"
    return suite_fmus("acs", kind="python")["acs"]


@pytest.mark.slow
def test_fmu_validates_and_three_hosts_agree(fmu):
    from tests.support.hosts import run_c_host, run_fmpy, run_libcosim
    from fmutools.validate import validate_fmu

    assert validate_fmu(fmu) == []
    u = _inputs()
    kw = dict(inputs={n: u[:, i] for i, n in enumerate(INPUTS)}, outputs=OUTPUTS,
              step_size=0.1, n_steps=N,
              parameters={"momentum0_x": 1.0, "momentum0_z": -1.0})
    y = run_fmpy(fmu, **kw)
    np.testing.assert_allclose(y, _reference(u), rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(run_c_host(fmu, **kw), y)
    # libcosim's nanosecond clock hands the slave step sizes rounded in the last bit
    scale = np.abs(y).max(axis=0)
    np.testing.assert_allclose(run_libcosim(fmu, **kw) / scale, y / scale, rtol=0, atol=1e-12)


@pytest.mark.slow
def test_fmu_sub_steps_at_its_own_rate(fmu):
    from tests.support.hosts import run_fmpy

    u = _inputs()[:40]
    u2 = np.repeat(u, 2, axis=0)  # same held inputs, communication step 0.05 s
    y1 = run_fmpy(fmu, inputs={n: u[:, i] for i, n in enumerate(INPUTS)}, outputs=OUTPUTS,
                  step_size=0.1, n_steps=40)
    y2 = run_fmpy(fmu, inputs={n: u2[:, i] for i, n in enumerate(INPUTS)}, outputs=OUTPUTS,
                  step_size=0.05, n_steps=80)
    np.testing.assert_allclose(y2[1::2], y1, rtol=1e-9, atol=1e-15)
    assert np.abs(y1[:, :3]).max() > 1e-3  # the controller did act
