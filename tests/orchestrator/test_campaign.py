"""Tests of the campaign engine with a cheap pure-Python case runner (no FMUs)."""

from __future__ import annotations

import hashlib
import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from orchestrator import metrics as M
from orchestrator.campaign import (
    ANGLE_UNITS,
    CampaignError,
    campaign_from_dict,
    execute_case,
    keyed,
    run_campaign,
)
from orchestrator.cli import main as cli_main
from orchestrator.results import RunResult, read_columns

ARCSEC = ANGLE_UNITS["arcsec"]
DT = 0.001


def synthetic_runner(scenario: dict, out_dir) -> Path:
    """Case runner: LOS angles are sines set by the scenario's parameters.

    ``dist.amplitude`` (rad) at ``dist.frequency`` (Hz) reaches instrument A (pitch and yaw,
    yaw a quarter period later) attenuated by ``1 + ctrl.gain``, and instrument B (roll) at
    half that amplitude.  ``dist.fail`` raises; ``dist.sleep`` (s) slows the case down;
    ``dist.log`` names a file to which every call appends the scenario's digest.
    """
    p = scenario["fmus"]["dist"]["parameters"]
    gain = scenario["fmus"]["ctrl"]["parameters"].get("gain", 0.0)
    if p.get("log"):
        digest = hashlib.sha256(json.dumps(scenario, sort_keys=True).encode()).hexdigest()
        with open(p["log"], "a", encoding="utf-8") as f:
            f.write(digest + "\n")
    if p.get("sleep"):
        time.sleep(float(p["sleep"]))
    if p.get("fail"):
        raise RuntimeError(f"disturbance model diverged at {p['frequency']} Hz")
    n = int(round(float(scenario["experiment"]["stop"]) / DT)) + 1
    t = np.arange(n) * DT
    a = float(p["amplitude"]) / (1.0 + float(gain))
    w = 2 * np.pi * float(p["frequency"])
    table = pa.table({
        "time": t,
        "sc.los_a_pitch": a * np.sin(w * t),
        "sc.los_a_yaw": a * np.cos(w * t),
        "sc.los_b_roll": 0.5 * a * np.sin(w * t),
    })
    path = Path(out_dir) / "results.parquet"
    pq.write_table(table, path)
    return path


class FingerprintedRunner:
    """A runner whose FMUs have a checksum (here a constant)."""

    def fingerprint(self, scenario):
        return "fmu-checksums-v2"

    def __call__(self, scenario, out_dir):
        return synthetic_runner(scenario, out_dir)


def campaign_data(log=None, sleep=0.0, fail_event=None, n_events=3, sweep=False):
    """A small campaign: events x {isolation off, on}, peak-to-peak and RMS jitter."""
    base = {
        "experiment": {"stop": 1.0, "output_interval": DT},
        "fmus": {
            "dist": {"fmu": "dist", "period": DT,
                     "parameters": {"amplitude": 0.0, "frequency": 1.0, "sleep": sleep,
                                    "log": str(log or "")}},
            "ctrl": {"fmu": "ctrl", "period": DT, "parameters": {"gain": 0.0}},
            "sc": {"fmu": "sc", "period": DT},
        },
        "record": {"variables": ["sc.los_a_pitch", "sc.los_a_yaw", "sc.los_b_roll"]},
    }
    events = []
    # Frequencies whose crests fall on the 1 ms grid and that fit whole periods in 0.4 s.
    freqs = [5.0, 10.0, 50.0, 25.0, 100.0, 125.0]
    for i in range(n_events):
        ov = {"dist.amplitude": 1e-6 * (i + 1), "dist.frequency": freqs[i]}
        if fail_event == i:
            ov["dist.fail"] = True
        events.append({"name": f"event{i}", "overrides": ov})
    data = {
        "campaign": {"name": "synthetic", "scenario": base, "unit": "arcsec", "skip": 0.1},
        "events": events,
        "configurations": [
            {"name": "isolation off", "overrides": {"ctrl.gain": 0.0}},
            {"name": "isolation on", "overrides": {"ctrl.gain": 3.0}},
        ],
        "instruments": [
            {"name": "A", "axes": {"pitch": "sc.los_a_pitch", "yaw": "sc.los_a_yaw"}},
            {"name": "B", "axes": {"roll": "sc.los_b_roll"}, "requirement": 0.3},
        ],
        "metrics": [{"kind": "peak_to_peak", "windows": [0.2]},
                    {"kind": "rms_jitter", "windows": [0.4]}],
        "requirements": [{"instrument": "A", "metric": "peak_to_peak", "window": 0.2,
                          "value": 1.0}],
    }
    if sweep:
        data["sweeps"] = [{"parameter": "sc.mass", "values": [1.0, 2.0]}]
    return data


