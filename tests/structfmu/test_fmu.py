"""The structure FMU: valid, exact, and the same in fmpy, a C host and libcosim."""

import numpy as np
import pytest

from structfmu.discrete import simulate

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def structure_fmu(suite_fmus, truss10_reduced):
    model, _ = truss10_reduced
    return suite_fmus("truss10_structure", kind="python")["truss10_structure"], model


def _inputs(n):
    t = np.arange(n) * 1e-3
    return {"fc_diag": 50 * np.sin(2 * np.pi * 8.4 * t), "f_tip_x": np.where(t > 0.02, 3.0, 0.0)}


OUTS = ["strain_diag", "elong_long", "acc_tip_x", "los_tip_pitch"]


def test_fmu_validates_with_no_message(structure_fmu):
    from fmpy.validation import validate_fmu
    from fmutools.validate import validate_fmu as ours
    fmu, _ = structure_fmu
    assert validate_fmu(str(fmu)) == []
    assert ours(fmu) == []


def test_dependencies_exact(structure_fmu):
    from fmpy import read_model_description
    fmu, model = structure_fmu
    md = read_model_description(str(fmu))
    deps = {u.variable.name: sorted(d.name for d in u.dependencies) for u in md.outputs}
    assert deps["strain_diag"] == [] and deps["los_tip_pitch"] == []
    assert deps["elong_long"] == []
    assert set(deps["acc_tip_x"]) == {"fc_long", "fc_diag", "f_tip_x", "f_tip_y"} or \
        set(deps["acc_tip_x"]) <= set(model.input_names) and deps["acc_tip_x"]


def test_fmpy_matches_the_numerics_and_other_hosts(structure_fmu):
    from tests.support.hosts import run_c_host, run_fmpy, run_libcosim
    fmu, model = structure_fmu
    n = 200
    kw = dict(inputs=_inputs(n), outputs=OUTS, step_size=1e-3, n_steps=n)
    y_fmpy = run_fmpy(fmu, **kw)
    # reference: the pure numerics, outputs after each step with the held input
    u = np.zeros((n, model.n_inputs))
    for name, col in _inputs(n).items():
        u[:, model.input_index(name)] = col
    _, x = simulate(model, 1e-3, u)
    from structfmu.discrete import output
    ref = np.array([output(model, x[k + 1], u[k]) for k in range(n)])
    ref = ref[:, [model.output_index(o) for o in OUTS]]
    np.testing.assert_allclose(y_fmpy / np.abs(ref).max(0), ref / np.abs(ref).max(0), rtol=0, atol=1e-12)
    y_c = run_c_host(fmu, **kw)
    y_cosim = run_libcosim(fmu, **kw)
    # hosts agree to 1e-12 of each signal's peak (relative error at zero crossings is
    # meaningless)
    scale = np.abs(y_fmpy).max(0)
    np.testing.assert_allclose(y_c / scale, y_fmpy / scale, rtol=0, atol=1e-12)
    np.testing.assert_allclose(y_cosim / scale, y_fmpy / scale, rtol=0, atol=1e-12)


def test_state_round_trip_is_bit_exact(structure_fmu):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    fmu, _ = structure_fmu
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    d = extract(str(fmu))
    s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="s")
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    s.setReal([vr["fc_diag"]], [40.0])
    for k in range(50):
        s.doStep(k * 1e-3, 1e-3)
    state = s.getFMUstate()
    outs = [vr[o] for o in OUTS]
    first = []
    for k in range(50, 80):
        s.doStep(k * 1e-3, 1e-3)
        first.append(s.getReal(outs))
    s.setFMUstate(state)
    second = []
    for k in range(50, 80):
        s.doStep(k * 1e-3, 1e-3)
        second.append(s.getReal(outs))
    s.freeFMUstate(state)
    s.terminate()
    s.freeInstance()
    assert np.array_equal(np.array(first), np.array(second))
    assert np.abs(np.array(first)).max() > 0


def test_analytic_step_force_response_through_the_fmu(tmp_path):
    # single undamped mode: q = F/w^2 (1 - cos w t), exact at the communication points
    from fmutools.build import build_fmu
    from tests.support.hosts import run_fmpy
    from structfmu.fmuspec import spec_from_model
    from structfmu.reduced import ReducedModel
    w, F = 2 * np.pi * 5.0, 2.0
    m = ReducedModel(omega=[w], modal_damping=[0.0], B_e=[[1.0]], C_e=[[1.0], [1.0]],
                     K_oo=np.zeros((0, 0)), D_oo=np.zeros((0, 0)), B_o=np.zeros((0, 1)),
                     C_o=np.zeros((2, 0)), input_names=("f",), output_names=("q", "a"),
                     output_kinds=("disp", "accel"), name="sdof")
    fmu = build_fmu(spec_from_model(m, "sdof_structure"), tmp_path)
    y = run_fmpy(fmu, inputs={"f": F}, outputs=["q", "a"], step_size=2.5e-3, n_steps=400)
    t = np.arange(1, 401) * 2.5e-3
    np.testing.assert_allclose(y[:, 0], F / w**2 * (1 - np.cos(w * t)), atol=1e-12)
    np.testing.assert_allclose(y[:, 1], F * np.cos(w * t), atol=1e-9)


def test_torque_inputs_are_declared_in_newton_metres(tmp_path):
    from fmpy import read_model_description

    from fmutools.build import build_fmu
    from structfmu.fmuspec import spec_from_model
    from structfmu.models import eos_testbed
    fmu = build_fmu(spec_from_model(eos_testbed.reduced(), "eos_units_structure"), tmp_path)
    units = {v.name: v.unit for v in read_model_description(str(fmu)).modelVariables}
    assert units["swir_mx"] == "N.m" and units["acs_tz"] == "N.m"
    assert units["swir_fx"] == "N" and units["fc_iso1"] == "N"
