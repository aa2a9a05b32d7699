"""Algebraic loops and every failure the master reports (test FMUs from fmukit)."""

import json
import math
import warnings

import numpy as np
import pytest

from orchestrator.cosim import AlgebraicLoopError
from orchestrator import SimulationError, UnconnectedInputWarning, prepare, run_scenario
from orchestrator.results import read_table
from orchestrator.scenario import ScenarioError, scenario_from_dict
from orchestrator.timebase import TimebaseError

pytestmark = [pytest.mark.slow,
              pytest.mark.filterwarnings("ignore::orchestrator.cosim.UnconnectedInputWarning")]

K1, B1, K2, B2 = 0.5, 1.0, -0.4, 2.0


def loop_scenario(fmu_b="MtGain", algorithm="gauss-seidel"):
    return {
        "experiment": {"stop": 0.05, "output_interval": 1e-3, "algorithm": algorithm},
        "fmus": {
            "a": {"fmu": "MtGain", "period": 1e-3, "parameters": {"k": K1, "b": B1}},
            "b": {"fmu": fmu_b, "period": 1e-3, "parameters": {"k": K2, "b": B2}},
        },
        "connections": [{"from": "a.y", "to": "b.u"}, {"from": "b.y", "to": "a.u"}],
        "record": {"variables": ["a.y", "b.y", "a.acc"]},
    }


def test_linear_loop_converges_to_analytic_fixed_point(fmu_dir):
    plan = prepare(scenario_from_dict(loop_scenario()), fmu_dir)
    assert [l.describe() for l in plan.loops] == ["a.y -> b.u, b.y -> a.u"]
    res = run_scenario(loop_scenario(), fmu_dir=fmu_dir)
    # ya = K1*yb + B1, yb = K2*ya + B2  =>  ya = (K1*B2 + B1) / (1 - K1*K2)
    ya = (K1 * B2 + B1) / (1 - K1 * K2)
    yb = K2 * ya + B2
    np.testing.assert_allclose(res["a.y"][1:], ya, rtol=1e-11)
    np.testing.assert_allclose(res["b.y"][1:], yb, rtol=1e-11)
    # a.acc integrates a's input once per step: rollback undid every discarded iterate
    # (the initial step integrates the initialisation value of b.y instead of yb only
    # for the iterates, never for the result)
    n = np.arange(len(res.time))
    np.testing.assert_allclose(res["a.acc"], n * 1e-3 * yb, rtol=1e-9, atol=1e-15)
    assert res.metadata["loops"] == ["a.y -> b.u, b.y -> a.u"]


def test_loop_without_state_rollback_is_named_before_instantiation(fmu_dir):
    with pytest.raises(AlgebraicLoopError,
                       match=r"algebraic loop a\.y -> b\.u, b\.y -> a\.u cannot be solved "
                             r"because b cannot get and set its FMU state.*jacobi"):
        run_scenario(loop_scenario("MtGainNoState"), fmu_dir=fmu_dir)


def test_jacobi_has_no_algebraic_loop(fmu_dir):
    from orchestrator import JacobiLoopWarning

    # the loop is not solved, and the run says so (a loop gain above 1 would diverge)
    with pytest.warns(JacobiLoopWarning, match=r"algebraic loop a\.y -> b\.u, b\.y -> a\.u "
                                               r"is not solved under algorithm 'jacobi'"):
        res = run_scenario(loop_scenario("MtGainNoState", "jacobi"), fmu_dir=fmu_dir)
    # ya[k+1] = K1*yb[k] + B1 with one-step delays: a damped oscillation to the fixed point
    ya = (K1 * B2 + B1) / (1 - K1 * K2)
    assert abs(res["a.y"][-1] - ya) < 1e-9
    assert abs(res["a.y"][2] - ya) > 1e-3


def test_divergent_loop_reports_loop_and_time(fmu_dir):
    d = loop_scenario()
    d["fmus"]["a"]["parameters"]["k"] = 3.0  # |k1 k2| > 1: fixed-point iteration diverges
    d["fmus"]["b"]["parameters"]["k"] = -1.0
    with pytest.raises(SimulationError, match=r"algebraic loop a\.y -> b\.u, b\.y -> a\.u "
                                              r"did not converge .* at t = 0\.0 s") as err:
        run_scenario(d, fmu_dir=fmu_dir)
    # the change of the last iteration is reported, and it grew (it used to read 0)
    import re
    change = float(re.search(r"last change ([^)]+)\)", str(err.value)).group(1))
    assert change > 1.0


