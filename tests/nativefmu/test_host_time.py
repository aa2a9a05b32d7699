"""Every FMU gives the exact-step answer whatever the host's time arithmetic.

Every FMU of the registry (both builds) is checked.  Hosts pass a step's start and size
in different ways (issue 22, items 16 and 17): the
exact tick ``k / 1000`` and the period (the reference), ``(k + 1) h - k h`` (FMPy), an
accumulated ``t += h``, and a host whose clock drifts by 1e-12 s over the run.  Each FMU
is stepped for 8 s at 1 ms under each host with the same inputs per step, and its
outputs are compared with the reference run, per output, relative to that output's peak.
The reference is independent of the host arithmetic under test: the tick times are
Python's correctly rounded ``Fraction(k, 1000)``.
"""

from fractions import Fraction

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

pytestmark = pytest.mark.slow

H = 1e-3
N = 8000                       # 8 s at 1 ms
RTOL = 1e-12                   # of each output's peak
DRIFT = 1e-12                  # s over the run: the host of issue 22, item 17


def exact_host(n=N):
    return [(float(Fraction(k, 1000)), H) for k in range(n)]


def fmpy_host(n=N):
    return [(k * H, (k + 1) * H - k * H) for k in range(n)]


def accumulating_host(n=N):
    steps, t = [], 0.0
    for _ in range(n):
        steps.append((t, H))
        t += H
    return steps


def drifting_host(drift, n=N):
    """A host whose clock is ``k h`` plus a drift growing linearly to ``drift`` s."""
    t = [k * H + drift * k / n for k in range(n + 1)]
    return [(t[k], t[k + 1] - t[k]) for k in range(n)]


HOSTS = {"(k+1)h - kh": fmpy_host, "t += h": accumulating_host}

RNG = np.random.default_rng(22)
K = np.arange(N)
# inputs per step k, the same under every host (held over the step)
CASES = {
    "truss10_structure": ({}, lambda n_in: RNG.standard_normal((N, n_in)) * 10.0),
    "eos_testbed_structure": ({}, lambda n_in: RNG.standard_normal((N, n_in))),
    "piezo_p845_37": ({}, lambda n_in: np.column_stack(
        [40 * np.sin(2 * np.pi * 22 * K * H), 1e-6 * np.sin(2 * np.pi * 30 * K * H)])),
    "piezo_p243_30": ({}, lambda n_in: np.column_stack(
        [400 * np.sin(2 * np.pi * 8.4 * K * H), 1e-6 * np.sin(2 * np.pi * 9.5 * K * H)])),
    "piezo_p243_40": ({}, lambda n_in: np.column_stack(
        [400 * np.sin(2 * np.pi * 9.5 * K * H), 1e-6 * np.sin(2 * np.pi * 8.4 * K * H)])),
    "controller_eos_isolation": ({}, lambda n_in: RNG.standard_normal((N, n_in))),
    "controller_testbed_isolation": ({}, lambda n_in: RNG.standard_normal((N, n_in))),
    "controller_truss10_strain_diag": ({}, lambda n_in: 1e-6 * RNG.standard_normal((N, n_in))),
    "controller_truss10_strain_long": ({}, lambda n_in: 1e-6 * RNG.standard_normal((N, n_in))),
    "acs": ({}, lambda n_in: 1e-4 * np.sin(np.outer(K * H, 1.0 + np.arange(n_in)))),
    "disturbance": ({"preset": "swir_pointing", "start_time": 0.5, "stop_time": 4.5},
                    lambda n_in: np.zeros((N, n_in))),
    "excitation": ({"amp1": 10.0, "freq1": 8.4, "amp2": 5.0, "freq2": 9.5,
                    "t_start": 0.25, "t_stop": 4.5}, lambda n_in: np.zeros((N, n_in))),
}


def simulate(path, parameters, inputs, steps):
    """Outputs after every step of ``steps`` (start, size), inputs[k] held over step k."""
    md = read_model_description(str(path))
    var = {v.name: v for v in md.modelVariables}
    ins = [v.valueReference for v in md.modelVariables
           if v.causality == "input" and v.type == "Real"]
    outs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    unzipped = extract(str(path))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, instanceName="host",
                    modelIdentifier=md.coSimulation.modelIdentifier)
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    for name, value in parameters.items():
        setter = {"Real": fmu.setReal, "String": fmu.setString}[var[name].type]
        setter([var[name].valueReference], [value])
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    y = np.empty((len(steps), len(outs)))
    for k, (t, h) in enumerate(steps):
        if ins:
            fmu.setReal(ins, inputs[k].tolist())
        fmu.doStep(t, h)
        y[k] = fmu.getReal(outs)
    fmu.terminate()
    fmu.freeInstance()
    return y


def n_real_inputs(path):
    return sum(v.causality == "input" and v.type == "Real"
               for v in read_model_description(str(path)).modelVariables)


def peak_errors(y, ref):
    """Largest difference of each output relative to its peak in the reference."""
    peak = np.max(np.abs(ref), axis=0)
    err = np.max(np.abs(y - ref), axis=0)
    return np.where(peak > 0, err / np.where(peak > 0, peak, 1.0), err)


