"""A run never loses a result, never says ``running`` behind an exited process, and never
reports a diverged or saturated loop as a plain ``ok``."""

import json
import warnings

import numpy as np
import pytest

from orchestrator import (
    DivergenceError,
    SaturationWarning,
    ScenarioError,
    SimulationError,
    load_scenario,
    prepare,
    run_scenario,
)
from orchestrator.cosim import Simulation
from orchestrator.cosim.bus import RUNAWAY
from orchestrator.results import read_columns, read_table
from orchestrator.run import (
    PARTIAL_DIR,
    PREVIOUS_DIR,
    RecordTooLargeError,
    check_record_size,
)

pytestmark = pytest.mark.filterwarnings(
    "ignore::orchestrator.cosim.UnconnectedInputWarning")


def integrator(stop=0.05, **params):
    """x(t) = t for u = 1 (the rows check themselves)."""
    return {
        "experiment": {"stop": stop, "output_interval": 1e-3},
        "fmus": {"i": {"fmu": "MtIntegrator", "period": 1e-3,
                       "parameters": {"u": 1.0, **params}}},
        "record": {"variables": ["i.x"]},
    }


def growing(k=1000.0):
    """x' = k x by feeding x back: x doubles every step for k h = 1."""
    return {
        "experiment": {"stop": 2.0, "output_interval": 1e-3},
        "fmus": {"i": {"fmu": "MtIntegrator", "period": 1e-3,
                       "parameters": {"k": k, "x0": 1.0}}},
        "connections": [{"from": "i.x", "to": "i.u"}],
        "record": {"variables": ["i.x"]},
    }


def failing(stop=0.05, fail_time=0.005):
    sc = integrator(stop)
    sc["fmus"]["bad"] = {"fmu": "MtFaulty", "period": 1e-3,
                         "parameters": {"fail_time": fail_time, "mode": 1}}
    return sc


# ------------------------------------------------------------------- no result lost
@pytest.mark.parametrize("fail_time", [0.0, 0.005], ids=["at-start", "mid-run"])
def test_a_failed_rerun_keeps_the_complete_result_it_found(fmu_dir, tmp_path, fail_time):
    out = tmp_path / "o"
    run_scenario(integrator(), out, fmu_dir=fmu_dir)
    with pytest.raises(SimulationError, match=r"the complete result found in the folder is "
                       r"kept in .*/o/previous"):
        run_scenario(failing(fail_time=fail_time), out, fmu_dir=fmu_dir)
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "error" and meta["previous_result"] == PREVIOUS_DIR
    kept = read_table(out / PREVIOUS_DIR / "results.parquet")
    assert len(kept["time"]) == 51   # the complete run: 0 to 0.05 s at 1 ms
    np.testing.assert_allclose(kept["i.x"], kept["time"], atol=1e-12)
    assert json.loads((out / PREVIOUS_DIR / "run.json").read_text())["status"] == "ok"
    # the failed run's own rows are where they always were
    assert len(read_table(out / "results.parquet")["time"]) == meta["rows"]
    # a failed run again: the complete result is still the one kept
    with pytest.raises(SimulationError):
        run_scenario(failing(fail_time=fail_time), out, fmu_dir=fmu_dir)
    assert len(read_table(out / PREVIOUS_DIR / "results.parquet")["time"]) == 51
    # a complete run replaces it
    run_scenario(integrator(stop=0.02), out, fmu_dir=fmu_dir)
    assert not (out / PREVIOUS_DIR).exists()
    assert len(read_table(out / "results.parquet")["time"]) == 21


def test_rows_of_an_unfinished_run_are_refused_not_deleted(fmu_dir, tmp_path):
    """What a SIGKILLed run leaves: run.json 'running' and complete parts (the kill itself
    is exercised in test_run_output.py)."""
    from orchestrator.results import write_table

    out = tmp_path / "o"
    run_scenario(integrator(), out, fmu_dir=fmu_dir)
    part = out / PARTIAL_DIR / "part-000000.parquet"
    write_table({"time": np.arange(1234) / 1e3, "i.x": np.arange(1234) / 1e3}, part)
    meta = json.loads((out / "run.json").read_text())
    (out / "run.json").write_text(json.dumps(dict(meta, status="running")))
    from orchestrator import OutputError

    with pytest.raises(OutputError, match=r"holds 1,234 rows of a run that did not finish "
                       r"\(results.partial/.*pass --overwrite to discard them"):
        run_scenario(integrator(), out, fmu_dir=fmu_dir)
    assert len(read_table(out / PARTIAL_DIR)["time"]) == 1234
    # the folder's lock was free, so no process writes that run: run.json says killed
    left = json.loads((out / "run.json").read_text())
    assert left["status"] == "killed" and "ended before it finished" in left["error"]
    run_scenario(integrator(), out, fmu_dir=fmu_dir, overwrite=True)
    assert not (out / PARTIAL_DIR).exists()
    assert json.loads((out / "run.json").read_text())["status"] == "ok"


