"""The piezo FMUs built, validated and run in fmpy, a plain C host and libcosim."""

import math
import shutil
import subprocess
import sys

import numpy as np
import pytest

from piezofmu import actuator as ac
from piezofmu.fmuspec import MODELS, specs

pytestmark = pytest.mark.slow

DT = 1e-3
N = 120
OUTPUTS = ["force", "voltage", "current", "free_stroke", "strain", "sat_voltage", "sat_slew",
           "sat_stroke"]


@pytest.fixture(scope="module")
def fmus(suite_fmus):
    return suite_fmus(*[s.model_identifier for s in specs(None)], kind="python")


def commands(model):
    """Command and elongation sequences that drive rails and slew limit of the preset."""
    k = np.arange(N)
    amp = 70.0 if model == "piezo_p845_37" else 1700.0
    cmd = amp * np.sign(np.sin(2 * np.pi * k / 40)) * (k > 3) + 0.3 * amp * np.sin(k / 7.0)
    elong = 2e-6 * np.sin(2 * np.pi * k / 30)
    return cmd, elong


@pytest.mark.parametrize("model", list(MODELS))
def test_fmu_validates_without_messages(fmus, model):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fmus[model])) == []
    from fmutools.validate import validate_fmu as project_validate

    assert project_validate(fmus[model]) == []


def test_cli_validate_reports_nothing(fmus):
    from pathlib import Path

    exe = Path(sys.executable).with_name("jitterfmu")
    proc = subprocess.run([str(exe), "validate", *map(str, fmus.values())],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_model_structure_is_exact(fmus):
    from fmpy import read_model_description

    md = read_model_description(str(fmus["piezo_p243_30"]))
    deps = {u.variable.name: sorted(d.name for d in u.dependencies)
            for u in md.outputs}
    # the force depends on the elongation through the stack's servo loop
    assert deps == {"force": ["elongation", "v_cmd"], "voltage": [], "current": [], "free_stroke": [],
                    "strain": ["elongation"], "sat_voltage": [], "sat_slew": [],
                    "sat_stroke": []}
    assert md.coSimulation.canGetAndSetFMUstate
    units = {v.name: v.unit for v in md.modelVariables}
    assert (units["force"], units["voltage"], units["current"], units["strain"]) == \
        ("N", "V", "A", "1")


@pytest.mark.parametrize("model", list(MODELS))
def test_fmpy_run_equals_the_pure_model(fmus, model):
    from tests.support import hosts
    cmd, elong = commands(model)
    params = {"noise_std": 1e-7}
    y = hosts.run_fmpy(fmus[model], inputs={"v_cmd": cmd, "elongation": elong},
                       outputs=OUTPUTS, step_size=DT, n_steps=N, parameters=params)
    act = ac.actuator_preset(MODELS[model]).replace(
        gauge=ac.actuator_preset(MODELS[model]).gauge.replace(noise_std=1e-7))
    state = ac.initial_state(act)
    want = []
    for u, e in zip(cmd, elong):
        state, out = ac.step(act, state, u, DT)
        # the force held over the next step: its mean with the command still u
        want.append([ac.step_mean(act, state, u, DT)[2], out.voltage, out.current, out.free_stroke,
                     ac.strain(act, state, e), out.sat_voltage, out.sat_slew, out.sat_stroke])
    np.testing.assert_array_equal(y, np.array(want, dtype=float))
    assert y[:, 5].max() == 1.0 and y[:, 6].max() == 1.0  # rails and slew limit reached


@pytest.mark.parametrize("model", ["piezo_p243_40", "piezo_p845_37"])
def test_c_host_and_libcosim_match_fmpy(fmus, model, tmp_path):
    from tests.support import hosts
    cmd, elong = commands(model)
    kw = dict(inputs={"v_cmd": cmd, "elongation": elong}, outputs=OUTPUTS, step_size=DT,
              n_steps=N, parameters={"noise_std": 1e-7, "stroke_limit": 15e-6})
    ref = hosts.run_fmpy(fmus[model], **kw)
    c_host = hosts.run_c_host(fmus[model], **kw,
                              host=hosts.compile_c_host(tmp_path / "host"))
    cosim = hosts.run_libcosim(fmus[model], **kw)
    scale = np.maximum(np.abs(ref).max(axis=0), 1e-300)
    np.testing.assert_allclose(c_host / scale, ref / scale, rtol=0, atol=1e-12)
    np.testing.assert_allclose(cosim / scale, ref / scale, rtol=0, atol=1e-12)
    assert np.ptp(ref[:, 0]) > 0


def test_fmpy_hysteresis_and_fmu_state_round_trip(fmus):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    path = str(fmus["piezo_p845_37"])
    md = read_model_description(path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzip = extract(path)
    try:
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                        modelIdentifier=md.coSimulation.modelIdentifier, instanceName="p")
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.setBoolean([vr["hysteresis"]], [True])
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        out_vrs = [vr[n] for n in OUTPUTS]

        def run(k0, k1):
            rows = []
            for k in range(k0, k1):
                fmu.setReal([vr["v_cmd"], vr["elongation"]],
                            [40.0 * math.sin(2 * math.pi * k / 50), 1e-6])
                fmu.doStep(k * DT, DT)
                rows.append(fmu.getReal(out_vrs))
            return np.array(rows)

        run(0, 60)
        state = fmu.getFMUstate()
        blob = fmu.serializeFMUstate(state)
        first = run(60, 160)
        fmu.setFMUstate(fmu.deSerializeFMUstate(blob))
        again = run(60, 160)
        fmu.freeFMUstate(state)
        fmu.terminate()
        fmu.freeInstance()
    finally:
        shutil.rmtree(unzip, ignore_errors=True)
    np.testing.assert_array_equal(first, again)
    # Same as the pure model with hysteresis on, and force is not c h times the voltage.
    act = ac.actuator_preset("P-845.37", hysteresis=True)
    state = ac.initial_state(act)
    for k in range(160):
        u = 40.0 * math.sin(2 * math.pi * k / 50)
        state, out = ac.step(act, state, u, DT)
        if k >= 60:
            assert first[k - 60].tolist() == [
                ac.step_mean(act, state, u, DT)[2], out.voltage, out.current, out.free_stroke, ac.strain(act, state, 1e-6),
                out.sat_voltage, out.sat_slew, out.sat_stroke]
    ch = act.stack.ch
    assert np.max(np.abs(first[:, 0] - ch * first[:, 1])) > 0.05 * np.max(np.abs(first[:, 0]))
