"""Native (C99) FMUs against their Python twins, FMI validity, state, C-only hosts.

The six FMUs of the ten-bay closed loop are built once per module, both flavours, into
a temporary folder.  Tolerances: the C kernels are line-by-line ports of the Python
step functions; what differs is the order of a few floating-point sums (BLAS vs a
plain loop) and libm vs numpy's exp/sin, so outputs agree to a few units of round-off
relative to each signal's peak (asserted at 1e-12).
"""

import ctypes
import shutil
import subprocess
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from nativefmu.build import CFLAGS, compile_sources, mingw_compiler

pytestmark = pytest.mark.slow

EOS_MODELS = ("eos_testbed_structure", "piezo_p845_37", "controller_eos_isolation",
              "controller_testbed_isolation")
MODELS = ("truss10_structure", "piezo_p243_30", "piezo_p243_40",
          "controller_truss10_strain_diag", "controller_truss10_strain_long", "excitation", "acs",
    "disturbance")
REPO = Path(__file__).resolve().parents[2]
RTOL = 1e-12


@pytest.fixture(scope="module")
def fmus(tmp_path_factory, suite_fmus, suite_fmu_dir):
    """{"py": folder of Python FMUs, "native": folder of native FMUs}."""
    from fmutools.registry import collect_specs

    # the session's suite FMUs: native ones built from their Python twins (python/)
    names = [s.model_identifier for s in collect_specs(list(MODELS) + list(EOS_MODELS))]
    suite_fmus(*names)
    return {"py": suite_fmu_dir / "python", "native": suite_fmu_dir}


def _md(path):
    with zipfile.ZipFile(path) as z:
        return ET.fromstring(z.read("modelDescription.xml"))


def run(fmu, *, outputs, step_size, n_steps, inputs=None, parameters=None, state_at=None):
    """Outputs after every step in fmpy; parameters of any type; optional state replay.

    With ``state_at=k`` the FMU state is saved (serialised and deserialised) before step
    ``k``, the run continues to the end, then the state is restored and steps ``k..``
    are run again: returns ``(y, y_again)``.
    """
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmu))
    var = {v.name: v for v in md.modelVariables}
    unzip = extract(str(fmu))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="t")
    try:
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        for name, value in (parameters or {}).items():
            v = var[name]
            setter = {"Real": slave.setReal, "Integer": slave.setInteger,
                      "Boolean": slave.setBoolean, "String": slave.setString}[v.type]
            setter([v.valueReference], [value])
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        in_vrs = [var[n].valueReference for n in (inputs or {})]
        u = np.column_stack([np.broadcast_to(np.asarray(c, float), (n_steps,))
                             for c in (inputs or {}).values()]) if inputs else None
        out_vrs = [var[n].valueReference for n in outputs]

        def steps(k0, k1, y):
            for k in range(k0, k1):
                if in_vrs:
                    slave.setReal(in_vrs, u[k].tolist())
                slave.doStep(currentCommunicationPoint=k * step_size,
                             communicationStepSize=step_size)
                y[k] = slave.getReal(out_vrs)

        y = np.zeros((n_steps, len(out_vrs)))
        if state_at is None:
            steps(0, n_steps, y)
            return y
        steps(0, state_at, y)
        state = slave.getFMUstate()
        blob = slave.serializeFMUstate(state)
        slave.freeFMUstate(state)
        steps(state_at, n_steps, y)
        again = y.copy()
        state = slave.deSerializeFMUstate(blob)
        slave.setFMUstate(state)
        slave.freeFMUstate(state)
        steps(state_at, n_steps, again)
        return y, again
    finally:
        slave.terminate()
        slave.freeInstance()
        shutil.rmtree(unzip, ignore_errors=True)


def assert_close(native, python, rtol=RTOL):
    peak = np.maximum(np.max(np.abs(python), axis=0), 1e-300)
    err = np.max(np.abs(native - python), axis=0) / peak
    assert np.all(err <= rtol), f"relative errors {err}"


# ---------------------------------------------------------------------- model description

def _signature(root):
    """Everything of a model description that must match, as comparable data."""
    vars_ = []
    for sv in root.iterfind("ModelVariables/ScalarVariable"):
        typed = next(iter(sv))
        vars_.append((dict(sv.attrib), typed.tag, dict(typed.attrib)))
    structure = ET.tostring(root.find("ModelStructure"))
    units = ET.tostring(root.find("UnitDefinitions"))
    cs = root.find("CoSimulation")
    flags = {k: cs.get(k) for k in ("modelIdentifier", "canGetAndSetFMUstate",
                                    "canSerializeFMUstate",
                                    "canHandleVariableCommunicationStepSize")}
    default = root.find("DefaultExperiment")
    return vars_, structure, units, flags, dict(default.attrib) if default is not None else None