def read_sorted(path):
    """Summary rows in a fixed order, NaN replaced by a marker so that rows compare."""
    t = pq.read_table(path).to_pylist()
    t = [{k: "NaN" if isinstance(v, float) and math.isnan(v) else v for k, v in r.items()}
         for r in t]
    return sorted(t, key=lambda r: (r["case"], r["instrument"], r["axis"], r["metric"]))


# ----------------------------------------------------------------------------- definition


def test_matrix_expands_events_configurations_and_sweeps():
    c = campaign_from_dict(campaign_data(n_events=3, sweep=True))
    assert len(c.cases) == 3 * 2 * 2
    assert len({case.key for case in c.cases}) == 12
    one = next(x for x in c.cases if x.label == "event1 | isolation on | sc.mass=2.0")
    params = {k: v["parameters"] for k, v in one.scenario["fmus"].items()}
    assert params["dist"]["amplitude"] == 2e-6 and params["ctrl"]["gain"] == 3.0
    assert params["sc"]["mass"] == 2.0
    # keys are stable, and the runner's fingerprint (FMU checksums) enters them
    again = campaign_from_dict(campaign_data(n_events=3, sweep=True))
    assert [x.key for x in again.cases] == [x.key for x in c.cases]
    other = keyed(c, FingerprintedRunner())
    assert not {x.key for x in other.cases} & {x.key for x in c.cases}
    assert [x.label for x in other.cases] == [x.label for x in c.cases]


def test_master_runner_reads_each_fmu_file_once_and_again_when_it_changes(tmp_path,
                                                                           monkeypatch):
    from orchestrator.campaign import MasterRunner, runner as runner_module

    fmus = tmp_path / "fmus"
    fmus.mkdir()
    (fmus / "plant.fmu").write_bytes(b"plant v1")
    (fmus / "ctrl.fmu").write_bytes(b"controller")
    digests = []
    real = runner_module._fmu_digest
    monkeypatch.setattr(runner_module, "_fmu_digest",
                        lambda files: digests.append(files) or real(files))

    def scenario(gain):
        return {"experiment": {"stop": 1.0, "output_interval": DT},
                "fmus": {"plant": {"fmu": "plant", "period": DT},
                         "ctrl": {"fmu": "ctrl", "period": DT, "parameters": {"gain": gain}},
                         "sensor": {"fmu": "absent", "period": DT}}}

    def expected():
        # the definition: instances by name, "name:fmu:" then the file's bytes or "missing"
        h = hashlib.sha256(b"ctrl:ctrl:" + (fmus / "ctrl.fmu").read_bytes())
        h.update(b"plant:plant:" + (fmus / "plant.fmu").read_bytes())
        h.update(b"sensor:absent:missing")
        return h.hexdigest()

    runner = MasterRunner(tmp_path, fmu_dir=fmus)
    assert {runner.fingerprint(scenario(g)) for g in (0.0, 1.0, 2.0, 3.0)} == {expected()}
    assert len(digests) == 1                             # four cases, files read once
    # rebuilt in place, same size; a second later (file times may be as coarse as a tick)
    mtime = (fmus / "plant.fmu").stat().st_mtime_ns
    (fmus / "plant.fmu").write_bytes(b"plant v2")
    os.utime(fmus / "plant.fmu", ns=(mtime + 10**9, mtime + 10**9))
    assert runner.fingerprint(scenario(0.0)) == expected()
    assert len(digests) == 2
    # the keys of a campaign (one fingerprint per case) move with the file
    camp = campaign_from_dict({**campaign_data(), "campaign": {
        "name": "fp", "scenario": {**scenario(0.0), "fmus": {**scenario(0.0)["fmus"],
                                                               "dist": {"fmu": "plant",
                                                                        "period": DT}}},
        "skip": 0.1}}, tmp_path)
    before = keyed(camp, runner)
    (fmus / "ctrl.fmu").write_bytes(b"controller, rebuilt")
    after = keyed(camp, runner)
    assert not {c.key for c in before.cases} & {c.key for c in after.cases}