@pytest.fixture(scope="module")
def inputs():
    return {}


@pytest.fixture(scope="module")
def exact():
    """``exact(path, parameters, inputs) -> outputs`` under the exact host, run once per
    FMU, parameters and inputs in this file (several tests compare other hosts with it)."""
    runs = {}

    def get(path, parameters, u):
        key = (str(path), tuple(sorted(parameters.items())),
               None if u is None else (u.shape, u.tobytes()))
        if key not in runs:
            runs[key] = simulate(path, parameters, u, exact_host())
        return runs[key]
    return get


def _paths(suite_fmus, model, kind):
    return suite_fmus(model, kind=kind)[model]


def _inputs(cache, model, path):
    if model not in cache:
        cache[model] = CASES[model][1](n_real_inputs(path))
    return cache[model]


@pytest.mark.parametrize("kind", ["native", "python"])
@pytest.mark.parametrize("model", list(CASES))
def test_every_host_gets_the_exact_step_answer(suite_fmus, inputs, exact, model, kind):
    path = _paths(suite_fmus, model, kind)
    params, _ = CASES[model]
    u = _inputs(inputs, model, path)
    ref = exact(path, params, u)
    assert np.any(ref != 0)
    for host, steps in HOSTS.items():
        err = peak_errors(simulate(path, params, u, steps()), ref)
        assert np.all(err <= RTOL), f"{host}: errors {err.max():.3g} of peak"


def test_native_and_python_agree_under_a_rounding_host(suite_fmus, inputs):
    """The structure's discretisation for a step that differs from a declared one by
    host rounding: the two flavours agree as on the exact step."""
    model = "eos_testbed_structure"
    native, python = (_paths(suite_fmus, model, k) for k in ("native", "python"))
    u = _inputs(inputs, model, native)
    steps = fmpy_host(1500)
    err = peak_errors(simulate(native, {}, u, steps), simulate(python, {}, u, steps))
    assert np.all(err <= RTOL), err.max()


@pytest.mark.parametrize("kind", ["native", "python"])
@pytest.mark.parametrize("drift", [DRIFT, -DRIFT])
def test_excitation_stops_at_t_stop_under_a_drifting_host(suite_fmus, exact, kind, drift):
    """v = 10 sin(2 pi 8.4 t) until 4.5 s: no sample at or after 4.5 s is non-zero, and
    the burst differs from the exact one by the drift's phase only, 2 pi f |drift| of
    peak (5.3e-11)."""
    path = _paths(suite_fmus, "excitation", kind)
    params = {"amp1": 10.0, "freq1": 8.4, "t_stop": 4.5}
    steps = drifting_host(drift)
    y = simulate(path, params, None, steps)[:, 0]
    ref = exact(path, params, None)[:, 0]
    k_stop = 4499                          # the step that ends at 4.5 s
    assert ref[k_stop] == 0.0 and ref[k_stop - 1] != 0.0
    assert np.all(y[k_stop:] == 0.0), f"{np.count_nonzero(y[k_stop:])} samples after t_stop"
    assert np.max(np.abs(y - ref)) <= 2 * np.pi * 8.4 * 10.0 * 2 * DRIFT


@pytest.mark.parametrize("kind", ["native", "python"])
@pytest.mark.parametrize("drift", [DRIFT, -DRIFT])
def test_controller_takes_every_sample_under_a_drifting_host(suite_fmus, inputs, exact, kind,
                                                              drift):
    """A 1 kHz law stepped at 1 ms: one sample per step whatever a 1e-12 s drift of the
    host's clock; a slipped sample shifts the whole output by one step."""
    model = "controller_eos_isolation"
    path = _paths(suite_fmus, model, kind)
    u = _inputs(inputs, model, path)
    ref = exact(path, {}, u)
    err = peak_errors(simulate(path, {}, u, drifting_host(drift)), ref)
    assert np.all(err <= RTOL), err.max()


@pytest.mark.parametrize("kind", ["native", "python"])
@pytest.mark.parametrize("drift", [DRIFT, -DRIFT])
@pytest.mark.parametrize("preset", ["swir_cryocooler", "swir_pointing", "tir_chopper"])
def test_disturbance_under_a_drifting_host(suite_fmus, exact, kind, drift, preset):
    """The active window [0.5, 4.5) s, and a source's own edges (a slew's start and end,
    a chopper's flanks): under a host whose clock drifts by 1e-12 s the FMU's time is
    brought back to the microsecond it is within 1e-6 of a step of, so every sample is
    the exact host's, bit for bit (before: the SWIR slew started one sample late, 100 %
    of its peak apart)."""
    path = _paths(suite_fmus, "disturbance", kind)
    params = {"preset": preset, "start_time": 0.5, "stop_time": 4.5}
    u = np.zeros((N, 1))                   # wheel_speed, not used by these presets
    y = simulate(path, params, u, drifting_host(drift))
    ref = exact(path, params, u)
    assert np.any(ref != 0.0)
    assert np.array_equal(y, ref)