@pytest.mark.parametrize("model", MODELS)
def test_model_description_matches_python_fmu(fmus, model):
    native, py = fmus["native"] / f"{model}.fmu", fmus["py"] / f"{model}.fmu"
    assert _signature(_md(native)) == _signature(_md(py))
    root = _md(native)
    cs = root.find("CoSimulation")
    assert cs.get("needsExecutionTool") == "false"
    listed = [f.get("name") for f in cs.iterfind("SourceFiles/File")]
    with zipfile.ZipFile(native) as z:
        names = set(z.namelist())
    assert listed and all(f"sources/{name}" in names for name in listed)
    assert f"binaries/linux64/{model}.so" in names
    assert not any(n.endswith(".py") for n in names)


@pytest.mark.parametrize("model", MODELS)
def test_fmpy_validation_and_project_checks_are_clean(fmus, model):
    from fmpy.validation import validate_fmu as fmpy_validate

    from fmutools.validate import validate_fmu

    path = fmus["native"] / f"{model}.fmu"
    assert fmpy_validate(str(path)) == []
    assert validate_fmu(path, strict=True) == []


# ---------------------------------------------------------------------- same outputs

N = 1500
T = np.arange(N) * 1e-3
RNG = np.random.default_rng(11)


def _pair(fmus, model, **kw):
    return (run(fmus["native"] / f"{model}.fmu", **kw), run(fmus["py"] / f"{model}.fmu", **kw))


@pytest.mark.parametrize("step", [1e-3, 4e-3])
def test_structure_equals_python_on_random_loads(fmus, step):
    root = _md(fmus["native"] / "truss10_structure.fmu")
    names = [(sv.get("name"), sv.get("causality"))
             for sv in root.iterfind("ModelVariables/ScalarVariable")]
    ins = [n for n, c in names if c == "input"]
    outs = [n for n, c in names if c == "output"]
    inputs = {n: 50 * np.sin(2 * np.pi * (8.4 + i) * T) * (T < 1.0) + RNG.standard_normal(N)
              for i, n in enumerate(ins)}
    assert_close(*_pair(fmus, "truss10_structure", outputs=outs, step_size=step, n_steps=N,
                        inputs=inputs))


def test_structure_on_an_undeclared_step_is_discretised_in_c(fmus):
    """2 ms is not a shipped step: C discretises it.  The stiff Ritz block's exponential
    is taken after an exact power-of-two balancing, so it keeps full accuracy (without
    the balancing the two implementations differed by ~1e-8 on the accelerations)."""
    outs = ["strain_long", "strain_diag", "acc_tip_x", "los_tip_pitch"]
    inputs = {"fc_long": 100 * np.sin(2 * np.pi * 9.5 * T), "fc_diag": RNG.standard_normal(N)}
    native, python = _pair(fmus, "truss10_structure", outputs=outs, step_size=2e-3,
                           n_steps=N, inputs=inputs)
    err = np.max(np.abs(native - python), axis=0) / np.max(np.abs(python), axis=0)
    assert np.all(err < 1e-12), err


PIEZO_OUTPUTS = ["force", "voltage", "current", "free_stroke", "strain", "sat_voltage",
                 "sat_slew", "sat_stroke"]


@pytest.mark.parametrize("model,params", [
    ("piezo_p243_30", {}),
    ("piezo_p243_40", {"hysteresis": True, "noise_std": 1e-7, "resolution": 1e-8, "seed": 7}),
    ("piezo_p243_30", {"amp_order": 1, "stroke_limit": 2e-5, "v_max": 600.0, "v_min": -100.0}),
    ("piezo_p243_40", {"internal_step": 3e-5, "hysteresis": True, "i_max": 0.5}),
    # the stacks' servo loop on the elongation (rails and slew reached by the integrator)
    ("piezo_p243_30", {"servo_bandwidth": 100.0, "servo_plant_gain": 2e-8}),
    ("piezo_p243_40", {"servo_bandwidth": 40.0, "amp_order": 1, "hysteresis": True,
                       "v_max": 300.0}),
    ("piezo_p845_37", {"servo_bandwidth": 150.0, "coupling": 0}),
])
def test_piezo_equals_python(fmus, model, params):
    v_cmd = 1200 * np.sin(2 * np.pi * 30 * T) + 200 * RNG.standard_normal(N)
    elong = 1e-6 * np.sin(2 * np.pi * 9 * T)
    native, python = _pair(fmus, model, outputs=PIEZO_OUTPUTS, step_size=1e-3, n_steps=N,
                           inputs={"v_cmd": v_cmd, "elongation": elong}, parameters=params)
    # the second-order amplifier's 3x3 exponential is a product of BLAS (numpy) vs plain
    # loops (C) products; with 34 sub-steps of a non-multiple internal step the rate state
    # (current output) gathers 2e-12 of its peak, everything else stays below 1e-12
    assert_close(native, python, rtol=5e-12 if "internal_step" in params else RTOL)
    if not params:
        assert np.any(python[:, 6] != 0)  # the slew limit acts: the comparison covers it