# --- failures before any FMU is instantiated ----------------------------------------


def base(**fmus):
    return {
        "experiment": {"stop": 0.01, "output_interval": 1e-3},
        "fmus": fmus or {"i": {"fmu": "MtIntegrator", "period": 1e-3},
                         "g": {"fmu": "MtGain", "period": 1e-3}},
        "connections": [],
        "record": {"variables": []},
    }


def conn(a, b, **kw):
    return {"from": a, "to": b, **kw}


@pytest.mark.parametrize(
    "edit, error, match",
    [
        (lambda d: d["fmus"]["i"].update(fmu="MtIntegrater"), ScenarioError,
         r"unknown FMU 'MtIntegrater'.*did you mean 'MtIntegrator'"),
        (lambda d: d["connections"].append(conn("i.xx", "g.u")), ScenarioError,
         r"unknown variable i\.xx \(FMU MtIntegrator\.fmu\) \(did you mean 'x'"),
        (lambda d: d["connections"].append(conn("ii.x", "g.u")), ScenarioError,
         r"unknown instance 'ii' \(did you mean 'i'"),
        (lambda d: d["connections"].append(conn("i.x", "g.y")), ScenarioError,
         r"target g\.y is a output, not an input"),
        (lambda d: d["connections"].append(conn("i.u", "g.u")), ScenarioError,
         r"source i\.u is a input; expected an output"),
        (lambda d: d["connections"].append(conn("i.steps", "g.enable")), ScenarioError,
         r"joins a Integer to a Boolean; types must match"),
        (lambda d: d["connections"].append(conn("i.xm", "g.u")), ScenarioError,
         r"joins unit 'm' to unit '1'; units must match"),
        (lambda d: d["connections"].append(conn("i.steps", "g.n", gain=2.0)), ScenarioError,
         r"gain or offset but carries a Integer"),
        (lambda d: d["connections"].extend([conn("i.x", "g.u"), conn("g.acc", "g.u")]),
         ScenarioError, r"input g\.u is driven twice \(from i\.x and g\.acc\)"),
        (lambda d: d.update(actions=[{"time": 0.005, "set": {"g.u": 1.0}}],
                            connections=[conn("i.x", "g.u")]), ScenarioError,
         r"input g\.u is driven twice \(by connection from i\.x and by an action\)"),
        (lambda d: d.update(actions=[{"time": 0.0025, "set": {"g.k": 1.0}}]), TimebaseError,
         r"action time 0\.0025 s is not on the base grid"),
        (lambda d: d.update(actions=[{"time": 0.002, "set": {"g.c": 1.0}}]), ScenarioError,
         r"sets g\.c, a fixed parameter; only inputs and tunable parameters"),
        (lambda d: d["fmus"]["g"].update(parameters={"k": "big"}), ScenarioError,
         r"g\.k is Real; got str 'big'"),
        (lambda d: d["fmus"]["g"].update(parameters={"kk": 1.0}), ScenarioError,
         r"unknown variable g\.kk.*did you mean 'k'"),
        (lambda d: d["fmus"]["g"].update(parameters={"y": 1.0}), ScenarioError,
         r"g\.y is a continuous output; only parameters and inputs can be set"),
        (lambda d: d["record"].update(variables=["g.yy"]), ScenarioError,
         r"recorded variable g\.yy refers to unknown variable g\.yy.*did you mean 'y'"),
        (lambda d: d["fmus"]["g"].update(period=0.0), ScenarioError,
         r"period of instance 'g' is 0\.0 s; expected > 0"),
        (lambda d: d["experiment"].update(output_interval=-1e-3), ScenarioError,
         r"output_interval is -0\.001 s; expected > 0"),
        (lambda d: d["experiment"].update(stop=0.0), ScenarioError, r"stop .* is not after"),
    ],
)
def test_failures_before_instantiation(fmu_dir, edit, error, match, monkeypatch):
    import orchestrator.cosim.simulation as simulation

    def no_instantiation(*a, **k):  # prove that nothing was instantiated
        raise AssertionError("an FMU was instantiated")
    monkeypatch.setattr(simulation, "FmuInstance", no_instantiation)
    d = base()
    edit(d)
    with pytest.raises(error, match=match):
        run_scenario(d, fmu_dir=fmu_dir)