def test_bad_campaigns_are_rejected_with_the_culprit_named():
    d = campaign_data()
    d["events"][0]["overrides"]["nosuch.amplitude"] = 1.0
    with pytest.raises(CampaignError, match="nosuch"):
        campaign_from_dict(d)
    d = campaign_data()
    d["metrics"] = [{"kind": "p2p", "windows": [1.0]}]
    with pytest.raises(CampaignError, match="p2p"):
        campaign_from_dict(d)
    d = campaign_data()
    d["requirements"] = [{"instrument": "C", "value": 1.0}]
    with pytest.raises(CampaignError, match="'C'"):
        campaign_from_dict(d)
    d = campaign_data(sweep=True)
    d["sweeps"][0]["parameter"] = "mass"   # no instance: one sentence, not a ValueError
    with pytest.raises(CampaignError, match="sweep 1 parameter 'mass' must have the form"):
        campaign_from_dict(d)


def _set(path, value):
    """Return an edit that sets ``data[path[0]][path[1]]... = value``."""
    def edit(d):
        target = d
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value
    return edit


@pytest.mark.parametrize("edit, message", [
    # issue 12: this typo ran the event unexcited, "pass" at 0 arcsec, exit status 0
    (lambda d: d["events"][0].update(overide=d["events"][0].pop("overrides")),
     r"\[\[events\]\] entry 1 \('event0'\) has an unknown key 'overide' \(did you mean "
     r"'overrides'\?\); expected one of name, overrides"),
    (lambda d: d["metrics"][0].update(windos=[1.0]),
     r"\[\[metrics\]\] entry 1 has an unknown key 'windos' \(did you mean 'windows' or "
     r"'window'.*\?\); expected one of kind, windows, window"),
    (lambda d: d["configurations"][1].update(overides={}),
     r"\[\[configurations\]\] entry 2 \('isolation on'\) has an unknown key 'overides'"),
    (lambda d: d["instruments"][0].update(axis={}), r"\[\[instruments\]\] entry 1 \('A'\) "
     r"has an unknown key 'axis' \(did you mean 'axes'\?\); expected one of name, axes, "
     r"requirement"),
    (lambda d: d["requirements"][0].update(windw=0.2),
     r"\[\[requirements\]\] entry 1 has an unknown key 'windw'"),
    (lambda d: d.update(sweeps=[{"parameter": "sc.mass", "value": [1.0]}]),
     r"\[\[sweeps\]\] entry 1 has an unknown key 'value' \(did you mean 'values'\?\)"),
    (lambda d: d["campaign"].update(skp=0.1),
     r"\[campaign\] has an unknown key 'skp' \(did you mean 'skip'.*\?\); expected one of "
     r"name, scenario, unit, skip, stop, output_interval, algorithm"),
    (lambda d: d.update(event=[]),
     r"campaign file has an unknown key 'event' \(did you mean 'events'\?\)"),
    (lambda d: d["requirements"][0].update(metric="peak2peak"),
     r"requirement 1 \(A\) has metric 'peak2peak' \(did you mean 'peak_to_peak'\?\)"),
    (lambda d: d["requirements"][0].update(axis="pich"),
     r"requirement 1 \(A\) has axis 'pich' \(did you mean 'pitch'\?\); expected one of "
     r"pitch, yaw"),
    (lambda d: d["requirements"][0].update(window=0.3),
     r"requirement 1 \(A\) has window 0.3 s, which no \[\[metrics\]\] entry computes; "
     r"expected one of \[0.2\]"),
    (lambda d: d["requirements"][0].update(value="1"), r"has value '1'; expected a positive"),
    (lambda d: d["events"].append(3), r"\[\[events\]\] entry 4 is a int; expected a table"),
])
def test_campaign_typos_are_rejected_in_one_sentence(edit, message):
    d = campaign_data()
    edit(d)
    with pytest.raises(CampaignError, match=message) as info:
        campaign_from_dict(d)
    assert "\n" not in str(info.value)