@pytest.mark.parametrize("build", ["native", "py"])
def test_piezo_flags_a_current_limit_reached_only_inside_a_step(fmus, build):
    """A 100 V command step into the diagonal's Trek amplifier: its 50 mA limit acts in
    the first 1 ms step only before the step's end (34 mA there).  The 1 ms step's flag
    equals its 100 sub-steps run as 10 us steps (one sub-step a step), or-ed; the flag of
    the last of them alone is clear (what a step's flags reported before)."""
    fmu = fmus[build] / "piezo_p243_40.fmu"
    outs = ["current", "sat_slew", "sat_voltage"]
    coarse = run(fmu, outputs=outs, step_size=1e-3, n_steps=4, inputs={"v_cmd": 100.0})
    fine = run(fmu, outputs=outs, step_size=1e-5, n_steps=400, inputs={"v_cmd": 100.0},
               parameters={"hold_step": 1e-5})
    per_step = fine[:, 1:].reshape(4, 100, 2).max(axis=1)
    assert fine[99, 1] == 0.0 and abs(coarse[0, 0]) < 0.05   # inside the limit at the end
    np.testing.assert_array_equal(coarse[:, 1:], per_step)
    assert coarse[:, 1].tolist() == [1.0, 0.0, 0.0, 0.0]
    if build == "native":   # and the two builds agree
        py = run(fmus["py"] / "piezo_p243_40.fmu", outputs=outs, step_size=1e-3, n_steps=4,
                 inputs={"v_cmd": 100.0})
        assert_close(coarse, py)