def test_a_record_too_large_for_memory_is_refused_before_the_run(fmu_dir, tmp_path,
                                                                  monkeypatch):
    import orchestrator.run as run_mod

    plan = prepare(load_scenario(integrator(stop=1e6)), fmu_dir)
    need = check_record_size(plan, available=1 << 62)
    assert need == 2 * 8 * (10**9 + 1) * 2   # rows x (time, i.x), held twice
    with pytest.raises(RecordTooLargeError, match=r"needs 29.8 GiB \(1,000,000,001 rows of "
                       r"2 columns, held twice\) and 1.0 GiB .*raise "
                       r"experiment.output_interval \(now 0.001 s\)"):
        check_record_size(plan, available=1 << 30)
    monkeypatch.setattr(run_mod, "_available_memory", lambda: 1 << 30)
    out = tmp_path / "o"
    with pytest.raises(RecordTooLargeError, match="needs 29.8 GiB"):
        run_scenario(integrator(stop=1e6), out, fmu_dir=fmu_dir)
    assert not (out / "run.json").exists()


def test_run_json_never_says_running_after_the_run_raised(fmu_dir, tmp_path, monkeypatch):
    import orchestrator.run as run_mod

    def no_memory(plan):
        raise MemoryError("Unable to allocate the record")
    monkeypatch.setattr(run_mod, "Simulation", no_memory)
    out = tmp_path / "o"
    with pytest.raises(MemoryError):
        run_scenario(integrator(), out, fmu_dir=fmu_dir)
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "error" and "Unable to allocate" in meta["error"]


# -------------------------------------------------------------------- divergence
@pytest.mark.parametrize("fast", [True, False], ids=["compiled-loop", "python-loop"])
def test_a_run_that_grows_without_bound_ends_as_diverged(fmu_dir, fast):
    sim = Simulation(prepare(load_scenario(growing()), fmu_dir), fast=fast)
    try:
        sim.initialize()
        with pytest.raises(DivergenceError, match=r"instance 'i' produced x = .*beyond 1e\+100 "
                           r"in magnitude, in its step at t = 0.332 s: the run diverged"):
            sim.run()
    finally:
        sim.close()
    # x = 2^(k+1) after the step of tick k: the first beyond 1e100 is k = 332
    assert 2.0**333 > RUNAWAY > 2.0**332


def test_diverged_status_on_disk_with_the_rows_so_far(fmu_dir, tmp_path):
    out = tmp_path / "o"
    with pytest.raises(DivergenceError) as info:
        run_scenario(growing(), out, fmu_dir=fmu_dir)
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "diverged"
    assert meta["diverged"] == {"instance": "i", "time": pytest.approx(0.332)}
    table = read_table(out / "results.parquet")
    assert len(table["time"]) == meta["rows"] == 333
    np.testing.assert_array_equal(table["i.x"], 2.0 ** np.arange(333))
    assert info.value.result.metadata["status"] == "diverged"


TRUSS = "scenarios/truss10_closed_loop.toml"


def truss_plan(suite_fmus, **overrides):
    fmus = suite_fmus("truss10_structure", "piezo_p243_40", "piezo_p243_30",
                      "controller_truss10_strain_diag", "controller_truss10_strain_long",
                      "excitation")
    folder = next(iter(fmus.values())).parent
    sc = load_scenario(TRUSS).with_overrides(overrides)
    return sc, folder


def test_an_unstable_truss_loop_leaves_the_declared_strain_range(suite_fmus, tmp_path):
    """The truss with a strain-feedback gain of 1e6 and limits and rails of +-1e12 V (today:
    exit 0, status ok, strains of 3e5 by 12 s): the gauge strain
    leaves the +-1 % every FMU declares (FMI max), and the run says where."""
    sc, folder = truss_plan(suite_fmus, **{
        "ctrl_diag.gain": 1e6, "ctrl_long.gain": 1e6, "ctrl_diag.t_on": 0.0,
        "ctrl_long.t_on": 0.0, "ctrl_diag.u_min": -1e12, "ctrl_diag.u_max": 1e12,
        "ctrl_long.u_min": -1e12, "ctrl_long.u_max": 1e12,
        "piezo_diag.v_min": -1e12, "piezo_diag.v_max": 1e12, "piezo_long.v_min": -1e12, "piezo_long.v_max": 1e12,
        "piezo_diag.i_max": 1e12, "piezo_long.i_max": 1e12})
    out = tmp_path / "o"
    with pytest.raises(DivergenceError, match=r"instance '(structure|piezo_\w+)' produced "
                       r"\w+ = .*outside its declared range \[-0.01, 0.01\]"):
        run_scenario(sc.with_experiment(stop=2.0), out, fmu_dir=folder)
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "diverged" and meta["diverged"]["time"] < 2.0
    table = read_columns(out / "results.parquet")
    assert all(np.all(np.isfinite(v)) for v in table.values())


