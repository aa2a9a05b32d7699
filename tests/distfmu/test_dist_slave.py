"""Disturbance slave as a Python object, then as a built FMU in fmpy, C host, libcosim."""

import zipfile
from xml.etree.ElementTree import fromstring, tostring

import numpy as np
import pytest

from distfmu.fmuspec import specs
from distfmu.presets import PRESETS, get_preset, randomized, retimed
from distfmu.slave import DisturbanceSlave
from distfmu.sources import (WRENCH_NAMES, Chopper, Harmonic, ScanMirror, Slew,
                             SourceError, SpeedProfile, Stepper, Table, WheelImbalance)
from fmutools.build import FmuSpec, build_fmu
from fmukit.modeldesc import check_model_description

H = 1e-3
N = 200


def _slave(preset, **params):
    s = DisturbanceSlave(instance_name="d")
    s.preset = preset
    for k, v in params.items():
        setattr(s, k, v)
    s.setup_experiment(0.0)
    s.exit_initialization_mode()
    return s


# ---------------------------------------------------------------- plain Python object
def test_outputs_have_no_dependencies_and_units():
    root = DisturbanceSlave(instance_name="d").to_xml()
    assert check_model_description(tostring(root)) == []
    names = [sv.get("name") for sv in root.iter("ScalarVariable")]
    deps = {names[int(u.get("index")) - 1]: u.get("dependencies")
            for u in root.iterfind("ModelStructure/Outputs/Unknown")}
    assert deps == {n: "" for n in WRENCH_NAMES}
    units = {sv.get("name"): sv.find("Real").get("unit") for sv in root.iter("ScalarVariable")
             if sv.find("Real") is not None}
    assert units["Fx"] == "N" and units["Mz"] == "N.m" and units["wheel_speed"] == "rad/s"


def test_slave_reproduces_the_gated_scaled_source():
    s = _slave("swir_cryocooler", scale=2.0, start_time=0.05, stop_time=0.15)
    src = PRESETS["swir_cryocooler"].source
    for k in range(N):
        s.do_step(k * H, H)
        t = (k + 1) * H
        expected = 2.0 * src.wrench(t) if 0.05 <= t < 0.15 else np.zeros(6)
        np.testing.assert_allclose(s.wrench, expected, atol=1e-15)


def test_wheel_speed_input_drives_the_rwa_without_feedthrough():
    s = _slave("rwa", use_speed_input=True)
    src = get_preset("rwa").source
    s.wheel_speed = 50.0
    before = s.wrench.copy()
    s.wheel_speed = 80.0  # setting the input does not change the current output
    np.testing.assert_array_equal(s.wrench, before)
    theta = 0.0
    for k in range(20):
        s.wheel_speed = 100.0 + 5.0 * k
        s.do_step(k * H, H)
        theta += (100.0 + 5.0 * k) * H
        np.testing.assert_allclose(s.wrench, src.wrench_at(theta, 100.0 + 5.0 * k), rtol=1e-12)


def test_seed_randomises_phases_reproducibly():
    a = randomized(PRESETS["swir_cryocooler"].source, 5)
    b = randomized(PRESETS["swir_cryocooler"].source, 5)
    c = randomized(PRESETS["swir_cryocooler"].source, 6)
    assert a == b and a != c and randomized(a, 0) is a
    t = np.linspace(0, 1, 101)
    # phases change, the amplitude spectrum does not: same RMS over whole periods
    np.testing.assert_allclose(np.std(a.wrench(t)[:-1, 2]),
                               np.std(PRESETS["swir_cryocooler"].source.wrench(t)[:-1, 2]),
                               rtol=0.05)


def test_state_round_trip():
    s = _slave("rwa", use_speed_input=True)
    for k in range(5):
        s.wheel_speed = 120.0
        s.do_step(k * H, H)
    saved = s._get_fmu_state()
    s.do_step(5 * H, H)
    first = s.wrench.copy()
    s.wheel_speed = 999.0
    s.do_step(6 * H, H)
    s._set_fmu_state(saved)
    s.do_step(5 * H, H)
    np.testing.assert_array_equal(s.wrench, first)