def test_unconnected_inputs_are_listed_in_a_warning(fmu_dir):
    d = base()
    d["connections"].append(conn("i.x", "g.u"))
    d["fmus"]["g"]["parameters"] = {"enable": True}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        plan = prepare(scenario_from_dict(d), fmu_dir)
    msgs = [str(w.message) for w in caught if issubclass(w.category, UnconnectedInputWarning)]
    assert msgs == ["2 input(s) are not connected and keep their start values: i.u, g.n"]
    assert plan.unconnected == ["i.u", "g.n"]


# --- failures during a run ------------------------------------------------------------


@pytest.mark.parametrize(
    "mode, match",
    [
        (1, r"instance 'bad' failed in fmi2DoStep at t = 0\.02 s with status Fatal: .*"
            r"RuntimeError\('deliberate failure at t = 0\.02'\)"),
        # a Python FMU declines a step that leaves an output NaN and logs why (fmukit)
        (2, r"instance 'bad' failed in fmi2DoStep at t = 0\.02 s with status Discard: "
            r"doStep from t = 0\.02 s: output y = nan after the step is not a finite"),
    ],
)
def test_failure_mid_run_keeps_rows_so_far(fmu_dir, tmp_path, mode, match):
    d = base(i={"fmu": "MtIntegrator", "period": 1e-3, "parameters": {"u": 1.0}},
             bad={"fmu": "MtFaulty", "period": 2e-3,
                  "parameters": {"fail_time": 0.02, "mode": mode}})
    d["experiment"]["stop"] = 0.05
    d["record"]["variables"] = ["i.x", "bad.y"]
    with pytest.raises(SimulationError, match=match) as info:
        run_scenario(d, tmp_path, fmu_dir=fmu_dir)
    assert info.value.instance == "bad" and info.value.time == 0.02
    table = read_table(tmp_path / "results.parquet")
    meta = json.loads((tmp_path / "run.json").read_text())
    assert meta["status"] == "error" and "instance 'bad'" in meta["error"]
    # rows 0 .. 20 ms were recorded (the row at 20 ms is read before that tick's steps)
    np.testing.assert_array_equal(table["time"], np.arange(21) / 1000)
    np.testing.assert_allclose(table["i.x"], np.arange(21) / 1000, atol=1e-15)
    # the faulty FMU outputs t + h (a float sum) after each 2 ms step; a row shows the
    # value stamped <= its time: 0, 0, 2, 2, 4, ... ms
    np.testing.assert_allclose(table["bad.y"], 2 * (np.arange(21) // 2) / 1000,
                               rtol=0, atol=1e-17)
    assert info.value.result.table["time"][-1] == 0.02


def test_python_slave_whose_step_returns_false_ends_the_run_normally(fmu_dir, tmp_path):
    """pythonfmu 0.7 turns ``do_step() -> False`` into fmi2Discard with fmi2Terminated
    true: the FMU asks to end the simulation, which FMI 2.0 makes a normal end."""
    from orchestrator import EarlyEndWarning

    d = base(i={"fmu": "MtIntegrator", "period": 1e-3, "parameters": {"u": 1.0}},
             bad={"fmu": "MtFaulty", "period": 2e-3,
                  "parameters": {"fail_time": 0.02, "mode": 0}})
    d["experiment"]["stop"] = 0.05
    d["record"]["variables"] = ["i.x", "bad.y"]
    with pytest.warns(EarlyEndWarning, match=r"instance 'bad' ended the run at t = 0.02 s"):
        result = run_scenario(d, tmp_path, fmu_dir=fmu_dir)
    assert result.metadata["status"] == "terminated"
    assert json.loads((tmp_path / "run.json").read_text())["terminated"]["instance"] == "bad"
    np.testing.assert_array_equal(read_table(tmp_path / "results.parquet")["time"],
                                  np.arange(21) / 1000)


# --- non-finite values: rejected before the run, blamed on their source ------------


@pytest.mark.parametrize("value, match", [
    (math.nan, r"^g.k is Real; got nan, expected a finite number$"),
    (math.inf, r"g.k is Real; got inf, expected a finite number"),
    (10**400, r"g.k is Real; got 1000000.*\(401 characters\), expected a finite number"),
])
def test_non_finite_parameters_are_rejected_before_anything_runs(fmu_dir, value, match):
    d = base()
    d["fmus"]["g"]["parameters"] = {"k": value}
    with pytest.raises(ScenarioError, match=match):
        run_scenario(d, fmu_dir=fmu_dir)


def test_non_finite_override_and_action_values_are_rejected(fmu_dir):
    with pytest.raises(ScenarioError, match=r"g.b is Real; got nan, expected a finite"):
        run_scenario(base(), fmu_dir=fmu_dir, overrides=["g.b=nan"])
    d = base()
    d["actions"] = [{"time": 0.005, "set": {"g.k": -math.inf}}]
    with pytest.raises(ScenarioError, match=r"g.k is Real; got -inf, expected a finite"):
        run_scenario(d, fmu_dir=fmu_dir)
    # issue 12: an error line echoed a 5 MB value
    with pytest.raises(ScenarioError, match=r"^g.b is Real; got str 'x{20,40}\.\.\.x{5,12}' "
                       r"\(1000002 characters\)$"):
        run_scenario(base(), fmu_dir=fmu_dir, overrides={"g.b": "x" * 10**6})


@pytest.mark.parametrize("key", ["gain", "offset"])
@pytest.mark.parametrize("value", [math.nan, math.inf, 10**400])
def test_non_finite_connection_gains_are_rejected(key, value):
    d = base()
    d["connections"] = [conn("i.x", "g.u", **{key: value})]
    with pytest.raises(ScenarioError, match=f"connection 1 {key} is .*; expected a finite"):
        scenario_from_dict(d)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
def test_a_non_finite_value_is_blamed_on_the_instance_that_produced_it(fmu_dir):
    """g1 = 1e308 * 10 overflows to inf at initialisation and g2 = 0 * inf is NaN; g2
    comes first in the table, g1 first in the order the instances ran."""
    d = base(g2={"fmu": "MtGain", "period": 1e-3, "parameters": {"k": 0.0}},
             g1={"fmu": "MtGain", "period": 1e-3, "parameters": {"k": 1e308}},
             i={"fmu": "MtIntegrator", "period": 1e-3, "parameters": {"x0": 10.0}})
    d["connections"] = [conn("i.x", "g1.u"), conn("g1.y", "g2.u")]
    with pytest.raises(SimulationError, match=r"instance 'g1' produced inf for y in "
                       r"initialisation at t = 0\.0 s") as info:
        run_scenario(d, fmu_dir=fmu_dir)
    assert info.value.instance == "g1"


def test_needlessly_fine_tick_grids_are_warned_about(fmu_dir, tmp_path):
    from fmutools.build import FmuSpec, build_fmu
    from orchestrator import TimebaseWarning

    def warned(d):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            prepare(scenario_from_dict(d, fmu_dir), fmu_dir)
        return [str(w.message) for w in caught if issubclass(w.category, TimebaseWarning)]

    assert warned(base()) == []
    # a 0.4 ms output interval with 1 ms instances: base step 0.2 ms, five times the ticks
    d = base()
    d["experiment"]["output_interval"] = 4e-4
    (msg,) = warned(d)
    assert "common step 0.001 s" in msg and "0.0002 s" in msg and "5 times" in msg
    # a period 10 000 times finer than the FMU's DefaultExperiment step (a typo for 1e-3)
    fmu = build_fmu(FmuSpec("MtStepped", "mastertest_slaves:Integrator", step_size=1e-3),
                    tmp_path)
    import sys
    sys.modules.pop("mastertest_slaves", None)   # as conftest.py does after its builds
    d = base(i={"fmu": str(fmu), "period": 1e-7})
    d["experiment"].update(stop=0.05, output_interval=1e-7)
    (msg,) = warned(d)
    assert "'i' steps every 1e-07 s, 10000 times finer" in msg and "500000 steps" in msg
