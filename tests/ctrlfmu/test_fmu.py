"""Controller FMUs built, validated and run in fmpy, a plain C host and libcosim."""

import shutil

import numpy as np
import pytest

from ctrlfmu.designs import design
from ctrlfmu.fmuspec import MODELS, law_spec, specs
from ctrlfmu.law import DiscreteLaw, simulate
from fmutools.build import build_fmu

pytestmark = pytest.mark.slow

N = 120


@pytest.fixture(scope="module")
def fmus(tmp_path_factory, suite_fmus):
    built = dict(suite_fmus(*[s.model_identifier for s in specs(None)], kind="python"))
    built["direct"] = build_fmu(law_spec(direct_law(), "controller_direct_test"),
                                tmp_path_factory.mktemp("ctrl_fmus"))
    return built


def direct_law():
    """Non-delayed MIMO law: u1 <- y1 feedthrough, u2 <- y2 feedthrough, no y2 -> u1."""
    return DiscreteLaw([[0.5, 0.1], [0.0, 0.7]], [[1.0, 0.0], [0.3, 1.0]],
                       [[1.0, 0.0], [0.2, 0.4]], [[0.8, 0.0], [0.0, -0.25]], 0.002,
                       delayed=False, name="direct_test", u_min=-3.0, u_max=3.0)


def measurements(law, n=N):
    rng = np.random.default_rng(11)
    scale = 1e-6 if law.input_units[0] == "1" else 0.2
    return rng.standard_normal((n, law.n_inputs)) * scale


def test_specs_cover_the_named_designs():
    assert sorted(MODELS) == ["controller_eos_isolation", "controller_testbed_isolation",
                              "controller_truss10_strain_diag", "controller_truss10_strain_long"]
    (spec,) = specs(["controller_testbed_isolation"])
    assert spec.step_size == 1e-3 and "law.npz" in spec.resources
    # The registry asks every package with the full list: foreign names are ignored.
    assert [s.model_identifier for s in specs(["piezo_p243_30", "controller_eos_isolation"])] \
        == ["controller_eos_isolation"]
    from fmutools.registry import collect_specs

    assert [s.model_identifier for s in collect_specs(["controller_eos_isolation"])] == \
        ["controller_eos_isolation"]


@pytest.mark.parametrize("model", [*MODELS, "direct"])
def test_fmu_validates_without_messages(fmus, model):
    from fmpy.validation import validate_fmu

    from fmutools.validate import validate_fmu as project_validate

    assert validate_fmu(str(fmus[model])) == []
    assert project_validate(fmus[model]) == []


def test_model_structure_is_exact(fmus):
    from fmpy import read_model_description

    def deps(path):
        md = read_model_description(str(path))
        return ({u.variable.name: sorted(d.name for d in u.dependencies) for u in md.outputs},
                {v.name: v.unit for v in md.modelVariables}, md)

    d, units, md = deps(fmus["controller_testbed_isolation"])
    # Eq. (11): no feedthrough from the measurements; only the additive command r1
    assert d == {"u1": ["r1"]}
    assert (units["y1"], units["y2"], units["u1"], units["t_on"]) == ("m/s2", "m/s2", "V", "s")
    assert md.coSimulation.canGetAndSetFMUstate
    assert md.defaultExperiment.stepSize == "0.001"
    d, units, _ = deps(fmus["controller_truss10_strain_diag"])
    assert d == {"u1": ["r1"]} and units["y1"] == "1"
    d, _, _ = deps(fmus["direct"])
    assert d == {"u1": ["enable", "r1", "y1"], "u2": ["enable", "r2", "y2"]}


def test_additive_command_is_added_after_the_law(fmus):
    from tests.support.hosts import run_fmpy

    law = design(MODELS["controller_truss10_strain_diag"])
    y = measurements(law)
    r = 100.0 * np.sin(2 * np.pi * 8.4 * np.arange(N) * law.dt)
    base = run_fmpy(fmus["controller_truss10_strain_diag"], inputs={"y1": y[:, 0]},
                    outputs=["u1"], step_size=law.dt, n_steps=N)
    with_r = run_fmpy(fmus["controller_truss10_strain_diag"],
                      inputs={"y1": y[:, 0], "r1": r}, outputs=["u1"], step_size=law.dt,
                      n_steps=N)
    # the runner reads u after the step while r[k] is still set: u = law + r[k]
    np.testing.assert_allclose(with_r[:, 0] - base[:, 0], r, rtol=0, atol=1e-9)