@pytest.mark.parametrize("step", [4e-3, 1e-3, 3e-3, 8e-3])
def test_controller_equals_python_on_any_step(fmus, step):
    y = 1e-5 * np.sin(2 * np.pi * 8.4 * T)
    kw = dict(outputs=["u1"], step_size=step, n_steps=N // 2,
              inputs={"y1": y[:N // 2], "r1": np.sin(T[:N // 2])},
              parameters={"t_on": 0.5, "u_max": 150.0, "gain": 1.3})
    native, python = _pair(fmus, "controller_truss10_strain_diag", **kw)
    assert_close(native, python)
    assert np.max(np.abs(python)) > 1.0


def test_controller_enable_off_gives_the_additive_command_only(fmus):
    kw = dict(outputs=["u1"], step_size=4e-3, n_steps=200,
              inputs={"y1": 1e-4, "r1": 2.5}, parameters={"enable": False, "t_on": 0.0})
    native, python = _pair(fmus, "controller_truss10_strain_long", **kw)
    np.testing.assert_array_equal(native, python)
    np.testing.assert_array_equal(native, 2.5)


def test_excitation_equals_python(fmus):
    kw = dict(outputs=["v1", "v2"], step_size=4e-3, n_steps=400,
              parameters={"amp1": 10.0, "freq1": 8.4, "amp2": 10.0, "freq2": 9.5,
                          "t_start": 0.1, "t_stop": 1.2})
    native, python = _pair(fmus, "excitation", **kw)
    assert_close(native, python)
    assert native[-1, 0] == 0.0 and np.max(np.abs(native)) > 9.0


ACS_OUTPUTS = ["Tx", "Ty", "Tz", "wheel_speed_x", "wheel_speed_y", "wheel_speed_z"]


@pytest.mark.parametrize("step,params", [
    (0.05, {}),
    (0.1, {"momentum0_x": 70.0, "torque_limit": 0.01}),  # momentum and torque limits
    (0.03, {"anti_windup": False, "torque_limit": 0.005}),
    (0.25, {"bandwidth": 0.05, "inertia_y": 9000.0}),  # steps longer than the sample time
])
def test_acs_equals_python(fmus, step, params):
    t = np.arange(600) * 0.05
    inputs = {"roll": 1e-3 * np.sin(0.3 * t), "pitch": 2e-3 * np.cos(0.2 * t),
              "yaw": 1e-4 * RNG.standard_normal(600), "rate_x": 1e-4 * np.cos(0.3 * t),
              "rate_y": 0.0, "rate_z": 1e-5 * RNG.standard_normal(600)}
    native, python = _pair(fmus, "acs", outputs=ACS_OUTPUTS, step_size=step, n_steps=600,
                           inputs=inputs, parameters=params)
    assert_close(native, python)
    assert np.max(np.abs(python[:, :3])) > 0


WRENCH = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]


def _presets():
    from distfmu.presets import preset_names

    return [(name, 7) for name in preset_names()] + [("swir_cryocooler", 0), ("rwa", 0)]


@pytest.mark.parametrize("preset,seed", _presets())
def test_disturbance_equals_python_for_every_preset(fmus, preset, seed):
    """Every preset, with phases drawn from seed 7 (numpy's SeedSequence and PCG64,
    ported to C) and with the preset's own phases (seed 0); a window and a scale."""
    params = {"preset": preset, "seed": seed, "start_time": 0.5, "stop_time": 11.0,
              "scale": 1.5}
    native, python = _pair(fmus, "disturbance", outputs=WRENCH, step_size=8e-3,
                           n_steps=1500, parameters=params)
    assert_close(native, python)
    assert (np.max(np.abs(python)) > 0) == (preset != "none")
    assert np.all(python[-100:] == 0) and np.all(python[:61] == 0)  # t < 0.5 s, t >= 11 s


@pytest.mark.parametrize("preset", ["ceres_scan", "misr_calibration", "mopitt_scan", "tir_chopper",
                                    "swir_cryocooler", "rwa", "sad"])
def test_disturbance_frequency_scale_equals_python(fmus, preset):
    """A factor on the line and repetition frequencies (distfmu.presets.retimed), every
    kind of source that repeats (a sum, a repeated slew, a scan, a chopper, a harmonic, a
    wheel, a stepper), with drawn phases: C against the Python twin, and not ignored."""
    kw = dict(outputs=WRENCH, step_size=0.02, n_steps=4000)   # 80 s: repeats of 30 s slews
    params = {"preset": preset, "seed": 7, "frequency_scale": 1.07}
    native, python = _pair(fmus, "disturbance", parameters=params, **kw)
    assert_close(native, python)
    plain = run(fmus["native"] / "disturbance.fmu", parameters={**params, "frequency_scale": 1.0},
                **kw)
    assert np.max(np.abs(native - plain)) > 1e-3 * np.max(np.abs(plain))


@pytest.mark.parametrize("params,message", [
    ({"preset": "none", "frequency_scale": -1.0}, "positive finite number"),
    ({"preset": "swir_cryocooler", "frequency_scale": 0.0}, "positive finite number"),
    ({"preset": "rwa", "use_speed_input": True, "frequency_scale": 1.05}, "wheel_speed input"),
    ({"preset": "mopitt_scan", "frequency_scale": 100.0}, "turnaround must be shorter"),
    ({"preset": "misr_calibration", "frequency_scale": 100.0}, "repeat must be at least"),
])
def test_disturbance_frequency_scale_it_cannot_apply_fails_like_python(fmus, params, message):
    """The native FMU refuses what the Python slave refuses, with the same sentence."""
    assert any(message in line for line in _initialisation_messages(
        fmus["native"] / "disturbance.fmu", params)), message


_CALLBACKS: list = []   # FMI callback structs stay alive: fmpy's logger proxy keeps them


def _initialisation_messages(fmu, parameters) -> list:
    """The FMU's log messages of an initialisation that must fail (through the
    process's one logger callback, as the master logs)."""
    import ctypes
    import fmpy.fmi2 as f2
    from fmpy import extract, read_model_description
    from fmpy.fmi1 import FMICallException
    from fmpy.logging import addLoggerProxy

    from orchestrator.cosim import instance as ci

    md = read_model_description(str(fmu))
    var = {v.name: v for v in md.modelVariables}
    slave = f2.FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu)),
                         modelIdentifier=md.coSimulation.modelIdentifier, instanceName="t")
    key, messages = next(ci._LOG_KEYS), []
    ci._LOG_SINKS[key] = messages
    cb = f2.fmi2CallbackFunctions()
    cb.logger = ci._shared_logger(f2.fmi2CallbackLoggerTYPE)
    cb.allocateMemory, cb.freeMemory = (f2.defaultCallbacks.allocateMemory,
                                        f2.defaultCallbacks.freeMemory)
    cb.componentEnvironment = ctypes.c_void_p(key)
    addLoggerProxy(ctypes.byref(cb))
    _CALLBACKS.append(cb)
    slave.instantiate(callbacks=cb, loggingOn=True)
    try:
        slave.setupExperiment(startTime=0.0)
        for name, value in parameters.items():
            setter = {"Real": slave.setReal, "Boolean": slave.setBoolean,
                      "String": slave.setString}[var[name].type]
            setter([var[name].valueReference], [value])
        slave.enterInitializationMode()
        with pytest.raises(FMICallException):
            slave.exitInitializationMode()
    finally:
        slave.freeInstance()
    return [text for _, text in messages]


def test_disturbance_seed_changes_the_phases_the_same_way(fmus):
    kw = dict(outputs=WRENCH, step_size=1e-3, n_steps=300)
    a = run(fmus["native"] / "disturbance.fmu", parameters={"preset": "tir_cryocooler",
                                                             "seed": 1}, **kw)
    b = run(fmus["native"] / "disturbance.fmu", parameters={"preset": "tir_cryocooler",
                                                             "seed": 2}, **kw)
    assert np.max(np.abs(a - b)) > 0.01