def test_campaign_typo_in_a_toml_file_fails_the_cli_before_any_case(tmp_path, capsys):
    import tomli_w

    data = campaign_data()
    data["events"][0]["overide"] = data["events"][0].pop("overrides")
    path = tmp_path / "c.toml"
    path.write_text(tomli_w.dumps(data))
    code = cli_main(["campaign", str(path), "--out", str(tmp_path / "o"), "--workers", "0",
                     "--runner", f"{__name__}:synthetic_runner", "--quiet"])
    assert code != 0
    assert "unknown key 'overide'" in capsys.readouterr().err
    assert not (tmp_path / "o" / "summary.parquet").exists()


def test_shipped_campaigns_still_load():
    from orchestrator.campaign import load_campaign

    import tomllib

    root = Path(__file__).resolve().parents[2] / "campaigns"
    # a file of one [uncertainty] table goes with its campaign (jitterfmu campaign
    # C --uncertainty U)
    pairs = {"eos_uncertainty.toml": "eos_budget.toml"}
    for path in sorted(root.glob("*.toml")):
        with open(path, "rb") as f:
            tables = set(tomllib.load(f))
        if tables == {"uncertainty"}:
            camp = load_campaign(root / pairs[path.name], path)
            assert camp.uncertainty and camp.cases
            continue
        camp = load_campaign(path)
        assert camp.cases or camp.wheel_sweeps   # a sweep-only campaign has no cases


# ----------------------------------------------------------------------------- results


def test_serial_summary_holds_analytic_jitter_rss_and_margins(tmp_path):
    camp = campaign_from_dict(campaign_data())
    res = run_campaign(camp, tmp_path, synthetic_runner, workers=0, progress=False)
    assert (res.n_cases, res.n_run, res.n_failed) == (6, 6, 0)
    rows = pq.read_table(tmp_path / "summary.parquet").to_pylist()
    assert len(rows) == 6 * 3 * 2 + 2 * 3 * 2  # case rows + RSS rows
    get = {(r["event"], r["configuration"], r["instrument"], r["axis"], r["metric"]): r
           for r in rows}
    # Sine of amplitude a and period P <= 0.2 s: a 0.2 s window holds >= P/2, so 2a
    # (crests on the sample grid); RMS jitter over 0.4 s, a whole number of periods, a/sqrt 2.
    for i in range(3):
        for cf, g in (("isolation off", 0.0), ("isolation on", 3.0)):
            a = 1e-6 * (i + 1) / (1 + g) * ARCSEC
            r = get[(f"event{i}", cf, "A", "pitch", "peak_to_peak")]
            np.testing.assert_allclose(r["value"], 2 * a, rtol=1e-6)
            r = get[(f"event{i}", cf, "A", "yaw", "rms_jitter")]
            np.testing.assert_allclose(r["value"], a / math.sqrt(2), rtol=1e-6)
    rss = get[("RSS", "isolation off", "A", "pitch", "peak_to_peak")]
    np.testing.assert_allclose(rss["value"], 2e-6 * ARCSEC * math.sqrt(1 + 4 + 9), rtol=1e-6)
    assert rss["requirement"] == 1.0
    np.testing.assert_allclose(rss["margin"], 1.0 - rss["value"])
    np.testing.assert_allclose(rss["margin_ratio"], (1.0 - rss["value"]) / 1.0)
    assert rss["pass"] is False  # 1.54 arcsec > 1 arcsec
    on = get[("RSS", "isolation on", "A", "pitch", "peak_to_peak")]
    assert on["pass"] is True  # a quarter of the above
    shares = [get[(f"event{i}", "isolation off", "A", "pitch", "peak_to_peak")]["share"]
              for i in range(3)]
    np.testing.assert_allclose(shares, np.array([1, 4, 9]) / 14)
    # requirement shorthand on instrument B applies to every metric; none for A's RMS
    assert get[("RSS", "isolation off", "B", "roll", "rms_jitter")]["requirement"] == 0.3
    assert get[("RSS", "isolation off", "A", "yaw", "rms_jitter")]["pass"] is None
    csv = (tmp_path / "summary.csv").read_text()
    assert csv.splitlines()[0].startswith('"case","key","event","configuration"')
    n_rss = sum(r["event"] == "RSS" for r in rows)
    assert csv.count("\n") == len(rows) - n_rss + 1 and '"RSS"' not in csv   # case rows
    budget = (tmp_path / "budget.csv").read_text().splitlines()
    assert len(budget) == n_rss + 1 and all('"RSS"' in line for line in budget[1:])