def test_declared_ranges_are_in_the_model_descriptions(suite_fmus):
    from orchestrator.cosim import read_fmu_info

    fmus = suite_fmus("truss10_structure", "piezo_p243_30")
    st = read_fmu_info(fmus["truss10_structure"]).variables
    assert (st["strain_diag"].min, st["strain_diag"].max) == (-0.01, 0.01)
    los = [v for v in st.values() if v.causality == "output" and v.unit == "rad"]
    assert los and all((v.min, v.max) == (-np.pi, np.pi) for v in los)
    pz = read_fmu_info(fmus["piezo_p243_30"]).variables
    assert (pz["strain"].min, pz["strain"].max) == (-0.01, 0.01)
    assert (pz["force"].min, pz["force"].max) == (-np.inf, np.inf)


# -------------------------------------------------------------------- saturation
def test_a_loop_at_its_rail_is_reported_with_how_long(suite_fmus, tmp_path):
    """Gain 1e4 on the strain loops from t = 0 with the hardware's rails: the commands
    sit at the rails; the run is bounded but held there, so it ends with status
    ``unstable`` (more than 10 % of it at a limit) and says which stacks saturated."""
    sc, folder = truss_plan(suite_fmus, **{
        "ctrl_diag.gain": 1e4, "ctrl_long.gain": 1e4,
        "ctrl_diag.t_on": 0.0, "ctrl_long.t_on": 0.0})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = run_scenario(sc.with_experiment(stop=1.0), tmp_path / "o", fmu_dir=folder)
    sat = [w for w in caught if issubclass(w.category, SaturationWarning)]
    assert len(sat) == 1
    meta = result.metadata
    assert meta["status"] == "unstable"
    assert meta["unstable"]["message"].startswith(f"the loop through {meta['unstable']['instance']}")
    spans = {(s["instance"], s["flag"]): s for s in meta["saturation"]}
    assert ("piezo_diag", "sat_voltage") in spans or ("piezo_diag", "sat_slew") in spans
    worst = max(s["fraction"] for s in meta["saturation"])
    assert 0.5 < worst <= 1.0
    text = str(sat[0].message)
    assert text.startswith("saturated during the run: piezo_")
    assert "% of the run, from t = " in text
    assert json.loads((tmp_path / "o/run.json").read_text())["saturation"]


def test_a_run_within_its_rails_reports_no_saturation(fmu_dir):
    with warnings.catch_warnings():
        warnings.simplefilter("error", SaturationWarning)
        result = run_scenario(integrator(), fmu_dir=fmu_dir)
    assert "saturation" not in result.metadata


# ---------------------------------------------------------------- silent no-ops
def test_an_instance_that_would_never_step_is_refused(fmu_dir):
    sc = integrator(stop=1.0)
    sc["fmus"]["i"]["period"] = 1e300
    with pytest.raises(ScenarioError, match=r"instance 'i' has period 1e\+300 s, longer than "
                       r"the run \(1.0 s\): it would never step"):
        prepare(load_scenario(sc), fmu_dir)


def test_an_output_interval_longer_than_the_run_is_refused(fmu_dir):
    sc = integrator(stop=1.0)
    sc["experiment"]["output_interval"] = 5.0
    with pytest.raises(ScenarioError, match=r"experiment.output_interval 5.0 s is longer "
                       r"than the run \(1.0 s\): it would record one row"):
        prepare(load_scenario(sc), fmu_dir)


@pytest.mark.parametrize("gain", [30.0, -5.0])
def test_a_loop_held_by_its_limits_ends_unstable_not_ok(suite_fmus, tmp_path, gain):
    """The truss with both strain gains at 30 or -5, outside the range the linear engine
    finds stable (-0.19 to 2.8): bounded only by the rails, it ran 12 s at +-1000 V and
    ended ``ok``.  Now: status ``unstable``, one sentence naming the loop's instance,
    limit and how long; the rows are kept.  The shipped gains (1) end ``ok``."""
    results = {}
    for g in (gain, 1.0):
        sc, folder = truss_plan(suite_fmus, **{"ctrl_diag.gain": g, "ctrl_long.gain": g})
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            results[g] = run_scenario(sc, tmp_path / f"o{g}", fmu_dir=folder)
    meta = results[gain].metadata
    assert meta["status"] == "unstable", meta.get("saturation")
    held = meta["unstable"]
    assert held["seconds"] > 0.1 * 12.0
    assert held["instance"].startswith("piezo_") and "% of the run from t = " in held["message"]
    assert json.loads((tmp_path / f"o{gain}" / "run.json").read_text())["status"] == "unstable"
    assert len(results[gain].table["time"]) == len(results[1.0].table["time"])
    assert results[1.0].metadata["status"] == "ok"


def test_the_command_line_says_in_one_line_which_loop_is_held_and_exits_1(suite_fmus, tmp_path,
                                                                       capsys):
    from orchestrator.cli import main

    _, folder = truss_plan(suite_fmus)
    code = main(["run", str(TRUSS), "--out", str(tmp_path / "o"), "--fmu-dir", str(folder),
                 "--set", "ctrl_diag.gain=30", "--set", "ctrl_long.gain=30", "--quiet"])
    err = capsys.readouterr().err
    assert code == 1
    lines = [ln for ln in err.splitlines() if ln.startswith("jitterfmu: unstable: ")]
    assert len(lines) == 1 and "the loop through piezo_" in lines[0] and "% of the run" in lines[0]
    assert (tmp_path / "o" / "results.parquet").exists()
