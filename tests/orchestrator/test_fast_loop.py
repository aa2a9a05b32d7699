"""The compiled tick loop gives the Python loop's results bit for bit, and its errors.

Every scenario runs twice in one process, with ``Simulation(fast=True)`` (the C loop of
:mod:`orchestrator.cosim.fastloop`) and ``fast=False`` (the Python loop); the recorded
tables must be equal to the last bit (``np.array_equal``), not merely close, and a
failure must end both runs with the same message at the same row.
"""

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from orchestrator import SimulationError, prepare
from orchestrator.cosim import Simulation
from orchestrator.scenario import load_scenario, scenario_from_dict

from .test_ssp_cli import mixed

pytestmark = [pytest.mark.slow,
              pytest.mark.filterwarnings("ignore::orchestrator.cosim.UnconnectedInputWarning")]

ROOT = Path(__file__).resolve().parents[2]


def run(plan, fast):
    """``(table, error message or None, terminated, fast loop used)`` of one run."""
    sim = Simulation(plan, fast=fast)
    error = None
    ticks = []
    try:
        sim.initialize()
        sim.run(lambda f: ticks.append((f, sim.tick, sim.rows)))
    except SimulationError as exc:
        error = (str(exc), exc.instance, exc.time)
    finally:
        sim.close()
    return sim.table(), error, sim.terminated, ticks, sim.compiled_loop


def assert_same(plan, expect_fast=True):
    """Run ``plan`` both ways; the tables, errors and progress calls must be identical."""
    fast = run(plan, True)
    slow = run(plan, False)
    assert fast[4] is expect_fast and slow[4] is False
    assert fast[0].keys() == slow[0].keys()
    for key in slow[0]:
        assert np.array_equal(fast[0][key], slow[0][key], equal_nan=True), key
    assert fast[1:4] == slow[1:4]
    return fast


def with_stop(sc, stop):
    d = dict(sc)
    d["experiment"] = {**sc["experiment"], "stop": stop}
    return d


@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_mixed_rates_are_bit_identical(fmu_dir, algorithm):
    # 5.0 s: 5000 ticks, three chunks of the compiled loop
    table, error, *_ = assert_same(prepare(scenario_from_dict(mixed(algorithm, stop=5.0)),
                                           fmu_dir))
    assert error is None and len(table["time"]) == 5001
    assert np.all(np.isfinite(table["sink.x"])) and np.any(table["sink.x"] != 0)


def test_integers_booleans_and_actions_are_bit_identical(fmu_dir):
    d = mixed("gauss-seidel", stop=0.5)
    d["connections"].append({"from": "ramp.steps", "to": "g2.n"})
    d["fmus"]["g2"]["parameters"]["c"] = 1e-3
    d["actions"] = [{"time": 0.1, "set": {"g2.k": -2.0}},
                    {"time": 0.1, "set": {"ctrl.enable": False}},
                    {"time": 0.3, "set": {"ctrl.enable": True, "ramp.k": 0.5}}]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plan = prepare(scenario_from_dict(d), fmu_dir)
    table, *_ = assert_same(plan)
    assert np.any(table["g2.y"] < 0) and np.any(table["g2.y"] > 0)


def test_an_algebraic_loop_runs_the_python_loop(fmu_dir):
    d = {"experiment": {"stop": 0.05, "output_interval": 1e-3},
         "fmus": {"a": {"fmu": "MtGain", "period": 1e-3, "parameters": {"k": 0.5, "b": 1.0}},
                  "b": {"fmu": "MtGain", "period": 1e-3, "parameters": {"k": -0.4}}},
         "connections": [{"from": "a.y", "to": "b.u"}, {"from": "b.y", "to": "a.u"}],
         "record": {"variables": ["a.y", "b.y"]}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plan = prepare(scenario_from_dict(d), fmu_dir)
    assert_same(plan, expect_fast=False)


@pytest.mark.parametrize("mode, match", [
    (0, None),                                          # fmi2Discard + fmi2Terminated
    (1, r"instance 'bad' failed in fmi2DoStep at t = 0\.02 s with status Fatal"),
    # a Python FMU declines a step that leaves an output NaN and logs why (fmukit)
    (2, r"instance 'bad' failed in fmi2DoStep at t = 0\.02 s with status Discard: "
        r"doStep from t = 0\.02 s: output y = nan after the step is not a finite"),
])
@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_failures_give_the_same_message_and_rows(fmu_dir, mode, match, algorithm):
    d = {"experiment": {"stop": 0.05, "output_interval": 1e-3, "algorithm": algorithm},
         "fmus": {"i": {"fmu": "MtIntegrator", "period": 1e-3, "parameters": {"u": 1.0}},
                  "bad": {"fmu": "MtFaulty", "period": 2e-3,
                          "parameters": {"fail_time": 0.02, "mode": mode}},
                  "g": {"fmu": "MtGain", "period": 1e-3}},
         "connections": [{"from": "i.x", "to": "bad.u", "gain": 2.0},
                         {"from": "i.x", "to": "g.u", "offset": 0.5}],
         "record": {"variables": ["i.x", "bad.y", "g.y"]}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plan = prepare(scenario_from_dict(d), fmu_dir)
    table, error, terminated, *_ = assert_same(plan)
    assert len(table["time"]) == 21
    if match is None:
        assert error is None and terminated[0] == "bad" and terminated[1] == 0.02
    else:
        assert error[1] == "bad" and error[2] == 0.02
        import re
        assert re.match(match, error[0])


@pytest.mark.parametrize("kind", ["native", "python"])
def test_ten_bay_closed_loop_is_bit_identical(suite_fmus, suite_fmu_dir, kind):
    import tomllib

    path = ROOT / "scenarios" / "truss10_closed_loop.toml"
    names = [spec["fmu"] for spec in tomllib.loads(path.read_text())["fmus"].values()]
    suite_fmus(*names, kind=kind)
    fmu_dir = suite_fmu_dir if kind == "native" else suite_fmu_dir / "python"
    stop = 1.0 if kind == "native" else 0.3
    sc = load_scenario(path).with_experiment(stop=stop)
    table, error, *_ = assert_same(prepare(sc, fmu_dir))
    assert error is None and len(table["time"]) == round(stop / 0.004) + 1
    assert all(np.all(np.isfinite(v)) for v in table.values())
    assert max(float(np.max(np.abs(v))) for k, v in table.items() if k != "time") > 0
    assert not math.isnan(table["time"][-1])
