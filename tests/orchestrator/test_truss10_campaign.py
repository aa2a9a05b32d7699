"""The quick ten-bay campaign (campaigns/truss10_quick.toml) through the real FMUs."""

import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from orchestrator import metrics as M
from orchestrator.campaign import MasterRunner, load_campaign, run_campaign
from orchestrator.report import write_report

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
CAMPAIGN = ROOT / "campaigns" / "truss10_quick.toml"
FMUS = ("truss10_structure", "piezo_p243_40", "piezo_p243_30",
        "controller_truss10_strain_diag", "controller_truss10_strain_long", "excitation")
EVENTS = ("diagonal 8.4 Hz", "longeron 9.5 Hz")
AXES = ("roll", "pitch", "yaw")


@pytest.fixture(scope="module")
def campaign_out(tmp_path_factory, suite_fmus, suite_fmu_dir):
    suite_fmus(*FMUS)
    fmu_dir = suite_fmu_dir
    camp = load_campaign(CAMPAIGN)
    out = tmp_path_factory.mktemp("truss10_quick")
    result = run_campaign(camp, out, MasterRunner(camp.scenario_dir, fmu_dir=fmu_dir),
                          workers=2, progress=False)
    return camp, out, result


def p2p(rows, event, configuration, axis):
    (value,) = [r["value"] for r in rows
                if r["event"] == event and r["configuration"] == configuration
                and r["axis"] == axis and r["metric"] == "peak_to_peak"]
    return value


def test_every_case_runs(campaign_out):
    camp, out, result = campaign_out
    assert (result.n_cases, result.n_run, result.n_failed) == (4, 4, 0), result.failures
    cases = pq.read_table(out / "cases.parquet").to_pylist()
    assert {c["status"] for c in cases} == {"ok"}


def test_control_on_reduces_tip_jitter_of_each_event(campaign_out):
    _, out, _ = campaign_out
    rows = pq.read_table(out / "summary.parquet").to_pylist()
    for event in EVENTS:
        for axis in AXES:
            off = p2p(rows, event, "control off", axis)
            on = p2p(rows, event, "control on", axis)
            assert 0 < on < off, (event, axis, on, off)
    # and on the dominant (roll) axis by more than half for both events
    for event in EVENTS:
        assert p2p(rows, event, "control on", "roll") < 0.5 * p2p(rows, event, "control off",
                                                                    "roll")
    # the excited member's own mode dominates its axis: open loop is far above 1 arcsec
    assert p2p(rows, "diagonal 8.4 Hz", "control off", "roll") > 10.0


def test_summary_has_rss_rows_against_the_requirement(campaign_out):
    _, out, _ = campaign_out
    rows = pq.read_table(out / "summary.parquet").to_pylist()
    for configuration in ("control off", "control on"):
        for axis in AXES:
            (rss,) = [r for r in rows if r["event"] == "RSS" and r["axis"] == axis
                      and r["configuration"] == configuration
                      and r["metric"] == "peak_to_peak"]
            events = [p2p(rows, e, configuration, axis) for e in EVENTS]
            assert rss["value"] == pytest.approx(np.sqrt(np.sum(np.square(events))), rel=1e-12)
            assert rss["window"] == 0.5 and rss["unit"] == "arcsec"
            assert rss["requirement"] == 5.0
            assert rss["margin"] == pytest.approx(5.0 - rss["value"], rel=1e-12)
            # pass is the margin's sign against the requirement the file gives (an
            # assumed 5 arcsec; without control it is missed on every axis)
            assert rss["pass"] is (rss["value"] <= 5.0)
            if configuration == "control off":
                assert rss["pass"] is False
    # control removes most of the RSS tip jitter on every axis (72-75 % with the
    # absorbers tuned on the step-mean coupling; 4x was asked of the earlier tuning)
    for axis in AXES:
        on, off = ([r["value"] for r in rows if r["event"] == "RSS" and r["axis"] == axis
                    and r["configuration"] == c and r["metric"] == "peak_to_peak"][0]
                   for c in ("control on", "control off"))
        assert on < 0.5 * off, (axis, on, off)


def test_case_metrics_equal_those_of_the_results_read_back(campaign_out):
    # The campaign computes each case's metrics from the master's table in memory; here
    # they are recomputed from results.parquet read back, calling the metric functions.
    camp, out, _ = campaign_out
    (p2p_window,) = [w for kind, w in camp.metrics if kind == "peak_to_peak"]
    keys = [c["key"] for c in json.loads((out / "campaign.json").read_text())["cases"]]
    assert len(keys) == 4
    for key in keys:
        folder = out / "cases" / key
        results = pq.read_table(folder / "results.parquet")
        t = results.column("time").to_numpy()
        dt = float(np.median(np.diff(t)))
        stored = {(r["axis"], r["metric"]): r["value"]
                  for r in pq.read_table(folder / "metrics.parquet").to_pylist()}
        for axis, var in camp.instruments["tip"].items():
            x = results.column(var).to_numpy()[t >= t[0] + camp.skip - 0.5 * dt]
            # same float64 samples either way: equal to the last bit
            assert stored[(axis, "peak_to_peak")] == M.peak_to_peak(x, dt, p2p_window,
                                                                    short="whole")
            assert stored[(axis, "rms")] == float(np.std(x))


def test_report_is_written(campaign_out):
    _, out, _ = campaign_out
    path = write_report(out)
    text = path.read_text(encoding="utf-8")
    assert "control on" in text and "RSS" in text


@pytest.mark.long   # make test-full: a campaign on both builds, 7 s
def test_python_and_native_fmus_give_the_same_cases(campaign_out, tmp_path, suite_fmus,
                                                    suite_fmu_dir):
    """Every case of the shipped quick campaign, run on the Python build of the FMUs
    (--python-fmus), records the same signals as on the native build, to 1e-12 of each
    signal's peak; the case keys differ (other FMU files)."""
    from orchestrator.results import read_columns

    camp, out, result = campaign_out
    suite_fmus(*FMUS, kind="python")
    py = run_campaign(camp, tmp_path, MasterRunner(camp.scenario_dir, fmu_dir=suite_fmu_dir,
                                                   fmu_kind="python"),
                      workers=0, progress=False)
    assert (py.n_run, py.n_failed) == (4, 0)
    native_cases = pq.read_table(out / "cases.parquet").to_pylist()
    python_cases = pq.read_table(tmp_path / "cases.parquet").to_pylist()
    by_label = {c["case"]: c for c in python_cases}
    for nc in native_cases:
        pc = by_label[nc["case"]]
        assert pc["key"] != nc["key"]
        a = read_columns(out / "cases" / nc["key"] / "results.parquet")
        b = read_columns(tmp_path / "cases" / pc["key"] / "results.parquet")
        assert a.keys() == b.keys()
        for name in a:
            peak = np.max(np.abs(b[name]))
            assert np.max(np.abs(a[name] - b[name])) <= 1e-12 * max(peak, 1e-300), name