def test_unknown_preset_is_a_clear_error():
    with pytest.raises(KeyError, match="'bogus' is unknown"):
        _slave("bogus")


# ---------------------------------------------------------------- frequency_scale
K = 1.05
T_GRID = np.linspace(0.0, 7.0, 3001)


def test_retimed_harmonic_is_the_source_on_a_faster_clock():
    """sin(2 pi h (k f) t + phi) is the original at time k t, to round-off."""
    src = randomized(get_preset("swir_cryocooler").source, 3)
    np.testing.assert_allclose(retimed(src, K).wrench(T_GRID), src.wrench(K * T_GRID),
                               rtol=0, atol=1e-12 * np.abs(src.wrench(T_GRID)).max())


def test_retimed_wheel_turns_faster_and_its_forces_follow_the_speed_squared():
    """Masterson: every force and torque is C Omega^2 sin(h Omega t + phi), so the wheel
    at k Omega is k^2 times the original at time k t (constant speed and a profile)."""
    src = randomized(get_preset("rwa").source, 3)
    w = src.wrench(T_GRID)
    np.testing.assert_allclose(retimed(src, K).wrench(T_GRID), K**2 * src.wrench(K * T_GRID),
                               rtol=0, atol=1e-11 * np.abs(w).max())
    prof = SpeedProfile(times=(0.0, 7.0), speeds=(50.0, 150.0))
    wheel = WheelImbalance(harmonics=(1.0,), force_coeffs=(1e-6,), torque_coeffs=(1e-5,),
                           speed=prof)
    fast = retimed(wheel, K)
    assert fast.speed.speeds == (50.0 * K, 150.0 * K) and fast.speed.times == prof.times


def test_retimed_keeps_the_shapes_in_time_and_scales_the_repetition():
    chop = Chopper(frequency=7.0, amplitude=0.02, rise_time=0.005)
    scan = ScanMirror(inertia=0.02, period=12.0, amplitude=0.45, turnaround=0.1)
    step = Stepper(step_rate=0.5, peak_torque=0.5, pulse_width=0.5)
    slew = Slew(angle=0.1, max_rate=0.1, max_accel=0.2, inertia=0.03, repeat=30.0)
    assert retimed(chop, K) == Chopper(frequency=7.0 * K, amplitude=0.02, rise_time=0.005)
    assert retimed(scan, K).period == 12.0 / K and retimed(scan, K).turnaround == 0.1
    assert retimed(step, K).step_rate == 0.5 * K and retimed(step, K).pulse_width == 0.5
    assert retimed(slew, K).repeat == 30.0 / K and retimed(slew, K).max_accel == 0.2
    assert retimed(chop, 1.0) is chop
    none = get_preset("none").source
    assert retimed(none, K) is none   # no disturbance stays none (it is in most events)


@pytest.mark.parametrize("source,match", [
    (Slew(angle=0.1, max_rate=0.1, max_accel=0.2, inertia=0.03), "a Slew source does not"),
    (Table(np.array([0.0, 1.0]), np.zeros((2, 6))), "a Table source does not repeat"),
])
def test_a_source_that_does_not_repeat_refuses_a_frequency_scale(source, match):
    with pytest.raises(SourceError, match=match):
        retimed(source, K)
    assert retimed(source, 1.0) is source


@pytest.mark.parametrize("factor", [0.0, -1.0, float("nan"), float("inf")])
def test_frequency_scale_must_be_positive_and_finite(factor):
    with pytest.raises(SourceError, match="positive finite number"):
        retimed(Harmonic(frequency=22.0, amplitudes=(1.0,)), factor)