def table_runner(scenario: dict, out_dir) -> RunResult:
    """The synthetic runner returning its table in memory, as the master's runner does."""
    path = synthetic_runner(scenario, out_dir)
    return RunResult(read_columns(path), {}, Path(out_dir))


def test_metrics_from_the_in_memory_table_equal_those_of_the_written_results(tmp_path):
    camp = campaign_from_dict(campaign_data())
    case = camp.cases[4]                                 # event2 | isolation off
    status = execute_case(case, table_runner, tmp_path, camp.instruments, camp.metrics,
                          camp.skip)
    assert status["status"] == "ok", status["error"]
    folder = tmp_path / case.key
    stored = {(r["instrument"], r["axis"], r["metric"], r["window"]): r["value"]
              for r in pq.read_table(folder / "metrics.parquet").to_pylist()}
    # Independently: the written results read back with pyarrow, the metric functions
    # called directly.  Same float64 samples, so the values are equal to the last bit.
    results = pq.read_table(folder / "results.parquet")
    t = results.column("time").to_numpy()
    keep = t >= t[0] + camp.skip - 0.5 * DT
    expected = {}
    for inst, axes in camp.instruments.items():
        for axis, var in axes.items():
            x = results.column(var).to_numpy()[keep]
            expected[(inst, axis, "peak_to_peak", 0.2)] = M.peak_to_peak(x, DT, 0.2,
                                                                         short="whole")
            expected[(inst, axis, "rms_jitter", 0.4)] = M.jitter_rms(x, DT, 0.4)
    assert stored.keys() == expected.keys()
    for line, value in expected.items():
        np.testing.assert_allclose(stored[line], value, rtol=0, atol=0, err_msg=str(line))
    # and the analytic value: peak-to-peak of a sine of amplitude a over >= half a period
    a = 3e-6
    np.testing.assert_allclose(stored[("A", "pitch", "peak_to_peak", 0.2)], 2 * a, rtol=1e-9)


def test_a_runner_returning_its_table_gives_the_same_summary(tmp_path):
    camp = campaign_from_dict(campaign_data())
    run_campaign(camp, tmp_path / "path", synthetic_runner, workers=0, progress=False)
    run_campaign(camp, tmp_path / "table", table_runner, workers=0, progress=False)
    assert read_sorted(tmp_path / "table/summary.parquet") == read_sorted(
        tmp_path / "path/summary.parquet")


def test_parallel_result_identical_to_serial(tmp_path):
    camp = campaign_from_dict(campaign_data(sweep=True))
    run_campaign(camp, tmp_path / "serial", synthetic_runner, workers=0, progress=False)
    res = run_campaign(camp, tmp_path / "pool", synthetic_runner, workers=2, progress=False)
    assert (res.n_run, res.n_failed) == (12, 0)
    assert read_sorted(tmp_path / "pool/summary.parquet") == read_sorted(
        tmp_path / "serial/summary.parquet")