def test_disturbance_wheel_driven_by_the_speed_input(fmus):
    speed = 100 + 50 * np.sin(np.arange(1000) * 1e-3)
    native, python = _pair(fmus, "disturbance", outputs=WRENCH, step_size=1e-3,
                           n_steps=1000, inputs={"wheel_speed": speed},
                           parameters={"preset": "rwa", "use_speed_input": True, "seed": 3})
    assert_close(native, python)
    assert np.max(np.abs(python)) > 0


@pytest.mark.parametrize("model,params", [
    ("disturbance", {"preset": "no_such_event"}),
    ("acs", {"sample_time": 0.1, "bandwidth": 5.0}),  # w_c T > 0.5
    ("piezo_p243_30", {"amp_order": 3}),
    ("controller_truss10_strain_diag", {"u_min": 10.0, "u_max": -10.0}),
])
def test_invalid_parameters_fail_initialisation(fmus, model, params):
    """The Python slaves raise on the same values (their own tests); here the native
    FMU must refuse them too, not run with them."""
    from fmpy.fmi1 import FMICallException

    with pytest.raises(FMICallException):
        run(fmus["native"] / f"{model}.fmu", outputs=[], step_size=1e-3, n_steps=1,
            parameters=params)


@pytest.mark.filterwarnings("ignore:.*not connected and keep their start values")
@pytest.mark.parametrize("scenario,stop,overrides", [
    ("truss10_closed_loop.toml", 5.0, []),
    ("truss10_campaign.toml", 3.0, ["excitation.amp1=10.0", "ctrl_diag.gain=0.5"]),
])
def test_ten_bay_scenarios_give_the_same_table(fmus, tmp_path, scenario, stop, overrides):
    """The shipped ten-bay scenarios, run with each flavour: same table."""
    from orchestrator import run_scenario

    tables = {}
    for flavour in ("py", "native"):
        table, meta = run_scenario(REPO / "scenarios" / scenario, tmp_path / flavour,
                                   fmu_dir=fmus[flavour], stop_time=stop, overrides=overrides)
        assert meta["status"] == "ok"
        tables[flavour] = table
    py, nat = tables["py"], tables["native"]
    assert list(py.keys()) == list(nat.keys())
    np.testing.assert_array_equal(np.asarray(nat["time"]), np.asarray(py["time"]))
    for name in py.keys():
        a, b = np.asarray(py[name], float), np.asarray(nat[name], float)
        peak = max(np.max(np.abs(a)), 1e-300)
        assert np.max(np.abs(a - b)) <= RTOL * peak, name
    pitch = np.asarray(py["structure.los_tip_pitch"], float)
    assert np.max(np.abs(pitch)) > 0  # something moved: the comparison is not of zeros


@pytest.mark.long   # make test-full: the EOS budget co-simulated on both builds, 8 s
@pytest.mark.filterwarnings("ignore:.*not connected and keep their start values")
def test_eos_budget_scenario_gives_the_same_table(fmus, tmp_path):
    """scenarios/eos_budget.toml (21 instances: EOS testbed structure with accelerometer
    low-pass and 59 Ritz vectors, nine disturbances, ACS, five isolation loops) with
    four events and isolation on: same table both ways."""
    from orchestrator import run_scenario

    overrides = ["dist_swir.preset=swir_cryocooler", "dist_rwa.preset=rwa",
                 "dist_vnir.preset=vnir_pointing", "dist_ceres.preset=ceres_scan",
                 "dist_tir.seed=4", "dist_tir.preset=tir_cryocooler",
                 "ctrl_iso1.gain=0.27", "ctrl_iso2.gain=0.27", "ctrl_iso3.gain=0.27",
                 "ctrl_swir.gain=0.1", "ctrl_vnir.gain=0.1"]
    tables = {}
    for flavour in ("py", "native"):
        table, meta = run_scenario(REPO / "scenarios" / "eos_budget.toml", tmp_path / flavour,
                                   fmu_dir=fmus[flavour], stop_time=0.3, overrides=overrides)
        assert meta["status"] == "ok"
        tables[flavour] = table
    py, nat = tables["py"], tables["native"]
    assert list(py.keys()) == list(nat.keys()) and len(py.keys()) > 30
    for name in py.keys():
        a, b = np.asarray(py[name], float), np.asarray(nat[name], float)
        assert np.max(np.abs(a - b)) <= RTOL * max(np.max(np.abs(a)), 1e-300), name
    assert np.max(np.abs(np.asarray(py["structure.los_swir_pitch"], float))) > 0


# ---------------------------------------------------------------------- FMU state

