"""The master against independently written reference loops (test FMUs from fmukit)."""

import numpy as np
import pytest

from orchestrator import run_scenario

pytestmark = [pytest.mark.slow,
              pytest.mark.filterwarnings("ignore::orchestrator.cosim.UnconnectedInputWarning")]

H = 1e-3          # integrator period (s)
CTRL = 4e-3       # controller period (s)
K, B, X0 = -5.0, 1.0, 0.3
STOP = 0.5


def loop_scenario(algorithm):
    """Integrator at 1 kHz fed by a proportional controller at 250 Hz."""
    return {
        "experiment": {"stop": STOP, "output_interval": H, "algorithm": algorithm},
        "fmus": {
            "plant": {"fmu": "MtIntegrator", "period": H, "parameters": {"x0": X0}},
            "ctrl": {"fmu": "MtGain", "rate_hz": 250, "parameters": {"k": K, "b": B}},
        },
        "connections": [
            {"from": "plant.x", "to": "ctrl.u"},
            {"from": "ctrl.y", "to": "plant.u"},
        ],
        "record": {"variables": ["plant.x", "ctrl.y", "plant.steps"]},
    }


def reference(jacobi):
    """The sampled-data loop written out by hand, tick by tick (h = 1 ms, controller 4 h).

    The controller samples x at its ticks j = 0, 4, 8, ...  Gauss-Seidel: the plant
    uses the controller's output at t_j for the input set at t_j (direct feedthrough,
    FMI 2.0), held over [t_j, t_j + 4h); the recorded y at row k is that value.
    Jacobi: the plant uses the controller output stamped <= t_k, i.e. the one computed
    a controller period earlier (the initialisation output k*x0 + b before that), and
    the recorded y at row k is the controller output stamped <= t_k.
    """
    n = round(STOP / H)
    x = X0
    pending = visible = K * X0 + B     # controller output after initialisation
    xs, ys = [x], [visible]
    for k in range(n):
        if k % 4 == 0:
            visible = pending
            pending = K * x + B
        x = x + H * 1.0 * (visible if jacobi else pending)
        xs.append(x)
        ys.append(pending if (k + 1) % 4 == 0 else visible)
    xs = np.array(xs)
    if not jacobi:
        ys = K * xs[(np.arange(n + 1) // 4) * 4] + B
    return xs, np.array(ys)


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_multirate_zoh_matches_reference_loop(fmu_dir, algorithm):
    res = run_scenario(loop_scenario(algorithm), fmu_dir=fmu_dir)
    x_ref, y_ref = reference(algorithm == "jacobi")
    # times are k/1000 correctly rounded, not k*0.001 (which is off by an ulp for some k)
    np.testing.assert_array_equal(res.time, np.arange(len(x_ref)) / 1000)
    np.testing.assert_allclose(res["plant.x"], x_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res["ctrl.y"], y_ref, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(res["plant.steps"], np.arange(len(x_ref)))


def chain_scenario(algorithm):
    """ramp (x = t) -> doubling gain (feedthrough) -> integrator, all at 1 kHz."""
    return {
        "experiment": {"stop": 0.1, "output_interval": H, "algorithm": algorithm},
        "fmus": {
            "ramp": {"fmu": "MtIntegrator", "period": H, "parameters": {"u": 1.0}},
            "g": {"fmu": "MtGain", "period": H, "parameters": {"k": 2.0}},
            "sink": {"fmu": "MtIntegrator", "period": H},
        },
        "connections": [{"from": "ramp.x", "to": "g.u"}, {"from": "g.y", "to": "sink.u"}],
        "record": {"variables": ["ramp.x", "g.y", "sink.x"]},
    }


def test_jacobi_is_gauss_seidel_delayed_by_one_step(fmu_dir):
    gs = run_scenario(chain_scenario("gauss-seidel"), fmu_dir=fmu_dir)
    jac = run_scenario(chain_scenario("jacobi"), fmu_dir=fmu_dir)
    np.testing.assert_array_equal(gs["ramp.x"], jac["ramp.x"])
    u_gs = np.diff(gs["sink.x"]) / H     # the sink's input over each step
    u_jac = np.diff(jac["sink.x"]) / H
    # Gauss-Seidel: the gain's output of the same tick, 2 * ramp(t_k)
    np.testing.assert_allclose(u_gs, 2 * gs["ramp.x"][:-1], rtol=0, atol=1e-9)
    # Jacobi: the gain's output of the previous tick (initial output 0 at the first)
    np.testing.assert_allclose(u_jac[1:], u_gs[:-1], rtol=0, atol=1e-9)
    assert u_jac[0] == 0.0 and u_gs[1] > 0.0


@pytest.mark.parametrize("fast", [True, False], ids=["compiled-loop", "python-loop"])
def test_a_recorded_feedthrough_output_that_feeds_nothing_is_the_one_at_t_k(fmu_dir, fast):
    """Gain y = 2 u with u = x(t) = t from an integrator, y recorded and connected to
    nothing: the row at t_k holds 2 t_k, the output for the inputs of t_k (it held
    2 t_(k-1), as after the previous step)."""
    from orchestrator import load_scenario, prepare
    from orchestrator.cosim import Simulation

    sc = {
        "experiment": {"stop": 0.02, "output_interval": 1e-3},
        "fmus": {"i": {"fmu": "MtIntegrator", "period": 1e-3, "parameters": {"u": 1.0}},
                 "g": {"fmu": "MtGain", "period": 1e-3, "parameters": {"k": 2.0}}},
        "connections": [{"from": "i.x", "to": "g.u"}],
        "record": {"variables": ["i.x", "g.y"]},
    }
    sim = Simulation(prepare(load_scenario(sc), fmu_dir), fast=fast)
    try:
        sim.initialize()
        sim.run()
    finally:
        sim.close()
    table = sim.table()
    np.testing.assert_allclose(table["g.y"], 2 * table["i.x"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(table["i.x"], table["time"], rtol=0, atol=1e-12)