def test_dask_local_cluster_identical_to_local(tmp_path):
    import distributed
    camp = campaign_from_dict(campaign_data())
    run_campaign(camp, tmp_path / "local", synthetic_runner, workers=0, progress=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        res = run_campaign(camp, tmp_path / "dask", synthetic_runner,
                           scheduler=cluster.scheduler_address, progress=False)
    assert (res.n_run, res.n_failed) == (6, 0)
    assert read_sorted(tmp_path / "dask/summary.parquet") == read_sorted(
        tmp_path / "local/summary.parquet")


def test_failing_case_is_recorded_and_others_complete(tmp_path):
    camp = campaign_from_dict(campaign_data(fail_event=1))
    res = run_campaign(camp, tmp_path, synthetic_runner, workers=2, progress=False)
    assert res.n_failed == 2  # event1 in both configurations
    cases = pq.read_table(tmp_path / "cases.parquet").to_pylist()
    failed = [c for c in cases if c["status"] == "failed"]
    assert sorted(c["case"] for c in failed) == ["event1 | isolation off",
                                                 "event1 | isolation on"]
    assert failed[0]["error"] == "RuntimeError: disturbance model diverged at 10.0 Hz"
    assert sum(c["status"] == "ok" for c in cases) == 4
    rows = pq.read_table(tmp_path / "summary.parquet").to_pylist()
    assert {r["event"] for r in rows} == {"event0", "event2", "RSS"}
    rss = [r for r in rows if r["event"] == "RSS"]
    assert all("event1" in r["note"] and r["pass"] is None for r in rss)


def test_rerun_skips_finished_cases(tmp_path):
    log = tmp_path / "calls.log"
    camp = campaign_from_dict(campaign_data(log=log))
    run_campaign(camp, tmp_path / "out", synthetic_runner, workers=0, progress=False)
    first = read_sorted(tmp_path / "out/summary.parquet")
    assert len(log.read_text().split()) == 6
    res = run_campaign(camp, tmp_path / "out", synthetic_runner, workers=0, progress=False)
    assert (res.n_run, res.n_skipped) == (0, 6)
    assert len(log.read_text().split()) == 6  # no case ran again
    assert read_sorted(tmp_path / "out/summary.parquet") == first


@pytest.mark.long   # make test-full: a killed campaign process, 5 s
def test_sigkill_mid_campaign_loses_only_cases_in_flight(tmp_path):
    log = tmp_path / "calls.log"
    data = campaign_data(log=log, sleep=0.25, n_events=6)  # 12 cases
    (tmp_path / "campaign.json").write_text(json.dumps(data))
    script = textwrap.dedent(f"""
        import json, sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_campaign import synthetic_runner
        from orchestrator.campaign import campaign_from_dict, run_campaign
        data = json.load(open({str(tmp_path / "campaign.json")!r}))
        run_campaign(campaign_from_dict(data), {str(tmp_path / "out")!r}, synthetic_runner,
                     workers=2, progress=False)
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    cases_dir = tmp_path / "out" / "cases"

    def finished():
        if not cases_dir.is_dir():
            return {}
        out = {}
        for d in cases_dir.iterdir():
            if not d.name.startswith(".") and (d / "case.json").is_file():
                out[d.name] = json.loads((d / "case.json").read_text())
        return out

    deadline = time.monotonic() + 60
    while len(finished()) < 4 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    os.killpg(proc.pid, signal.SIGKILL)  # the campaign process and its pool workers
    proc.wait()
    before = finished()
    assert 4 <= len(before) < 12, f"kill came too late: {len(before)} cases finished"
    assert all(st["status"] == "ok" for st in before.values())
    assert all((cases_dir / k / "metrics.parquet").is_file() for k in before)
    calls_before = log.read_text().split()

    camp = campaign_from_dict(data)
    res = run_campaign(camp, tmp_path / "out", synthetic_runner, workers=0, progress=False)
    assert (res.n_cases, res.n_failed) == (12, 0)
    assert res.n_skipped == len(before) and res.n_run == 12 - len(before)
    after = finished()
    assert set(after) == {c.key for c in camp.cases}
    assert all(after[k] == before[k] for k in before)  # finished cases untouched
    # none of the finished cases ran again
    rerun = log.read_text().split()[len(calls_before):]
    digest = {k: hashlib.sha256(json.dumps(v["scenario"], sort_keys=True).encode()).hexdigest()
              for k, v in after.items()}
    assert not {digest[k] for k in before} & set(rerun)
    assert len(rerun) == 12 - len(before)
    assert not list(cases_dir.glob(".tmp-*"))
    assert len(pq.read_table(tmp_path / "out/summary.parquet")) == 12 * 3 * 2 + 2 * 3 * 2


def test_cli_runs_campaign_and_reports_failures_in_exit_status(tmp_path, capsys):
    import tomli_w

    data = campaign_data(fail_event=0)
    path = tmp_path / "c.toml"
    path.write_text(tomli_w.dumps(data))
    code = cli_main(["campaign", str(path), "--out", str(tmp_path / "o"), "--workers", "0",
                     "--runner", f"{__name__}:synthetic_runner", "--quiet"])
    assert code == 2  # two failed cases
    out, err = capsys.readouterr()
    assert "6 cases: 6 run, 0 already finished, 2 failed" in out
    assert "diverged at 5.0 Hz" in err
    assert (tmp_path / "o/summary.csv").is_file()
    # it ends with the verdict a user came for, not only a path
    assert "budget (peak_to_peak over 0.2 s, RSS over events, arcsec):" in out
    assert "  A pitch: isolation off " in out and "requirement 1" in out


@pytest.mark.parametrize("damage", ["truncate results", "truncate metrics", "replace metrics",
                                    "delete results", "no file record"])
def test_resume_reruns_a_finished_case_whose_files_changed(tmp_path, damage):
    log = tmp_path / "calls.log"
    camp = campaign_from_dict(campaign_data(log=log))
    run_campaign(camp, tmp_path / "out", synthetic_runner, workers=0, progress=False)
    first = read_sorted(tmp_path / "out/summary.parquet")
    folder = tmp_path / "out" / "cases" / camp.cases[0].key
    if damage == "truncate results":
        data = (folder / "results.parquet").read_bytes()
        (folder / "results.parquet").write_bytes(data[: len(data) // 2])
    elif damage == "truncate metrics":
        data = (folder / "metrics.parquet").read_bytes()
        (folder / "metrics.parquet").write_bytes(data[:-10])
    elif damage == "replace metrics":   # same size, other bytes: only the hash sees it
        other = tmp_path / "out" / "cases" / camp.cases[1].key / "metrics.parquet"
        a, b = (folder / "metrics.parquet").read_bytes(), other.read_bytes()
        (folder / "metrics.parquet").write_bytes(b[: len(a)].ljust(len(a), b"\0"))
    elif damage == "delete results":
        (folder / "results.parquet").unlink()
    else:                               # a case.json written before files were recorded
        st = json.loads((folder / "case.json").read_text())
        del st["files"]
        (folder / "case.json").write_text(json.dumps(st))
    res = run_campaign(camp, tmp_path / "out", synthetic_runner, workers=0, progress=False)
    assert (res.n_run, res.n_skipped, res.n_failed) == (1, 5, 0)
    assert len(log.read_text().split()) == 7          # that case, and only it, ran again
    assert read_sorted(tmp_path / "out/summary.parquet") == first


def test_a_busy_campaign_folder_is_refused_at_once(tmp_path):
    import fcntl

    camp = campaign_from_dict(campaign_data())
    (tmp_path / "out").mkdir()
    with open(tmp_path / "out" / ".jitterfmu.lock", "a+") as held:
        fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)   # another campaign holds it
        with pytest.raises(CampaignError, match="in use by another campaign or run"):
            run_campaign(camp, tmp_path / "out", synthetic_runner, workers=0, progress=False)
    assert not list((tmp_path / "out" / "cases").iterdir())  # nothing touched
    res = run_campaign(camp, tmp_path / "out", synthetic_runner, workers=0, progress=False)
    assert res.n_run == 6                                    # free again once released


@pytest.mark.parametrize("end", ["reaped", "zombie"])
def test_pool_workers_exit_when_the_campaign_process_dies(tmp_path, end):
    # the worker initialiser, in a process whose "campaign" parent is killed; a zombie
    # (dead, not yet reaped) still answers os.kill(pid, 0)
    parent = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    script = textwrap.dedent(f"""
        import time
        from orchestrator.campaign.engine import _die_with_parent
        _die_with_parent({parent.pid}, period=0.05)
        time.sleep(60)
    """)
    worker = subprocess.Popen([sys.executable, "-c", script])
    try:
        time.sleep(1.0)
        assert worker.poll() is None                    # alive while the parent is
        parent.kill()
        if end == "reaped":
            parent.wait()
        else:
            deadline = time.monotonic() + 5
            while not _zombie(parent.pid) and time.monotonic() < deadline:
                time.sleep(0.01)
            assert _zombie(parent.pid)
        assert worker.wait(timeout=20) == 1             # gone soon after, not in 60 s
    finally:
        for p in (parent, worker):
            if p.poll() is None:
                p.kill()
            p.wait()


def _zombie(pid: int) -> bool:
    """Whether ``pid`` is a zombie (Linux: state Z in /proc/PID/stat)."""
    text = Path(f"/proc/{pid}/stat").read_text()
    return text.rsplit(")", 1)[1].split()[0] == "Z"


from hypothesis import given, settings, strategies as st  # noqa: E402

_leaf = st.one_of(st.none(), st.booleans(), st.integers(-3, 3), st.floats(allow_nan=True),
                  st.text(max_size=6))
_tree = st.recursive(_leaf, lambda inner: st.one_of(
    st.lists(inner, max_size=3),
    st.dictionaries(st.sampled_from(["name", "overrides", "kind", "windows", "instrument",
                                     "axes", "value", "metric", "window", "scenario", "x"]),
                    inner, max_size=4)), max_leaves=12)


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(st.sampled_from(["campaign", "events", "configurations", "sweeps",
                                        "instruments", "metrics", "requirements", "bogus"]),
                       _tree, max_size=6))
def test_any_campaign_layout_is_a_campaign_or_one_clear_error(data):
    # a mangled campaign file is read into a Campaign or refused with CampaignError
    # (one sentence), never another exception
    good = campaign_data()
    mixed = {**good, **data}
    try:
        campaign_from_dict(mixed)
    except CampaignError as exc:
        assert "\n" not in str(exc) and len(str(exc)) < 2000


def test_report_draws_the_rss_against_a_swept_parameter(tmp_path):
    """[[sweeps]] over sc.mass: the report holds one sweep figure per instrument and the
    worst points, the worst being the point whose RSS is the largest in the summary."""
    from orchestrator.report import write_report
    camp = campaign_from_dict(campaign_data(sweep=True))
    run_campaign(camp, tmp_path, synthetic_runner, workers=0, progress=False)
    text = write_report(tmp_path, "md").read_text(encoding="utf-8")
    assert "RSS against sc.mass" in text and "## Worst points of the sweeps" in text
    rss = [r for r in pq.read_table(tmp_path / "summary.parquet").to_pylist()
           if r["event"] == "RSS" and r["metric"] == "peak_to_peak"
           and r["configuration"] == "isolation off" and r["axis"] == "pitch"
           and r["instrument"] == "A"]
    top = max(rss, key=lambda r: r["value"])
    at = float(top["sweep"].split("=")[1])
    # the swept value is a number in a column of its own, in the Parquet and both CSVs
    assert all(r["sc.mass"] == float(r["sweep"].split("=")[1]) for r in rss)
    for name in ("summary.csv", "budget.csv"):
        header = (tmp_path / name).read_text().splitlines()[0].split(",")
        assert header[-1] == '"sc.mass"'
    want = f"| sc.mass | isolation off | A | pitch | peak_to_peak | sc.mass = {at:.4g} |"
    assert want in text


def test_ecss_indices_are_campaign_metrics(tmp_path):
    """ape (no window) and mpe/rpe/pde (windows) in [[metrics]]: on the sines of the
    synthetic runner (crests on the grid, whole periods per 0.2 s window) APE = RPE = the
    amplitude, MPE = PDE = 0 to round-off, in the campaign's unit."""
    data = campaign_data(n_events=1)
    data["metrics"] = [{"kind": "ape"}, {"kind": "mpe", "windows": [0.2]},
                       {"kind": "rpe", "windows": [0.2]}, {"kind": "pde", "windows": [0.2]}]
    data["requirements"] = [{"instrument": "A", "metric": "ape", "value": 0.5}]
    camp = campaign_from_dict(data)
    assert list(camp.metrics) == [("ape", None), ("mpe", 0.2), ("rpe", 0.2), ("pde", 0.2)]
    run_campaign(camp, tmp_path, synthetic_runner, workers=0, progress=False)
    rows = {(r["configuration"], r["metric"]): r for r in pq.read_table(
        tmp_path / "summary.parquet").to_pylist()
        if r["event"] == "event0" and r["instrument"] == "A" and r["axis"] == "pitch"}
    a = 1e-6 * ARCSEC   # event0's amplitude (rad) in arcsec, control off
    np.testing.assert_allclose(rows[("isolation off", "ape")]["value"], a, rtol=1e-9)
    np.testing.assert_allclose(rows[("isolation off", "rpe")]["value"], a, rtol=1e-9)
    assert abs(rows[("isolation off", "mpe")]["value"]) < 1e-9 * a
    assert abs(rows[("isolation off", "pde")]["value"]) < 1e-9 * a
    assert rows[("isolation off", "ape")]["requirement"] == 0.5
    with pytest.raises(CampaignError, match=r"metric 1 kind is 'apee'; expected one of"):
        campaign_from_dict({**data, "metrics": [{"kind": "apee"}]})