@pytest.mark.parametrize("model,inputs", [
    ("truss10_structure", {"fc_diag": 100 * np.sin(2 * np.pi * 8.4 * T[:300])}),
    ("piezo_p243_40", {"v_cmd": 800 * np.sin(2 * np.pi * 20 * T[:300])}),
    ("controller_truss10_strain_diag", {"y1": 1e-5 * np.sin(2 * np.pi * 8.4 * T[:300])}),
])
def test_state_round_trip_through_serialised_bytes(fmus, model, inputs):
    outputs = {"truss10_structure": ["strain_diag", "acc_tip_x"],
               "piezo_p243_40": ["voltage", "strain"],
               "controller_truss10_strain_diag": ["u1"]}[model]
    params = {"noise_std": 1e-7, "hysteresis": True} if model.startswith("piezo") else {}
    y, again = run(fmus["native"] / f"{model}.fmu", outputs=outputs, step_size=1e-3,
                   n_steps=300, inputs=inputs, parameters=params, state_at=120)
    np.testing.assert_array_equal(again[120:], y[120:])
    assert np.max(np.abs(y[120:])) > 0


def _load(fmu, tmp_path):
    """The native library of ``fmu`` via ctypes, with a live instance."""
    unzip = tmp_path / fmu.stem
    with zipfile.ZipFile(fmu) as z:
        z.extractall(unzip)
    return unzip


def test_corrupted_or_foreign_state_is_rejected(fmus, tmp_path):
    from fmpy import extract, read_model_description
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Slave

    fmu = fmus["native"] / "piezo_p243_30.fmu"
    md = read_model_description(str(fmu))
    unzip = extract(str(fmu))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="s")
    try:
        slave.instantiate(loggingOn=True)
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
        state = slave.getFMUstate()
        blob = bytes(slave.serializeFMUstate(state))
        slave.freeFMUstate(state)
        assert blob[:8] == b"JFMUSTAT"
        flipped = bytearray(blob)
        flipped[200] ^= 0x01  # one bit of a value: the checksum catches it
        other_version = bytearray(blob)
        other_version[8] = blob[8] + 1   # a layout version this build does not read
        for bad in (bytes(flipped), bytes(other_version), blob[:-1], b"x" * len(blob)):
            with pytest.raises(FMICallException):
                slave.deSerializeFMUstate(bad)
        state = slave.deSerializeFMUstate(blob)  # the intact one still works
        slave.setFMUstate(state)
        slave.freeFMUstate(state)
    finally:
        slave.terminate()
        slave.freeInstance()
        shutil.rmtree(unzip, ignore_errors=True)


# ---------------------------------------------------------------------- no Python anywhere