@pytest.mark.parametrize("model", list(MODELS))
def test_fmpy_run_equals_the_pure_law(fmus, model):
    from tests.support.hosts import run_fmpy

    law = design(MODELS[model])
    y = measurements(law)
    inputs = {f"y{j + 1}": y[:, j] for j in range(law.n_inputs)}
    out = run_fmpy(fmus[model], inputs=inputs, outputs=["u1"], step_size=law.dt, n_steps=N,
                   parameters={"gain": 3.0, "t_on": 10 * law.dt})
    u, _ = simulate(law.with_gain(3.0).with_t_on(10 * law.dt), y)
    np.testing.assert_array_equal(out[:-1], u[1:])
    np.testing.assert_array_equal(out[:10], 0.0)
    assert np.ptp(out) > 0


def test_fmpy_non_delayed_fmu_equals_the_pure_law(fmus):
    from tests.support.hosts import run_fmpy

    law = direct_law()
    y = measurements(law)
    out = run_fmpy(fmus["direct"], inputs={"y1": y[:, 0], "y2": y[:, 1]},
                   outputs=["u1", "u2"], step_size=law.dt, n_steps=N)
    # Read after step k, before the next input is set: C x(k+1) + D y(k) (input held).
    u, state = np.zeros((N, 2)), None
    from ctrlfmu.law import initial_state, output, step

    state = initial_state(law)
    for k in range(N):
        state, _ = step(law, state, y[k])
        u[k] = output(law, state, y[k])
    np.testing.assert_array_equal(out, u)


@pytest.mark.parametrize("model", ["controller_testbed_isolation",
                                   "controller_truss10_strain_diag"])
def test_c_host_and_libcosim_match_fmpy(fmus, model, tmp_path):
    from tests.support import hosts

    law = design(MODELS[model])
    y = measurements(law)
    kw = dict(inputs={f"y{j + 1}": y[:, j] for j in range(law.n_inputs)}, outputs=["u1"],
              step_size=law.dt, n_steps=N, parameters={"u_max": 20.0, "t_on": 5 * law.dt})
    ref = hosts.run_fmpy(fmus[model], **kw)
    c_host = hosts.run_c_host(fmus[model], **kw, host=hosts.compile_c_host(tmp_path / "h"))
    cosim = hosts.run_libcosim(fmus[model], **kw)
    np.testing.assert_array_equal(c_host, ref)
    np.testing.assert_array_equal(cosim, ref)
    assert np.ptp(ref) > 0 and ref.max() <= 20.0


def test_fmpy_enable_and_fmu_state_round_trip(fmus):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    path = str(fmus["controller_eos_isolation"])
    law = design("eos_isolation")
    md = read_model_description(path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    y = measurements(law, 200)[:, 0]
    unzip = extract(path)
    try:
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                        modelIdentifier=md.coSimulation.modelIdentifier, instanceName="c")
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()

        def run(k0, k1, enable=True):
            rows = []
            fmu.setBoolean([vr["enable"]], [enable])
            for k in range(k0, k1):
                fmu.setReal([vr["y1"]], [y[k]])
                fmu.doStep(k * law.dt, law.dt)
                rows.append(fmu.getReal([vr["u1"]])[0])
            return np.array(rows)

        first = run(0, 60)
        off = run(60, 70, enable=False)
        state = fmu.getFMUstate()
        blob = fmu.serializeFMUstate(state)
        later = run(70, 200)
        fmu.setFMUstate(fmu.deSerializeFMUstate(blob))
        again = run(70, 200)
        fmu.freeFMUstate(state)
        fmu.terminate()
        fmu.freeInstance()
    finally:
        shutil.rmtree(unzip, ignore_errors=True)
    np.testing.assert_array_equal(later, again)
    np.testing.assert_array_equal(off, 0.0)
    u, _ = simulate(law, y[:60])
    np.testing.assert_array_equal(first[:-1], u[1:, 0])
    # Re-enabled at sample 70 from a reset state: the response restarts from rest.
    u_re, _ = simulate(law, y[70:200])
    np.testing.assert_array_equal(later[:-1], u_re[1:, 0])