def test_slave_frequency_scale_gives_the_retimed_randomised_source():
    s = _slave("tir_cryocooler", seed=5, frequency_scale=K)
    src = randomized(retimed(get_preset("tir_cryocooler").source, K), 5)
    ref = _slave("tir_cryocooler", seed=5)
    # the slave's time is on a picosecond grid (fmukit.timing), (k + 1) H may be an ulp
    # away: 2 pi 78 Hz x 0.2 s x eps ~ 2e-14 rad on amplitudes below 0.5 N
    for k in range(N):
        s.do_step(k * H, H)
        ref.do_step(k * H, H)
        np.testing.assert_allclose(s.wrench, src.wrench((k + 1) * H), rtol=0, atol=1e-14)
    assert np.abs(s.wrench - ref.wrench).max() > 1e-3   # the factor is not ignored


def test_slave_refuses_a_frequency_scale_it_cannot_apply():
    with pytest.raises(SourceError, match="wheel_speed input"):
        _slave("rwa", use_speed_input=True, frequency_scale=K)
    with pytest.raises(SourceError, match="positive finite number"):
        _slave("none", frequency_scale=-1.0)


# ---------------------------------------------------------------- built FMUs
@pytest.fixture(scope="module")
def fmus(tmp_path_factory, suite_fmus):
    out = tmp_path_factory.mktemp("fmus")
    (spec,) = specs(["disturbance"])
    assert spec.model_identifier == "disturbance"
    real = suite_fmus("disturbance", kind="python")["disturbance"]
    # the test hosts set Real parameters only: a variant whose String/Boolean defaults
    # select the input-driven wheel exercises the same slave class in every host
    variant = build_fmu(FmuSpec("disturbance_rwa_test", spec.slave_class,
                                init_kwargs={"default_preset": "rwa",
                                             "default_speed_input": True}), out)
    return real, variant


@pytest.mark.slow
def test_built_fmus_validate_without_message(fmus):
    from fmutools.validate import validate_fmu

    for fmu in fmus:
        assert validate_fmu(fmu) == []
    with zipfile.ZipFile(fmus[0]) as zf:
        root = fromstring(zf.read("modelDescription.xml"))
    assert root.get("modelName") and root.find("CoSimulation").get("modelIdentifier") == \
        "disturbance"


@pytest.mark.slow
def test_fmpy_string_parameter_selects_the_preset(fmus):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmus[0]))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzip = extract(str(fmus[0]))
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier="disturbance",
                  instanceName="d")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.setString([vr["preset"]], ["vnir_pointing"])
    s.setReal([vr["scale"]], [0.5])
    s.enterInitializationMode()
    s.exitInitializationMode()
    outs = [vr[n] for n in WRENCH_NAMES]
    h, n = 0.01, 150
    y = []
    for k in range(n):
        s.doStep(k * h, h)
        y.append(s.getReal(outs))
    s.terminate()
    s.freeInstance()
    t = (np.arange(n) + 1) * h
    np.testing.assert_allclose(np.array(y), 0.5 * PRESETS["vnir_pointing"].source.wrench(t),
                               atol=1e-15)
    assert np.abs(y).max() > 1.0  # the slew started at 1 s with 4 N m pulses


@pytest.mark.slow
def test_three_hosts_give_identical_outputs(fmus):
    from tests.support.hosts import run_c_host, run_fmpy, run_libcosim

    rng = np.random.default_rng(11)
    speed = 100.0 + np.cumsum(rng.normal(size=N))
    kw = dict(inputs={"wheel_speed": speed}, outputs=list(WRENCH_NAMES), step_size=H,
              n_steps=N, parameters={"scale": 3.0})
    y = run_fmpy(fmus[1], **kw)
    # reference: the pure stepping form
    src = get_preset("rwa").source
    theta = np.cumsum(speed * H)
    np.testing.assert_allclose(y, 3.0 * src.wrench_at(theta, speed), rtol=1e-9, atol=1e-15)
    np.testing.assert_array_equal(run_c_host(fmus[1], **kw), y)
    # libcosim counts time in integer nanoseconds and hands back a step size converted
    # from them, so the rotor angle may differ in the last bits: 1e-12 of full scale
    np.testing.assert_allclose(run_libcosim(fmus[1], **kw), y, rtol=0,
                               atol=1e-12 * np.abs(y).max())