def test_sources_compile_alone_with_strict_flags_and_match_the_binary(fmus, tmp_path):
    """Unzip into an empty folder, compile sources/ alone, run it in place of the shipped
    binary: identical outputs."""
    fmu = fmus["native"] / "truss10_structure.fmu"
    with zipfile.ZipFile(fmu) as z:
        z.extractall(tmp_path / "unzip")
    src = tmp_path / "unzip" / "sources"
    assert "-pedantic" in CFLAGS and "-Werror" in CFLAGS
    lib = compile_sources(src, tmp_path / "truss10_structure.so")
    rebuilt = tmp_path / "rebuilt" / fmu.name
    rebuilt.parent.mkdir()
    with zipfile.ZipFile(fmu) as zin, zipfile.ZipFile(rebuilt, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "binaries/linux64/truss10_structure.so":
                data = lib.read_bytes()
            zout.writestr(item.filename, data)
    kw = dict(outputs=["strain_diag", "acc_tip_y"], step_size=1e-3, n_steps=300,
              inputs={"fc_long": RNG.standard_normal(300)})
    np.testing.assert_array_equal(run(rebuilt, **kw), run(fmu, **kw))


def test_binaries_hold_no_build_path_and_no_libpython(fmus):
    needles = [str(REPO).encode(), b"/tmp/", b"libpython", b"Py_", b".venv"]
    for model in MODELS:
        with zipfile.ZipFile(fmus["native"] / f"{model}.fmu") as z:
            for name in z.namelist():
                if name.startswith("binaries/"):
                    data = z.read(name)
                    for needle in needles:
                        assert needle not in data, (name, needle)


def test_runs_in_a_plain_c_host_under_a_clean_environment(fmus, tmp_path):
    """The C host of tests/support (no libpython) with only PATH and LANG set, on a copy
    of the FMU in a fresh folder: the same outputs as fmpy."""
    from tests.support.hosts import compile_c_host, run_c_host

    host = compile_c_host(tmp_path / "host")
    copy = tmp_path / "copy" / "piezo_p243_40.fmu"
    copy.parent.mkdir()
    shutil.copy2(fmus["native"] / "piezo_p243_40.fmu", copy)
    kw = dict(outputs=["force", "voltage", "strain"], step_size=1e-3, n_steps=400,
              inputs={"v_cmd": 700 * np.sin(2 * np.pi * 25 * T[:400]),
                      "elongation": 1e-6 * np.cos(T[:400])})
    in_c = run_c_host(copy, host=host, wrapper=["env", "-i"], **kw)  # empty environment
    np.testing.assert_array_equal(in_c, run(copy, **kw))
    lib = tmp_path / "model.so"
    with zipfile.ZipFile(copy) as z:
        lib.write_bytes(z.read("binaries/linux64/piezo_p243_40.so"))
    needed = subprocess.run(["objdump", "-p", str(lib)], capture_output=True, text=True).stdout
    libs = {line.split()[1] for line in needed.splitlines() if line.strip().startswith("NEEDED")}
    assert libs <= {"libc.so.6", "libm.so.6"}, libs


def test_windows_dll_is_built_when_mingw_is_installed(fmus, tmp_path):
    if mingw_compiler() is None:
        pytest.skip("x86_64-w64-mingw32-gcc is not installed (Debian: gcc-mingw-w64-x86-64, "
                    "`make native-deps`); the win64 binaries cannot be built here")
    from fmutools.registry import collect_specs

    from nativefmu import build_native

    spec = collect_specs(["controller_truss10_strain_diag"])[0]
    fmu = build_native(spec, tmp_path, windows=True,
                       python_fmu=fmus["py"] / "controller_truss10_strain_diag.fmu")
    with zipfile.ZipFile(fmu) as z:
        dll = z.read("binaries/win64/controller_truss10_strain_diag.dll")
        assert z.read("modelDescription.xml") == zipfile.ZipFile(
            fmus["native"] / fmu.name).read("modelDescription.xml")
    assert dll[:2] == b"MZ" and b"fmi2DoStep" in dll and b"fmi2SerializeFMUstate" in dll
    for needle in (str(REPO).encode(), str(tmp_path).encode(), b"python"):
        assert needle not in dll


def test_library_exports_every_fmi2_function(fmus, tmp_path):
    unzip = _load(fmus["native"] / "excitation.fmu", tmp_path)
    lib = ctypes.CDLL(str(unzip / "binaries/linux64/excitation.so"))
    for name in ("fmi2Instantiate", "fmi2DoStep", "fmi2GetFMUstate", "fmi2SetFMUstate",
                 "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate",
                 "fmi2DeSerializeFMUstate", "fmi2GetTypesPlatform", "fmi2GetVersion",
                 "fmi2GetRealStatus", "fmi2Reset"):
        assert hasattr(lib, name), name
    lib.fmi2GetVersion.restype = ctypes.c_char_p
    assert lib.fmi2GetVersion() == b"2.0"


# ---------------------------------------------------------------------- command line

@pytest.mark.long   # make test-full: builds every native FMU from the command line, 7 s
def test_jitterfmu_build_native_writes_native_fmus(tmp_path, capsys):
    from orchestrator.cli import main

    status = main(["build", "--native", "--out", str(tmp_path), "--model", "excitation",
                   "--model", "acs"])
    assert status == 0
    for name in ("excitation", "acs"):
        root = _md(tmp_path / f"{name}.fmu")
        assert root.find("CoSimulation/SourceFiles") is not None
    assert "(native) ok" in capsys.readouterr().out


@pytest.mark.long   # make test-full: reduces and builds a structure, 5 s
def test_jitterfmu_build_native_structure_from_a_reduced_model(tmp_path):
    from orchestrator.cli import main
    from structfmu.models import get_model

    npz = get_model("truss10").reduced().save(tmp_path / "mytruss.npz")
    assert main(["build", "--native", "--structure", str(npz), "--out",
                 str(tmp_path / "out")]) == 0
    root = _md(tmp_path / "out" / "mytruss_structure.fmu")
    assert root.find("CoSimulation").get("modelIdentifier") == "mytruss_structure"
    kw = dict(outputs=["strain_diag"], step_size=1e-3, n_steps=50, inputs={"fc_diag": 10.0})
    assert np.max(np.abs(run(tmp_path / "out" / "mytruss_structure.fmu", **kw))) > 0


def test_feedthrough_outputs_follow_inputs_in_initialisation_mode(fmus):
    """acc_tip_x of the ten-bay structure feeds fc_diag through: setting the input in
    initialisation mode updates it at once, in both flavours alike."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    got = {}
    for flavour in ("py", "native"):
        fmu = fmus[flavour] / "truss10_structure.fmu"
        md = read_model_description(str(fmu))
        var = {v.name: v.valueReference for v in md.modelVariables}
        unzip = extract(str(fmu))
        slave = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                          modelIdentifier=md.coSimulation.modelIdentifier, instanceName="i")
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.setReal([var["fc_diag"]], [5.0])
        in_init = slave.getReal([var["acc_tip_x"]])[0]
        slave.exitInitializationMode()
        slave.setReal([var["fc_diag"]], [-3.0])
        after = slave.getReal([var["acc_tip_x"]])[0]
        slave.terminate()
        slave.freeInstance()
        shutil.rmtree(unzip, ignore_errors=True)
        got[flavour] = (in_init, after)
    assert got["native"] == pytest.approx(got["py"], rel=1e-13, abs=0)
    assert got["py"][0] != 0 and got["py"][1] == pytest.approx(-0.6 * got["py"][0])


def test_runs_in_libcosim_like_in_fmpy(fmus):
    from tests.support.hosts import run_libcosim

    kw = dict(outputs=["u1"], step_size=4e-3, n_steps=300,
              inputs={"y1": 1e-5 * np.sin(2 * np.pi * 8.4 * T[:300] * 4)},
              parameters={"t_on": 0.1})
    fmu = fmus["native"] / "controller_truss10_strain_diag.fmu"
    in_libcosim = run_libcosim(fmu, **kw)
    np.testing.assert_array_equal(in_libcosim, run(fmu, **kw))
    assert np.max(np.abs(in_libcosim)) > 0


HARNESS = r"""
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "jfmu.h"
void jf_log(JfInstance *inst, int status, const char *fmt, ...) {
    va_list ap; (void)inst; (void)status;
    va_start(ap, fmt); vfprintf(stderr, fmt, ap); va_end(ap); fputc('\n', stderr);
}
void *jf_alloc(JfInstance *inst, size_t n, size_t size) {
    (void)inst; return calloc(n ? n : 1, size ? size : 1);
}
int main(int argc, char **argv) {
    JfInstance inst;
    JfData *d;
    double *v;
    int i, n = argc > 2 ? atoi(argv[2]) : 0;
    memset(&inst, 0, sizeof inst);
    inst.resource_dir = argv[1];
    d = jf_data_open(&inst, "t.dat");
    if (d == NULL || (v = jf_data_array(d, "x", 1, (size_t)n)) == NULL) return 1;
    for (i = 0; i < n; i++) printf("%a\n", v[i]);
    free(v);
    jf_data_close(d);
    return 0;
}
"""


@pytest.fixture(scope="module")
def data_harness(tmp_path_factory):
    """The C harness above, built against csrc/data.c: ``run(folder, n) -> process``."""
    from importlib import resources

    csrc = resources.files("nativefmu") / "csrc"
    tmp = tmp_path_factory.mktemp("data_harness")
    (tmp / "h.c").write_text(HARNESS)
    exe = tmp / "h"
    subprocess.run(["gcc", *CFLAGS, "-I", str(csrc), "-o", str(exe), str(tmp / "h.c"),
                    str(csrc / "data.c"), "-lm"], check=True)
    return lambda folder, n: subprocess.run([str(exe), str(folder) + "/", str(n)],
                                            capture_output=True, text=True)


DATA_VALUES = [0.0, -0.0, 5e-324, -2.2250738585072014e-308, 1.7976931348623157e308, 1 / 3,
               np.pi, -1e-300, 123456789.0]


def test_model_data_round_trips_every_double_exactly(tmp_path, data_harness):
    """Binary doubles through nativefmu.data.encode and csrc/data.c (assembled from their
    bytes, no parser, no locale): subnormals, signed zero, extremes, random doubles, in C
    and back through nativefmu.data.decode."""
    from nativefmu.data import decode, encode

    rng = np.random.default_rng(5)
    values = [*DATA_VALUES, *rng.standard_normal(20) * 10.0 ** rng.integers(-300, 300, 20)]
    content = encode({"n": 3, "x": values})
    (tmp_path / "t.dat").write_bytes(content)
    out = data_harness(tmp_path, len(values))
    assert out.returncode == 0, out.stderr
    back = np.array([float.fromhex(s) for s in out.stdout.split()])
    np.testing.assert_array_equal(back.view(np.uint64), np.array(values).view(np.uint64))
    arrays = decode(content)
    assert list(arrays) == ["n", "x"] and arrays["n"].shape == (1, 1)
    np.testing.assert_array_equal(arrays["x"].ravel().view(np.uint64),
                                  np.array(values).view(np.uint64))


@pytest.mark.parametrize("damage, words", [
    (lambda c: c[:-3], "is cut short at array 1"),
    (lambda c: c.replace(b"data 2", b"data 1"), "is not a jitterfmu native data file of "
                                                "version 2"),
    (lambda c: c[:-8] + np.array([np.nan]).astype("<f8").tobytes(), "is non-finite at "
                                                                     "array 1"),
    (lambda c: c.replace(b"x 1 9", b"x 1 9x"), "is malformed at array 1"),
    (lambda c: c + b"y 1 1\n", "is cut short at array 2"),
])
def test_damaged_model_data_is_refused_in_one_sentence(tmp_path, data_harness, damage,
                                                       words):
    """A cut, foreign, non-finite or malformed data file: the C reader refuses it, saying
    what and where (never values read past its end); Python's decode refuses it too."""
    from nativefmu.data import decode, encode

    content = damage(encode({"x": DATA_VALUES}))
    (tmp_path / "t.dat").write_bytes(content)
    out = data_harness(tmp_path, len(DATA_VALUES))
    assert out.returncode == 1 and f"t.dat {words}" in out.stderr, out.stderr
    if "non-finite" not in words:
        with pytest.raises(ValueError):
            decode(content)
